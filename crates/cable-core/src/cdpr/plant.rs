//! [`CdprPlant`]: a cable-driven parallel robot as a nonlinear [`Model`] — the platform as a
//! rigid body, elastic one-sided cables, one seed-003 winch per cable under its PID, and pulley
//! friction on each cable's path on both sides of a winch-side tension sensor (seeds 002 and
//! 003). [`closed_loop`] runs it under a trajectory controller with the tension distribution in
//! the loop and, optionally, seed 002's P force control (§4, eqs 10–15).
//!
//! ```text
//! platform   M(q)·[a; ω̇] = Aᵀ(q)·T_EE + w_g(q) + w_ext − bias(ω)      (seed 002 eq. 6)
//!            Newton–Euler about the platform origin with the centre of mass at R·c; a planar
//!            robot keeps x, y and the rotation about z
//! cable j    L_j = L0_j − r·α_j   (unstretched length; α > 0 hauls the cable in)
//!            T_EE = max(0, E·A·(l_j(q) − L_j)/L_j + c·(l̇_j + r·α̇_j))   (seed 002 eq. 15)
//! pulleys    sensor → platform: T_PUL = T_EE + F_d,   F_d = μ_d·N(θ_g, θ_exit(q))·T_EE·s + σ_d·v
//!            drum → sensor:     T_drum = T_PUL + F_u, F_u = μ_u·N(θ_g)·T_PUL·s + σ_u·v
//!            s = σ_ε(v) (Coulomb, eq. 7) or a Dahl state z (eq. 8), v the hauled-in speed
//!            (−l̇ on the platform side, r·α̇ at the drum); see [`super::path`]
//! creep      c_j: a Kelvin–Voigt element in series with the elastic stretch (polymer cables),
//!            ċ = (ρ·max(0, l_j − L_j − c_j) − c_j)/τ,  T_EE = max(0, E·A·(l_j − L_j − c_j)/L_j
//!            + c·(l̇_j + r·α̇_j − ċ_j)); settled, the cable's compliance is (1 + ρ)·L/(E·A)
//! winch j    J_l·α̈ = k_φ·r_gb·i − B_l·α̇ − k_j·τ_st·σ_ε(α̇) − r·T_drum     (seed 003 eqs 16–19;
//!            k_j = 1 unless a winch's friction differs)
//!            i = clamp(K_p·(e + D + z/t_i) + i_ff, ±I_max), e = α_ref − α   (eq. 13; eq. 12
//!            without the LPF), ż = e (held while saturated and e pushes further),
//!            Ḋ = ω_c·(t_d·(α̇_ref − α̇) − D)
//! ```
//!
//! Rotations: planar `θ` about `z`; spatial roll–pitch–yaw (`R = R_z·R_y·R_x`) with the angular
//! velocity `ω` in the world frame as the velocity state (singular at pitch ±90°).
//!
//! State `x = [q (n), v (n), α (m), α̇ (m), z (m), D (m), z_u (m), z_d (m), c (m)]`: pose
//! coordinates, platform velocity (planar `[ẋ, ẏ, θ̇]`; spatial `[ṗ, ω]`), drum angles and
//! rates, PID integrals and filtered derivatives, the Dahl states of the drum-side and
//! platform-side paths (held at 0 under Coulomb), and the creep stretches (m; held at 0
//! without creep). Input `u = [α_ref (m), α̇_ref (m), i_ff (m),
//! w_ext (n)]`. Output `y = [q (n), T_EE (m), T_PUL (m), i (m), T̂ (m), α (m)]` with the
//! motor-current tension estimate `T̂ = k_φ·r_gb·i/r` (seed 003 eqs 34–35).
//!
//! At α = 0 the platform rests at the home pose holding its weight with the home tensions (by
//! default the tension distribution there), its creep settled:
//! `L0_j = l_j(home)/(1 + (1 + ρ_j)·f0_j/(E·A)_j)`. The cable stretches over its length from the
//! frame (or its pulley) to the platform; the run from the drum to the frame is taken as
//! inextensible. [`closed_loop`] commands lengths with the settled compliance (a controller
//! calibrated statically), so creep shows in the transients: the platform sags or rises for
//! `τ` after each change of tension.

use super::controller::Controller;
use super::kinematics::{inverse_kinematics, CableGeometry, Pose};
use super::path::{dahl_slope, shared_or_own, PathFriction, PathLaw};
use super::robot::{Motion, Robot, MAX_CABLES};
use super::tension::Method;
use super::winch::Winch;
use crate::dynamics::Model;
use crate::error::{check, CableError, Result};
use crate::friction::smooth_sign;
use crate::integrate::{Rk4, MAX_SUBSTEPS};
use crate::nn::Mlp;
use nalgebra::{Matrix3, Matrix6, Vector3, Vector6};

/// A cable-driven parallel robot with its winches and pulleys as a [`Model`]; see the module
/// docs.
#[derive(Debug, Clone, PartialEq)]
pub struct CdprPlant {
    robot: Robot,
    winch: Winch,
    lpf: bool,
    current_limit: f64,
    friction_smoothing: f64,
    cable_damping: f64,
    drum_side: Vec<PathFriction>,
    platform_side: Vec<PathFriction>,
    creep: Vec<Creep>,
    drum_friction: Vec<f64>,
    home: Vec<f64>,
    home_tensions: Vec<f64>,
    rest_length: Vec<f64>,
}

/// The options of a [`CdprPlant`] besides the robot and the winch, with the defaults of
/// [`PlantOptions::default`].
#[derive(Debug, Clone, PartialEq)]
pub struct PlantOptions {
    /// The PID's derivative through the low-pass filter (seed 003 eq. 13); default true.
    pub lpf: bool,
    /// Servo amplifier current limit `I_max` (A), > 0; default 10 A (the ESCON 70/10).
    pub current_limit: f64,
    /// Smoothing velocity of the drum's static friction sign (rad/s), > 0; default 0.01.
    pub friction_smoothing: f64,
    /// Damping of each cable `c` (N·s/m), ≥ 0; default 50.
    pub cable_damping: f64,
    /// Friction between the drum and the sensor per cable (empty: none).
    pub drum_side: Vec<PathFriction>,
    /// Friction between the sensor and the platform per cable (empty: none).
    pub platform_side: Vec<PathFriction>,
    /// Tensions at the home pose (N, `m`); `None`: the tension distribution (`auto`) of the
    /// platform's weight there.
    pub home_tensions: Option<Vec<f64>>,
    /// Creep per cable (empty: none).
    pub creep: Vec<Creep>,
    /// Each winch's static friction as a multiple of the winch's `τ_st` (≥ 0; empty: 1 for
    /// every cable): winches of one design that differ (a worn gearbox, a tight bearing).
    pub drum_friction: Vec<f64>,
}

/// Creep of one cable (polymer cables: Dyneema, Kevlar): a Kelvin–Voigt element in series with
/// the elastic stretch, so that after a change of tension the cable keeps lengthening (or
/// recovering) with time constant `time_constant` until its stretch is `1 + ratio` times the
/// elastic one.
#[derive(Debug, Clone, Copy, PartialEq)]
pub struct Creep {
    /// `ρ = (E·A)/(E·A)_creep`, ≥ 0: the settled creep stretch per elastic stretch (0: none).
    pub ratio: f64,
    /// `τ` (s), > 0.
    pub time_constant: f64,
}

