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

use super::Model;
use crate::cdpr::winch::Winch;
use crate::cdpr::{
    dahl_slope, inverse_kinematics, shared_or_own, CableGeometry, Controller, Method, Motion,
    PathFriction, PathLaw, Pose, Robot, MAX_CABLES,
};
use crate::error::{check, CableError, Result};
use crate::friction::smooth_sign;
use nalgebra::{Matrix3, Matrix6, Vector3, Vector6};

/// A cable-driven parallel robot with its winches and pulleys as a [`Model`]; see the module
/// docs.
#[derive(Debug, Clone, PartialEq)]
pub struct CdprPlant {
    pub(crate) robot: Robot,
    pub(crate) winch: Winch,
    lpf: bool,
    current_limit: f64,
    friction_smoothing: f64,
    cable_damping: f64,
    drum_side: Vec<PathFriction>,
    platform_side: Vec<PathFriction>,
    creep: Vec<Creep>,
    drum_friction: Vec<f64>,
    home: Vec<f64>,
    pub(crate) home_tensions: Vec<f64>,
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

    pub(crate) fn sizes(&self) -> (usize, usize) {
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
    pub(crate) fn platform_acceleration(
        &self,
        pose: &Pose,
        v: &[f64],
        wrench: &[f64],
    ) -> Option<[f64; 6]> {
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