impl Creep {
    /// No creep.
    pub const NONE: Self = Self {
        ratio: 0.0,
        time_constant: 1.0,
    };

    /// Per cable from `(m,)` or shared `(1,)` columns.
    pub fn per_cable(ratio: &[f64], time_constant: &[f64], m: usize) -> Result<Vec<Self>> {
        (0..m)
            .map(|j| {
                let c = Self {
                    ratio: shared_or_own("creep ratio", ratio, j, m)?,
                    time_constant: shared_or_own("creep time_constant", time_constant, j, m)?,
                };
                c.validate().map(|()| c)
            })
            .collect()
    }

    /// `ratio` in `[0, 1e6]` (a creep a million times the elastic stretch is no cable; beyond
    /// it the rest state overflows), `time_constant` finite and > 0.
    pub fn validate(&self) -> Result<()> {
        check::at_most(
            "creep ratio",
            self.ratio,
            1e6,
            "finite, in [0, 1e6]: the settled creep stretch per elastic stretch",
        )?;
        check::positive("creep time_constant", self.time_constant)?;
        Ok(())
    }
}

impl Default for PlantOptions {
    fn default() -> Self {
        Self {
            lpf: true,
            current_limit: 10.0,
            friction_smoothing: 0.01,
            cable_damping: 50.0,
            drum_side: Vec::new(),
            platform_side: Vec::new(),
            home_tensions: None,
            creep: Vec::new(),
            drum_friction: Vec::new(),
        }
    }
}

/// No friction on a path.
fn frictionless() -> PathFriction {
    PathFriction {
        coefficient: 0.0,
        viscous: 0.0,
        guide_wrap: 0.0,
        law: PathLaw::Coulomb { smoothing: 1e-3 },
    }
}

/// Hauled-in speed `v`, the path's Dahl state `z` and tension `t` → friction force and `ż`.
#[inline]
fn path_force(p: &PathFriction, normal: f64, t: f64, v: f64, z: f64) -> (f64, f64) {
    match p.law {
        PathLaw::Coulomb { smoothing } => (
            p.coefficient * normal * t * smooth_sign(v, smoothing) + p.viscous * v,
            0.0,
        ),
        PathLaw::Dahl {
            presliding,
            exponent,
        } => (
            p.coefficient * normal * t * z + p.viscous * v,
            v * dahl_slope(z, v.signum(), presliding, exponent),
        ),
    }
}

/// What one evaluation of the plant computes besides the derivative.
#[derive(Debug, Clone, Copy)]
struct Eval {
    ee: [f64; MAX_CABLES],
    pul: [f64; MAX_CABLES],
    drum: [f64; MAX_CABLES],
    current: [f64; MAX_CABLES],
    command: [f64; MAX_CABLES],
}

impl CdprPlant {
    /// A validated plant for `robot` with one `winch` per cable, resting at `home` (pose
    /// coordinates) at α = 0. The platform needs a mass and an inertia about every axis it
    /// turns about (> 0); the home tensions must hold it within the cable bounds (a
    /// [`CableError::InvalidParameter`] otherwise) and leave every unstretched length positive.
    pub fn new(robot: &Robot, winch: Winch, home: &[f64], options: PlantOptions) -> Result<Self> {
        winch.validate()?;
        let m = robot.n_cables();
        check::positive("platform.mass", robot.platform.mass)?;
        let j = &robot.platform.inertia;
        match robot.motion {
            Motion::Planar => {
                check::positive("platform.inertia[2][2]", j[8])?;
            }
            Motion::Spatial => {
                let mat = Matrix3::from_row_slice(j);
                if mat.cholesky().is_none() {
                    return Err(CableError::InvalidParameter {
                        name: "platform.inertia".into(),
                        value: mat.determinant(),
                        requirement:
                            "positive definite (a spatial platform turns about every axis)",
                    });
                }
            }
        }
        check::positive("current_limit", options.current_limit)?;
        check::positive("friction_smoothing", options.friction_smoothing)?;
        check::non_negative("cable_damping", options.cable_damping)?;
        let paths = |what: &str, v: Vec<PathFriction>| -> Result<Vec<PathFriction>> {
            if v.is_empty() {
                return Ok(vec![frictionless(); m]);
            }
            if v.len() != m {
                return Err(CableError::Shape {
                    what: what.into(),
                    expected: format!("{m} paths (one per cable) or none"),
                    got: format!("{}", v.len()),
                });
            }
            v.iter().try_for_each(PathFriction::validate)?;
            Ok(v)
        };
        let creep = match options.creep.len() {
            0 => vec![Creep::NONE; m],
            k if k == m => options.creep,
            k => {
                return Err(CableError::Shape {
                    what: "creep".into(),
                    expected: format!("{m} cables or none"),
                    got: format!("{k}"),
                })
            }
        };
        creep.iter().try_for_each(Creep::validate)?;
        let drum_friction = match options.drum_friction.len() {
            0 => vec![1.0; m],
            _ => {
                check::len("drum_friction", &options.drum_friction, m)?;
                for (j, v) in options.drum_friction.iter().enumerate() {
                    check::non_negative(&format!("drum_friction[{j}]"), *v)?;
                }
                options.drum_friction
            }
        };
        let drum_side = paths("drum_side", options.drum_side)?;
        let platform_side = paths("platform_side", options.platform_side)?;
        let pose = Pose::from_coordinates(robot.motion, home)?;
        let mut g = CableGeometry::default();
        inverse_kinematics(robot, &pose, &mut g)?;
        let home_tensions = match options.home_tensions {
            Some(f) => {
                check::len("home_tensions", &f, m)?;
                check::all_finite("home_tensions", &f, 1)?;
                for (i, v) in f.iter().enumerate() {
                    check::non_negative(&format!("home_tensions[{i}]"), *v)?;
                }
                f
            }
            None => {
                let d = Controller::new(robot, Method::Auto, true)?.step(home, None)?;
                if !d.distribution.feasible {
                    return Err(CableError::InvalidParameter {
                        name: "home (the wrench error of the best tensions)".into(),
                        value: d.distribution.residual,
                        requirement: "a pose whose weight the cables hold within their bounds",
                    });
                }
                d.distribution.tensions().to_vec()
            }
        };
        let rest_length: Vec<f64> = (0..m)
            .map(|i| {
                let compliance = (1.0 + creep[i].ratio) / robot.cables[i].ea;
                g.length[i] / (1.0 + home_tensions[i] * compliance)
            })
            .collect();
        Ok(Self {
            robot: robot.clone(),
            winch,
            lpf: options.lpf,
            current_limit: options.current_limit,
            friction_smoothing: options.friction_smoothing,
            cable_damping: options.cable_damping,
            drum_side,
            platform_side,
            creep,
            drum_friction,
            home: home.to_vec(),
            home_tensions,
            rest_length,
        })
    }

    /// The robot.
    pub fn robot(&self) -> &Robot {
        &self.robot
    }
    /// The winch (every cable's).
    pub fn winch(&self) -> &Winch {
        &self.winch
    }
    /// The home pose.
    pub fn home(&self) -> &[f64] {
        &self.home
    }
    /// The tensions at the home pose (N).
    pub fn home_tensions(&self) -> &[f64] {
        &self.home_tensions
    }
    /// Unstretched cable lengths at α = 0 (m).
    pub fn rest_length(&self) -> &[f64] {
        &self.rest_length
    }
    /// The current limit (A).
    pub fn current_limit(&self) -> f64 {
        self.current_limit
    }

    /// Tension per ampere at the drum, `k_φ·r_gb/r` (N/A).
    pub fn tension_per_ampere(&self) -> f64 {
        let w = &self.winch;
        w.torque_constant * w.gear_ratio / w.drum_radius
    }

    /// The drum angle (rad) that sets cable `j`'s unstretched length to `length`.
    pub fn angle_for_length(&self, j: usize, length: f64) -> f64 {
        (self.rest_length[j] - length) / self.winch.drum_radius
    }

    /// The unstretched length at which cable `j` holds `tension` at geometric length `l`, its
    /// creep settled.
    pub fn unstretched_length(&self, j: usize, l: f64, tension: f64) -> f64 {
        l / (1.0 + tension * (1.0 + self.creep[j].ratio) / self.robot.cables[j].ea)
    }

    /// The creep of each cable.
    pub fn creep(&self) -> &[Creep] {
        &self.creep
    }

    fn sizes(&self) -> (usize, usize) {
        (self.robot.dof(), self.robot.n_cables())
    }

    /// Everything at `(x, u)`: writes `dx` if given; `None` where the pose is invalid (the
    /// geometry degenerates) or the platform's mass matrix is singular.
    fn eval(&self, x: &[f64], u: &[f64], dx: Option<&mut [f64]>) -> Option<Eval> {
        let (n, m) = self.sizes();
        let w = &self.winch;
        let r = w.drum_radius;
        let (q, v) = (&x[..n], &x[n..2 * n]);
        let off = 2 * n;
        let (alpha, omega) = (&x[off..off + m], &x[off + m..off + 2 * m]);
        let (zi, dd) = (&x[off + 2 * m..off + 3 * m], &x[off + 3 * m..off + 4 * m]);
        let (zu, zd) = (&x[off + 4 * m..off + 5 * m], &x[off + 5 * m..off + 6 * m]);
        let crept = &x[off + 6 * m..off + 7 * m];
        let (a_ref, w_ref, i_ff) = (&u[..m], &u[m..2 * m], &u[2 * m..3 * m]);
        let w_ext = &u[3 * m..3 * m + n];
        let pose = Pose::from_coordinates(self.robot.motion, q).ok()?;
        let mut g = CableGeometry::default();
        inverse_kinematics(&self.robot, &pose, &mut g).ok()?;
        let s = g.structure();
        let mut e = Eval {
            ee: [0.0; MAX_CABLES],
            pul: [0.0; MAX_CABLES],
            drum: [0.0; MAX_CABLES],
            current: [0.0; MAX_CABLES],
            command: [0.0; MAX_CABLES],
        };
        let mut dz = [[0.0; MAX_CABLES]; 3];
        for j in 0..m {
            let l_rate: f64 = -(0..n).map(|k| s[k * m + j] * v[k]).sum::<f64>();
            let len = self.rest_length[j] - r * alpha[j];
            let ea = self.robot.cables[j].ea;
            let cr = &self.creep[j];
            let elastic = g.length[j] - len - crept[j];
            dz[2][j] = if cr.ratio > 0.0 {
                (cr.ratio * elastic.max(0.0) - crept[j]) / cr.time_constant
            } else {
                0.0
            };
            let stretch =
                ea * elastic / len + self.cable_damping * (l_rate + r * omega[j] - dz[2][j]);
            let t_ee = if len > 0.0 {
                stretch.max(0.0)
            } else {
                f64::NAN
            };
            let pd = &self.platform_side[j];
            let (f_d, dzd) = path_force(pd, pd.normal_factor(g.wrap[j]), t_ee, -l_rate, zd[j]);
            let pul = (t_ee + f_d).max(0.0);
            let pu = &self.drum_side[j];
            let (f_u, dzu) = path_force(pu, pu.normal_factor(0.0), pul, r * omega[j], zu[j]);
            e.ee[j] = t_ee;
            e.pul[j] = pul;
            e.drum[j] = (pul + f_u).max(0.0);
            (dz[0][j], dz[1][j]) = (dzu, dzd);
            let err = a_ref[j] - alpha[j];
            let derivative = if self.lpf {
                dd[j]
            } else {
                w.td * (w_ref[j] - omega[j])
            };
            e.command[j] = w.kp * (err + derivative + zi[j] / w.ti) + i_ff[j];
            e.current[j] = e.command[j].clamp(-self.current_limit, self.current_limit);
        }
        let Some(dx) = dx else { return Some(e) };
        // platform
        let mut wrench = [0.0; 6];
        self.robot.gravity_wrench(&pose.rotation, &mut wrench);
        for k in 0..n {
            wrench[k] += w_ext[k] + (0..m).map(|j| s[k * m + j] * e.ee[j]).sum::<f64>();
        }
        let acc = self.platform_acceleration(&pose, v, &wrench[..n])?;
        dx[n..2 * n].copy_from_slice(&acc[..n]);
        match self.robot.motion {
            Motion::Planar => dx[..3].copy_from_slice(v),
            Motion::Spatial => {
                dx[..3].copy_from_slice(&v[..3]);
                let (sp, cp) = q[4].sin_cos();
                let (sy, cy) = q[5].sin_cos();
                let roll = (cy * v[3] + sy * v[4]) / cp;
                dx[3] = roll;
                dx[4] = -sy * v[3] + cy * v[4];
                dx[5] = v[5] + sp * roll;
            }
        }
        // winches
        for j in 0..m {
            let torque = w.torque_constant * w.gear_ratio * e.current[j]
                - w.load_viscous() * omega[j]
                - self.drum_friction[j]
                    * w.static_friction
                    * smooth_sign(omega[j], self.friction_smoothing)
                - r * e.drum[j];
            dx[off + j] = omega[j];
            dx[off + m + j] = torque / w.load_inertia();
            let err = a_ref[j] - alpha[j];
            let winding =
                e.command[j].abs() > self.current_limit && w.kp * err * e.command[j] > 0.0;
            dx[off + 2 * m + j] = if winding { 0.0 } else { err };
            dx[off + 3 * m + j] = if self.lpf {
                w.cutoff * (w.td * (w_ref[j] - omega[j]) - dd[j])
            } else {
                0.0
            };
            dx[off + 4 * m + j] = dz[0][j];
            dx[off + 5 * m + j] = dz[1][j];
            dx[off + 6 * m + j] = dz[2][j];
        }
        Some(e)
    }

    /// Platform acceleration `[a; ω̇]` (planar `[ẍ, ÿ, θ̈]`) under `wrench` about the origin.
    fn platform_acceleration(&self, pose: &Pose, v: &[f64], wrench: &[f64]) -> Option<[f64; 6]> {
        let p = &self.robot.platform;
        let mass = p.mass;
        let rc = pose.rotate(&p.com);
        let mut out = [0.0; 6];
        match self.robot.motion {
            Motion::Planar => {
                let (rx, ry, th) = (rc[0], rc[1], v[2]);
                let mm = Matrix3::new(
                    mass,
                    0.0,
                    -mass * ry,
                    0.0,
                    mass,
                    mass * rx,
                    -mass * ry,
                    mass * rx,
                    p.inertia[8] + mass * (rx * rx + ry * ry),
                );
                let rhs = Vector3::new(
                    wrench[0] + mass * th * th * rx,
                    wrench[1] + mass * th * th * ry,
                    wrench[2],
                );
                let a = mm.cholesky()?.solve(&rhs);
                out[..3].copy_from_slice(a.as_slice());
            }
            Motion::Spatial => {
                let rot = Matrix3::from_row_slice(&pose.rotation);
                let ic = rot * Matrix3::from_row_slice(&p.inertia) * rot.transpose();
                let c = Vector3::from(rc);
                let cx = c.cross_matrix();
                let om = Vector3::new(v[3], v[4], v[5]);
                let centripetal = om.cross(&om.cross(&c));
                let mut mm = Matrix6::zeros();
                mm.fixed_view_mut::<3, 3>(0, 0).fill_with_identity();
                mm.fixed_view_mut::<3, 3>(0, 0).scale_mut(mass);
                mm.fixed_view_mut::<3, 3>(0, 3).copy_from(&(-mass * cx));
                mm.fixed_view_mut::<3, 3>(3, 0).copy_from(&(mass * cx));
                mm.fixed_view_mut::<3, 3>(3, 3)
                    .copy_from(&(ic - mass * cx * cx));
                let f = Vector3::new(wrench[0], wrench[1], wrench[2]) - mass * centripetal;
                let tau = Vector3::new(wrench[3], wrench[4], wrench[5])
                    - om.cross(&(ic * om))
                    - mass * c.cross(&centripetal);
                let rhs = Vector6::new(f[0], f[1], f[2], tau[0], tau[1], tau[2]);
                let a = mm.cholesky()?.solve(&rhs);
                out.copy_from_slice(a.as_slice());
            }
        }
        Some(out)
    }
}

impl Model for CdprPlant {
    fn n_states(&self) -> usize {
        let (n, m) = self.sizes();
        2 * n + 7 * m
    }
    fn n_inputs(&self) -> usize {
        let (n, m) = self.sizes();
        3 * m + n
    }
    fn n_outputs(&self) -> usize {
        let (n, m) = self.sizes();
        n + 5 * m
    }

    /// NaN everywhere where the pose leaves the robot's geometry or a cable is wound in
    /// completely (the integrators report divergence).
    fn derivative(&self, x: &[f64], u: &[f64], dx: &mut [f64]) {
        if self.eval(x, u, Some(dx)).is_none() {
            dx.fill(f64::NAN);
        }
    }

    fn output(&self, x: &[f64], u: &[f64], y: &mut [f64]) {
        let (n, m) = self.sizes();
        let Some(e) = self.eval(x, u, None) else {
            y.fill(f64::NAN);
            return;
        };
        let k = self.tension_per_ampere();
        y[..n].copy_from_slice(&x[..n]);
        for j in 0..m {
            y[n + j] = e.ee[j];
            y[n + m + j] = e.pul[j];
            y[n + 2 * m + j] = e.current[j];
            y[n + 3 * m + j] = k * e.current[j];
            y[n + 4 * m + j] = x[2 * n + j];
        }
    }

    /// At rest at home: α = 0, each PID integral holding the current that carries the home
    /// tension at the drum (zero with `K_p = 0`), the creep settled.
    fn rest_state(&self) -> Vec<f64> {
        let (n, m) = self.sizes();
        let w = &self.winch;
        let mut x = vec![0.0; 2 * n + 7 * m];
        x[..n].copy_from_slice(&self.home);
        for j in 0..m {
            let ea = self.robot.cables[j].ea;
            x[2 * n + 6 * m + j] =
                self.creep[j].ratio * self.home_tensions[j] * self.rest_length[j] / ea;
        }
        if w.kp.abs() > 0.0 {
            for j in 0..m {
                let hold = (self.home_tensions[j] / self.tension_per_ampere())
                    .clamp(-self.current_limit, self.current_limit);
                x[2 * n + 2 * m + j] = hold * w.ti / w.kp;
            }
        }
        x
    }

    fn state_names(&self) -> Vec<String> {
        let (n, m) = self.sizes();
        let mut names = pose_names(self.robot.motion, "");
        names.extend(pose_names(self.robot.motion, "_dot").into_iter().take(n));
        if self.robot.motion == Motion::Spatial {
            for (k, a) in ["x", "y", "z"].iter().enumerate() {
                names[n + 3 + k] = format!("omega_{a}");
            }
        }
        for prefix in [
            "alpha",
            "alpha_dot",
            "error_integral",
            "derivative_filtered",
            "dahl_drum_side",
            "dahl_platform_side",
            "creep",
        ] {
            names.extend((0..m).map(|j| format!("{prefix}_{j}")));
        }
        names
    }
    fn input_names(&self) -> Vec<String> {
        let (n, m) = self.sizes();
        let mut names = Vec::with_capacity(3 * m + n);
        for prefix in ["alpha_ref", "alpha_ref_dot", "current_ff"] {
            names.extend((0..m).map(|j| format!("{prefix}_{j}")));
        }
        match self.robot.motion {
            Motion::Planar => names.extend(["f_x", "f_y", "m_z"].map(String::from)),
            Motion::Spatial => {
                names.extend(["f_x", "f_y", "f_z", "m_x", "m_y", "m_z"].map(String::from))
            }
        }
        names
    }
    fn output_names(&self) -> Vec<String> {
        let m = self.robot.n_cables();
        let mut names = pose_names(self.robot.motion, "");
        for prefix in [
            "tension_ee",
            "tension_pul",
            "current",
            "tension_from_current",
            "alpha",
        ] {
            names.extend((0..m).map(|j| format!("{prefix}_{j}")));
        }
        names
    }
}

fn pose_names(motion: Motion, suffix: &str) -> Vec<String> {
    let base: &[&str] = match motion {
        Motion::Planar => &["x", "y", "theta"],
        Motion::Spatial => &["x", "y", "z", "roll", "pitch", "yaw"],
    };
    base.iter().map(|b| format!("{b}{suffix}")).collect()
}

/// Which tension closes seed 002's force loop (`f_u = k_p·(f_d − f̂)`).
#[derive(Debug, Clone, Copy, PartialEq, Eq)]
pub enum Feedback {
    /// No force loop: the lengths alone (with the elastic feed-forward) set the tensions.
    Open,
    /// The platform-side tension (an ideal sensor at the platform).
    Platform,
    /// The winch-side sensor (PUL), with its noise.
    Sensor,
    /// A network's estimate of the platform-side tension from the desired position and
    /// velocity and the sensor (seed 002's NN-tension).
    Network,
}

impl Feedback {
    /// From its name (`"open"`, `"platform"`, `"sensor"`, `"network"`).
    pub fn from_name(name: &str) -> Result<Self> {
        match name {
            "open" => Ok(Self::Open),
            "platform" => Ok(Self::Platform),
            "sensor" => Ok(Self::Sensor),
            "network" => Ok(Self::Network),
            other => Err(CableError::InvalidOption {
                name: "feedback".into(),
                value: other.into(),
                allowed: "open, platform, sensor, network".into(),
            }),
        }
    }
}

/// The trajectory controller of [`closed_loop`].
#[derive(Debug, Clone, Copy, PartialEq)]
pub struct LoopOptions {
    /// Controller period (s), > 0.
    pub dt: f64,
    /// RK4 steps of the plant per period (1 ..= `MAX_SUBSTEPS`).
    pub substeps: usize,
    /// Tension distribution method for `f_d` (seed 002 uses the closed form).
    pub method: Method,
    /// Force-loop gain `k_p` (seed 002 Table 3), ≥ 0.
    pub gain: f64,
    /// The tension the force loop feeds back.
    pub feedback: Feedback,
    /// Periods by which the fed-back tensions lag beyond the one period of any sampled loop
    /// (a sensor's conversion and link latency); default 0.
    pub sensor_delay: usize,
    /// Feed forward the current that carries the target tension at the drum and turns the drum
    /// as referenced (step 4 of [`closed_loop`]); default true.
    pub current_feedforward: bool,
}

impl LoopOptions {
    /// Period `dt`, 5 substeps, `auto` distribution, no force loop, no extra delay, current
    /// feed-forward.
    pub fn new(dt: f64) -> Self {
        Self {
            dt,
            substeps: 5,
            method: Method::Auto,
            gain: 0.0,
            feedback: Feedback::Open,
            sensor_delay: 0,
            current_feedforward: true,
        }
    }
}

/// A [`closed_loop`] run: per controller period `k` (rows), row-major.
#[derive(Debug, Clone, PartialEq)]
pub struct LoopRun {
    /// Samples `T`.
    pub samples: usize,
    /// Platform pose `(T, n)`.
    pub pose: Vec<f64>,
    /// Desired tensions `f_d` `(T, m)` (N).
    pub desired: Vec<f64>,
    /// Platform-side tensions `(T, m)` (N).
    pub ee: Vec<f64>,
    /// Winch-side sensor `(T, m)` (N, noise included).
    pub sensor: Vec<f64>,
    /// The tension the force loop used `(T, m)` (N; the sensor under `Open`).
    pub feedback: Vec<f64>,
    /// Motor currents `(T, m)` (A), each its period's mean (trapezoidal: just after the
    /// period's reference step and at its end), as a drive's current measurement averages. (The
    /// PID runs continuously inside the period, so the current at the period's end alone sits
    /// about `K_p·α̇·Δt/2` below the mean that turned the drum.)
    pub current: Vec<f64>,
    /// Drum angles `(T, m)` (rad).
    pub alpha: Vec<f64>,
    /// Desired wrench `Aᵀ·f_d = M·ẍ_d − w_g` at the desired pose `(T, n)`.
    pub wrench_desired: Vec<f64>,
    /// Actual cable wrench `Aᵀ(q)·T_EE` at the actual pose `(T, n)`.
    pub wrench_ee: Vec<f64>,
    /// `Aᵀ(q_d)·T_PUL` from the sensor `(T, n)`.
    pub wrench_sensor: Vec<f64>,
    /// `Aᵀ(q_d)·f̂` from the fed-back tension `(T, n)`.
    pub wrench_feedback: Vec<f64>,
    /// Periods whose `f_d` was not feasible (the distribution's closest answer was used).
    pub infeasible: usize,
    /// The plant's inputs per period `(T, 3m + n)`, held over the period: with
    /// [`LoopRun::initial_state`] they replay the run through the model (the simulator, the
    /// sr-UKF).
    pub inputs: Vec<f64>,
    /// The plant's state at the start.
    pub initial_state: Vec<f64>,
}

/// Run `plant` under the trajectory controller: desired poses `(T, n)` every `opts.dt`
/// (velocity and acceleration by central differences), starting at rest at its home pose
/// (which should be the first desired pose). Each period:
///
/// 1. `f_d` = the tension distribution of the weight and the inertia `M·ẍ_d` at `q_d`;
/// 2. `f̂` = the fed-back tension measured at the end of period `k − 1 − sensor_delay` (the
///    home tensions before; `sensor_noise` `(T, m)` N is added to the sensor);
/// 3. `f_u = k_p·(f_d − f̂)` (0 under [`Feedback::Open`]);
/// 4. the drums take the unstretched lengths that give the target `f_t = max(0, f_d + f_u)`
///    at `q_d` (the length loop of seed 002 eq. 15), the rate `α̇_ref = A·v_d/r` of the desired
///    motion, and the current that carries the target at the drum and turns it as referenced,
///    `i_ff = (r·f_t + B_l·α̇_ref + J_l·α̈_ref)/(k_φ·r_gb)` (seed 003's winch is soft against a
///    stiff cable: a length alone would hold a tension only through the PID's integral);
/// 5. the plant advances one period.
///
/// `tension_offset` `(T, m)` N is added to `f_d` in step 4 (an excitation: in the null space
/// of `Aᵀ` it changes the internal forces and not the wrench).
///
/// `network` (14 → 8 for seed 002's robot: inputs the desired position and linear velocity
/// and the `m` sensor tensions, outputs the `m` platform-side tensions) is needed by
/// [`Feedback::Network`]. A diverged plant is [`CableError::Diverged`] at its period.
pub fn closed_loop(
    plant: &CdprPlant,
    poses: &[f64],
    opts: &LoopOptions,
    sensor_noise: Option<&[f64]>,
    tension_offset: Option<&[f64]>,
    network: Option<&Mlp>,
) -> Result<LoopRun> {
    let (n, m) = plant.sizes();
    check::positive("dt", opts.dt)?;
    check::non_negative("gain", opts.gain)?;
    if opts.substeps == 0 || opts.substeps > MAX_SUBSTEPS {
        return Err(CableError::InvalidParameter {
            name: "substeps".into(),
            value: opts.substeps as f64,
            requirement: "between 1 and 100000",
        });
    }
    if poses.is_empty() || !poses.len().is_multiple_of(n) {
        return Err(CableError::Shape {
            what: "poses".into(),
            expected: format!("(T ≥ 1, {n})"),
            got: format!("{} values", poses.len()),
        });
    }
    check::all_finite("poses", poses, n)?;
    let t_len = poses.len() / n;
    if let Some(noise) = sensor_noise {
        check::len("sensor_noise", noise, t_len * m)?;
        check::all_finite("sensor_noise", noise, m)?;
    }
    if let Some(offset) = tension_offset {
        check::len("tension_offset", offset, t_len * m)?;
        check::all_finite("tension_offset", offset, m)?;
    }
    let translation = match plant.robot.motion {
        Motion::Planar => 2,
        Motion::Spatial => 3,
    };
    let net = match (opts.feedback, network) {
        (Feedback::Network, None) => {
            return Err(CableError::InvalidOption {
                name: "network".into(),
                value: "None".into(),
                allowed: "a network (feedback = \"network\" needs one)".into(),
            })
        }
        (Feedback::Network, Some(net)) => {
            if net.n_inputs() != 2 * translation + m || net.n_outputs() != m {
                return Err(CableError::Shape {
                    what: "network".into(),
                    expected: format!("{} inputs and {m} outputs", 2 * translation + m),
                    got: format!("{} inputs and {} outputs", net.n_inputs(), net.n_outputs()),
                });
            }
            Some(net)
        }
        _ => None,
    };
    let mut scratch = net.map(Mlp::scratch);
    let mut ctl = Controller::new(&plant.robot, opts.method, true)?;
    let mut rk = Rk4::for_model(plant);
    let mut x = plant.rest_state();
    if opts.current_feedforward {
        x[2 * n + 2 * m..2 * n + 3 * m].fill(0.0);
    }
    let mut u = vec![0.0; 3 * m + n];
    let mut y = vec![0.0; n + 5 * m];
    let mut y_start = y.clone();
    let (tm, tn) = (t_len * m, t_len * n);
    let mut run = LoopRun {
        samples: t_len,
        pose: vec![0.0; tn],
        desired: vec![0.0; tm],
        ee: vec![0.0; tm],
        sensor: vec![0.0; tm],
        feedback: vec![0.0; tm],
        current: vec![0.0; tm],
        alpha: vec![0.0; tm],
        wrench_desired: vec![0.0; tn],
        wrench_ee: vec![0.0; tn],
        wrench_sensor: vec![0.0; tn],
        wrench_feedback: vec![0.0; tn],
        infeasible: 0,
        inputs: vec![0.0; t_len * (3 * m + n)],
        initial_state: x.clone(),
    };
    let row = |k: usize| &poses[k.min(t_len - 1) * n..(k.min(t_len - 1) + 1) * n];
    let mut last_rate: Option<Vec<f64>> = None;
    // platform-side and (noiseless) sensor tensions at the end of each period, for the delay
    let mut pul_raw = vec![0.0; tm];
    let mut measured_ee = plant.home_tensions.clone();
    let mut measured_pul = plant.home_tensions.clone();
    let mut f_hat = vec![0.0; m];
    let mut noisy = vec![0.0; m];
    let mut net_in = vec![0.0; 2 * translation + m];
    let mut geom = CableGeometry::default();
    let mut inertial = [0.0; 6];
    for k in 0..t_len {
        // desired motion by central differences (one-sided at the ends)
        let (a, b) = (k.saturating_sub(1), (k + 1).min(t_len - 1));
        let qd = row(k);
        let span = (b - a).max(1) as f64 * opts.dt;
        let mut vel = [0.0; 6];
        let mut acc = [0.0; 6];
        for i in 0..n {
            vel[i] = (row(b)[i] - row(a)[i]) / span;
            if k > 0 && k + 1 < t_len {
                acc[i] = (row(k + 1)[i] - 2.0 * qd[i] + row(k - 1)[i]) / (opts.dt * opts.dt);
            }
        }
        inertial_wrench(&plant.robot, &acc[..n], &mut inertial[..n]);
        let step = ctl.step(qd, Some(&inertial[..n]))?;
        let fd = step.distribution.tensions();
        if !step.distribution.feasible {
            run.infeasible += 1;
        }
        geom.clone_from(ctl.geometry());
        // the fed-back tension: the measurement `sensor_delay` periods before the last one
        if let Some(p) = k.checked_sub(opts.sensor_delay.saturating_add(1)) {
            measured_ee.copy_from_slice(&run.ee[p * m..(p + 1) * m]);
            measured_pul.copy_from_slice(&pul_raw[p * m..(p + 1) * m]);
        }
        for (j, v) in noisy.iter_mut().enumerate() {
            *v = measured_pul[j] + sensor_noise.map_or(0.0, |s| s[k * m + j]);
        }
        match opts.feedback {
            Feedback::Open | Feedback::Sensor => f_hat.copy_from_slice(&noisy),
            Feedback::Platform => f_hat.copy_from_slice(&measured_ee),
            Feedback::Network => {
                net_in[..translation].copy_from_slice(&qd[..translation]);
                net_in[translation..2 * translation].copy_from_slice(&vel[..translation]);
                net_in[2 * translation..].copy_from_slice(&noisy);
                if let (Some(net), Some(s)) = (net, scratch.as_mut()) {
                    net.forward_with(&net_in, &mut f_hat, s)?;
                }
            }
        }
        let gain = if opts.feedback == Feedback::Open {
            0.0
        } else {
            opts.gain
        };
        let wch = &plant.winch;
        let sd = geom.structure();
        for j in 0..m {
            let excite = tension_offset.map_or(0.0, |o| o[k * m + j]);
            let target = (fd[j] + excite + gain * (fd[j] - f_hat[j])).max(0.0);
            u[j] = plant.angle_for_length(j, plant.unstretched_length(j, geom.length[j], target));
            // the drum rate that follows the desired motion (l̇ = −A·v), and its change
            let rate = (0..n).map(|i| sd[i * m + j] * vel[i]).sum::<f64>() / wch.drum_radius;
            let accel = last_rate
                .as_ref()
                .map_or(0.0, |l: &Vec<f64>| (rate - l[j]) / opts.dt);
            u[m + j] = rate;
            u[2 * m + j] = if opts.current_feedforward {
                (wch.drum_radius * target + wch.load_viscous() * rate + wch.load_inertia() * accel)
                    / (wch.torque_constant * wch.gear_ratio)
            } else {
                0.0
            };
        }
        last_rate = Some(u[m..2 * m].to_vec());
        run.inputs[k * (3 * m + n)..(k + 1) * (3 * m + n)].copy_from_slice(&u);
        plant.output(&x, &u, &mut y_start);
        rk.advance(plant, &mut x, &u, &u, opts.dt, opts.substeps);
        if !x.iter().all(|v| v.is_finite()) {
            return Err(CableError::Diverged {
                step: k,
                time_s: k as f64 * opts.dt,
            });
        }
        plant.output(&x, &u, &mut y);
        // record
        let s_d = geom.structure();
        run.pose[k * n..(k + 1) * n].copy_from_slice(&y[..n]);
        for j in 0..m {
            pul_raw[k * m + j] = y[n + m + j];
            let i = k * m + j;
            run.desired[i] = fd[j];
            run.ee[i] = y[n + j];
            run.sensor[i] = noisy[j];
            run.feedback[i] = f_hat[j];
            run.current[i] = 0.5 * (y_start[n + 2 * m + j] + y[n + 2 * m + j]);
            run.alpha[i] = y[n + 4 * m + j];
        }
        let actual = Pose::from_coordinates(plant.robot.motion, &y[..n])?;
        let mut g = CableGeometry::default();
        inverse_kinematics(&plant.robot, &actual, &mut g)?;
        let s_a = g.structure();
        for i in 0..n {
            let at = k * n + i;
            let dot = |s: &[f64], f: &[f64]| (0..m).map(|j| s[i * m + j] * f[j]).sum::<f64>();
            run.wrench_desired[at] = dot(s_d, fd);
            run.wrench_ee[at] = dot(s_a, &y[n..n + m]);
            run.wrench_sensor[at] = dot(s_d, &noisy);
            run.wrench_feedback[at] = dot(s_d, &f_hat);
        }
    }
    Ok(run)
}

/// `−M·ẍ` as an external wrench for the distribution: the mass times the acceleration and the
/// inertia times the orientation coordinates' second derivatives (the angular acceleration
/// for small angles; gyroscopic terms and the centre of mass's offset are neglected).
fn inertial_wrench(robot: &Robot, acc: &[f64], out: &mut [f64]) {
    let p = &robot.platform;
    match robot.motion {
        Motion::Planar => {
            out[0] = -p.mass * acc[0];
            out[1] = -p.mass * acc[1];
            out[2] = -p.inertia[8] * acc[2];
        }
        Motion::Spatial => {
            for i in 0..3 {
                out[i] = -p.mass * acc[i];
                out[3 + i] = -(0..3)
                    .map(|c| p.inertia[3 * i + c] * acc[3 + c])
                    .sum::<f64>();
            }
        }
    }
}

#[cfg(test)]
mod tests {
    use super::*;
    use crate::cdpr::tests::{box_robot, planar_robot};

    fn coulomb(mu: f64, wrap: f64, m: usize) -> Vec<PathFriction> {
        vec![
            PathFriction {
                coefficient: mu,
                viscous: 2.0,
                guide_wrap: wrap,
                law: PathLaw::Coulomb { smoothing: 1e-3 },
            };
            m
        ]
    }

    fn circle(home: &[f64], n: usize, radius: f64, period: f64, dt: f64, t_end: f64) -> Vec<f64> {
        let steps = (t_end / dt) as usize;
        let mut poses = Vec::with_capacity(steps * n);
        for k in 0..steps {
            let t = k as f64 * dt;
            // start at rest: the radius ramps in over the first second
            let tau = (t / 1.0).min(1.0);
            let ramp = tau * tau * (3.0 - 2.0 * tau);
            let ph = std::f64::consts::TAU * t / period;
            let mut q = home.to_vec();
            q[0] += ramp * radius * ph.sin();
            q[1] += ramp * radius * (1.0 - ph.cos());
            poses.extend(q);
        }
        poses
    }

    fn rmse(a: &[f64], b: &[f64]) -> f64 {
        (a.iter().zip(b).map(|(x, y)| (x - y).powi(2)).sum::<f64>() / a.len() as f64).sqrt()
    }

    fn run(plant: &CdprPlant, poses: &[f64], feedback: Feedback, gain: f64) -> LoopRun {
        let mut o = LoopOptions::new(1e-3);
        o.feedback = feedback;
        o.gain = gain;
        closed_loop(plant, poses, &o, None, None, None).unwrap()
    }

    /// At rest at home the plant is in equilibrium (every derivative 0) and both sensors and
    /// the current estimate read the home tensions: planar, and spatial with pulleys and the
    /// centre of mass off the origin.
    #[test]
    fn a_creep_ratio_past_any_cable_is_refused() {
        assert!(Creep::per_cable(&[1e308], &[1.0], 4).is_err());
        assert!(Creep::per_cable(&[2.0], &[1.0], 4).is_ok());
    }

    #[test]
    fn rest_is_an_equilibrium_holding_the_home_tensions() {
        for (robot, home) in [
            (planar_robot(), vec![0.5, 0.4, 0.0]),
            (box_robot(true), vec![0.02, -0.01, 0.03, 0.0, 0.0, 0.05]),
        ] {
            let plant =
                CdprPlant::new(&robot, Winch::seed003(), &home, PlantOptions::default()).unwrap();
            let (n, m) = (robot.dof(), robot.n_cables());
            let x = plant.rest_state();
            let u = vec![0.0; plant.n_inputs()];
            let mut dx = vec![1.0; plant.n_states()];
            plant.derivative(&x, &u, &mut dx);
            let worst = dx.iter().fold(0.0_f64, |a, b| a.max(b.abs()));
            assert!(worst < 1e-8, "{}: |dx| = {worst:e}", robot.name);
            let mut y = vec![0.0; plant.n_outputs()];
            plant.output(&x, &u, &mut y);
            for j in 0..m {
                let f0 = plant.home_tensions()[j];
                assert!(f0 >= robot.cables[j].f_min - 1e-9);
                for (what, v) in [
                    ("ee", y[n + j]),
                    ("pul", y[n + m + j]),
                    ("current", y[n + 3 * m + j]),
                ] {
                    assert!(
                        (v - f0).abs() < 1e-9 * (1.0 + f0),
                        "{what} {j}: {v} vs {f0}"
                    );
                }
            }
            assert_eq!(plant.state_names().len(), plant.n_states());
            assert_eq!(plant.input_names().len(), plant.n_inputs());
            assert_eq!(plant.output_names().len(), plant.n_outputs());
        }
    }

    /// Creep: at rest with settled creep the plant is in equilibrium; after a push held for
    /// 20 s (`τ` = 3 s) the platform has sunk further than without creep, and each cable's
    /// creep has settled at `ρ` times its elastic stretch.
    #[test]
    fn creep_lets_the_platform_sink_further_and_settles_at_its_ratio() {
        let robot = planar_robot();
        let home = [0.5, 0.4, 0.0];
        let (n, m) = (robot.dof(), robot.n_cables());
        let sink = |ratio: f64| {
            let opts = PlantOptions {
                creep: vec![
                    Creep {
                        ratio,
                        time_constant: 3.0,
                    };
                    m
                ],
                ..PlantOptions::default()
            };
            let plant = CdprPlant::new(&robot, Winch::seed003(), &home, opts).unwrap();
            let mut x = plant.rest_state();
            let mut u = vec![0.0; plant.n_inputs()];
            let mut dx = vec![1.0; plant.n_states()];
            plant.derivative(&x, &u, &mut dx);
            assert!(dx.iter().all(|d| d.abs() < 1e-8), "rest with creep {ratio}");
            u[3 * m + 1] = -20.0;
            let mut rk = Rk4::for_model(&plant);
            let mut y = 0.0;
            for k in 0..20_000 {
                rk.advance(&plant, &mut x, &u, &u, 1e-3, 2);
                if k == 19_999 {
                    y = home[1] - x[1];
                }
            }
            (plant, x, y)
        };
        let (_, _, stiff) = sink(0.0);
        let (plant, x, creepy) = sink(0.5);
        assert!(stiff > 0.0 && creepy > 1.3 * stiff, "{creepy} vs {stiff}");
        let pose = Pose::from_coordinates(robot.motion, &x[..n]).unwrap();
        let mut g = CableGeometry::default();
        inverse_kinematics(&robot, &pose, &mut g).unwrap();
        for j in 0..m {
            let len = plant.rest_length()[j] - plant.winch().drum_radius * x[2 * n + j];
            let c = x[2 * n + 6 * m + j];
            let elastic = g.length[j] - len - c;
            assert!(
                (c - 0.5 * elastic).abs() < 1e-3 * c.abs(),
                "{j}: {c} vs {elastic}"
            );
        }
    }

    /// With no wrench, the rigid body (centre of mass off the origin, a full inertia, spinning
    /// about no principal axis) keeps its kinetic energy and its linear and angular momenta.
    #[test]
    fn a_free_platform_keeps_its_energy_and_momenta() {
        let mut robot = box_robot(false);
        robot.platform.com = [0.02, -0.01, 0.015];
        robot.platform.inertia = [2e-3, 2e-4, -1e-4, 2e-4, 3e-3, 3e-4, -1e-4, 3e-4, 4e-3];
        let plant =
            CdprPlant::new(&robot, Winch::seed003(), &[0.0; 6], PlantOptions::default()).unwrap();
        let mass = robot.platform.mass;
        let body = |q: &[f64], v: &[f64]| {
            let pose = Pose::from_coordinates(Motion::Spatial, q).unwrap();
            let rot = Matrix3::from_row_slice(&pose.rotation);
            let ic = rot * Matrix3::from_row_slice(&robot.platform.inertia) * rot.transpose();
            let c = Vector3::from(pose.rotate(&robot.platform.com));
            let om = Vector3::new(v[3], v[4], v[5]);
            let vc = Vector3::new(v[0], v[1], v[2]) + om.cross(&c);
            let energy = 0.5 * mass * vc.norm_squared() + 0.5 * om.dot(&(ic * om));
            let p = mass * vc;
            let pc = Vector3::new(q[0], q[1], q[2]) + c;
            let l = ic * om + pc.cross(&p);
            (energy, p, l)
        };
        let f = |s: &[f64; 12]| -> [f64; 12] {
            let (q, v) = (&s[..6], &s[6..]);
            let pose = Pose::from_coordinates(Motion::Spatial, q).unwrap();
            let a = plant.platform_acceleration(&pose, v, &[0.0; 6]).unwrap();
            let (sp, cp) = q[4].sin_cos();
            let (sy, cy) = q[5].sin_cos();
            let roll = (cy * v[3] + sy * v[4]) / cp;
            let mut d = [0.0; 12];
            d[..3].copy_from_slice(&v[..3]);
            d[3] = roll;
            d[4] = -sy * v[3] + cy * v[4];
            d[5] = v[5] + sp * roll;
            d[6..].copy_from_slice(&a);
            d
        };
        let mut s = [
            0.0, 0.0, 0.0, 0.1, -0.2, 0.3, 0.05, -0.02, 0.01, 1.5, -0.7, 2.0,
        ];
        let (e0, p0, l0) = body(&s[..6], &s[6..]);
        let h = 1e-4;
        for _ in 0..5000 {
            let k1 = f(&s);
            let k2 = f(&std::array::from_fn(|i| s[i] + 0.5 * h * k1[i]));
            let k3 = f(&std::array::from_fn(|i| s[i] + 0.5 * h * k2[i]));
            let k4 = f(&std::array::from_fn(|i| s[i] + h * k3[i]));
            s = std::array::from_fn(|i| {
                s[i] + h / 6.0 * (k1[i] + 2.0 * k2[i] + 2.0 * k3[i] + k4[i])
            });
        }
        let (e1, p1, l1) = body(&s[..6], &s[6..]);
        assert!((e1 - e0).abs() < 1e-9 * e0, "energy {e0} -> {e1}");
        assert!((p1 - p0).norm() < 1e-9, "momentum {p0} -> {p1}");
        assert!((l1 - l0).norm() < 1e-9, "angular momentum {l0} -> {l1}");
    }

    /// Seed 002's force loop: frictionless, the feed-forward alone tracks `f_d`; with pulley
    /// friction between the sensor and the platform, feeding back the platform-side tension
    /// takes the error down by about `1/(1 + k_p)`, while feeding back the winch-side sensor
    /// cannot (it reads the friction as tension).
    #[test]
    fn the_force_loop_needs_the_platform_side_tension() {
        let robot = planar_robot();
        let home = [0.5, 0.4, 0.0];
        let poses = circle(&home, 3, 0.05, 2.0, 1e-3, 4.0);
        let plain = CdprPlant::new(
            &robot,
            Winch {
                static_friction: 0.0,
                ..Winch::seed003()
            },
            &home,
            PlantOptions::default(),
        )
        .unwrap();
        let r = run(&plain, &poses, Feedback::Open, 0.0);
        assert!(
            rmse(&r.ee, &r.desired) < 0.05,
            "{}",
            rmse(&r.ee, &r.desired)
        );
        assert!(rmse(&r.pose, &poses) < 1e-4);
        assert_eq!(r.infeasible, 0);
        let opts = PlantOptions {
            platform_side: coulomb(0.05, std::f64::consts::PI, 4),
            ..PlantOptions::default()
        };
        let rough = CdprPlant::new(
            &robot,
            Winch {
                static_friction: 0.0,
                ..Winch::seed003()
            },
            &home,
            opts,
        )
        .unwrap();
        let err = |fb, k| {
            let r = run(&rough, &poses, fb, k);
            rmse(&r.ee, &r.desired)
        };
        let open = err(Feedback::Open, 0.0);
        assert!(open > 1.0, "{open}");
        let (p07, p3) = (err(Feedback::Platform, 0.7), err(Feedback::Platform, 3.0));
        assert!(
            p07 < 0.7 * open && p3 < 0.3 * open && p3 < p07,
            "{open} {p07} {p3}"
        );
        let s07 = err(Feedback::Sensor, 0.7);
        assert!(s07 > 0.95 * open, "{open} {s07}");
    }

    #[test]
    fn bad_input_is_a_typed_error() {
        let robot = planar_robot();
        let home = [0.5, 0.4, 0.0];
        let plant =
            CdprPlant::new(&robot, Winch::seed003(), &home, PlantOptions::default()).unwrap();
        let poses = vec![0.5, 0.4, 0.0, 0.5, 0.4, 0.0];
        let mut o = LoopOptions::new(1e-3);
        o.feedback = Feedback::Network;
        assert!(matches!(
            closed_loop(&plant, &poses, &o, None, None, None),
            Err(CableError::InvalidOption { .. })
        ));
        let mut o = LoopOptions::new(1e-3);
        o.substeps = 0;
        assert!(matches!(
            closed_loop(&plant, &poses, &o, None, None, None),
            Err(CableError::InvalidParameter { .. })
        ));
        let o = LoopOptions::new(1e-3);
        assert!(matches!(
            closed_loop(&plant, &poses[..4], &o, None, None, None),
            Err(CableError::Shape { .. })
        ));
        assert!(matches!(
            closed_loop(&plant, &poses, &o, Some(&[0.0; 3]), None, None),
            Err(CableError::Shape { .. })
        ));
        let mut bad = poses.clone();
        bad[1] = f64::NAN;
        assert!(matches!(
            closed_loop(&plant, &bad, &o, None, None, None),
            Err(CableError::NotFinite { .. })
        ));
        // outside the frame: the weight cannot be held
        assert!(CdprPlant::new(
            &robot,
            Winch::seed003(),
            &[0.5, 2.0, 0.0],
            PlantOptions::default()
        )
        .is_err());
        let mut light = robot.clone();
        light.platform.mass = 0.0;
        assert!(matches!(
            CdprPlant::new(&light, Winch::seed003(), &home, PlantOptions::default()),
            Err(CableError::InvalidParameter { .. })
        ));
        let opts = PlantOptions {
            platform_side: coulomb(0.05, 1.0, 3),
            ..PlantOptions::default()
        };
        assert!(matches!(
            CdprPlant::new(&robot, Winch::seed003(), &home, opts),
            Err(CableError::Shape { .. })
        ));
        let opts = PlantOptions {
            cable_damping: -1.0,
            ..PlantOptions::default()
        };
        assert!(CdprPlant::new(&robot, Winch::seed003(), &home, opts).is_err());
    }
}
