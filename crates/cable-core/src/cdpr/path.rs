//! Friction on a cable's path between a winch-side tension sensor and the platform (seed 002
//! §3.1): the tension the sensor reads (PUL) is the platform-side tension (EE) plus the friction
//! of the pulleys between them.
//!
//! ```text
//! v = −dl/dt                         the cable's speed towards the winch (hauled in: v > 0)
//! F_n = T_EE · N(θ),  N(θ) = 2·sin(θ_g/2) + 2·sin(θ_e/2)
//!                                    the pulleys' normal force: the guides' fixed wrap θ_g and
//!                                    the exit pulley's wrap θ_e, which moves with the pose
//! Coulomb + viscous (eq. 7):  F_f = μ·F_n·σ_ε(v) + σ_v·v
//! Dahl (eq. 8):               F_f = μ·F_n·z + σ_v·v,
//!                             dz/ds = |1 − z·sgn(ṡ)|ⁿ·sgn(1 − z·sgn(ṡ))/x_c over the hauled
//!                             length s (z ∈ [−1, 1]: rate-independent hysteresis, presliding
//!                             length x_c; eq. 8 with F = μ·F_n·z and σ₀ = μ·F_n/x_c)
//! T_PUL = T_EE + F_f
//! ```
//!
//! Hauled in, the sensor (upstream of the pulleys) reads more than the platform gets; paid out,
//! less. The normal force is taken from the platform-side tension (the difference is of the
//! friction's own order, a second-order term for μ·N ≪ 1). The speed is the central difference
//! of the cable lengths of the poses (one-sided at the ends); the Dahl state starts relaxed
//! (`z = 0`) and is integrated per sample over the hauled length by RK4 (steps of at most
//! `x_c/20`, at most 1,024 per sample).

use super::batch::at_row;
use super::kinematics::{inverse_kinematics, CableGeometry, Pose};
use super::robot::Robot;
use super::tension::project;
use crate::error::{check, CableError, Result};
use crate::friction::smooth_sign;

/// The friction law of a path.
#[derive(Debug, Clone, Copy, PartialEq)]
pub enum PathLaw {
    /// Eq. 7: Coulomb (sign smoothed over `smoothing` m/s) and viscous.
    Coulomb {
        /// Smoothing speed `ε` of the sign (m/s), > 0.
        smoothing: f64,
    },
    /// Eq. 8: a Dahl state over the hauled length, and viscous.
    Dahl {
        /// Presliding length `x_c` (m), > 0.
        presliding: f64,
        /// Shape exponent `n`, > 0.
        exponent: f64,
    },
}

/// Friction between the sensor and the platform of one cable.
#[derive(Debug, Clone, Copy, PartialEq)]
pub struct PathFriction {
    /// Friction coefficient `μ` of the pulleys, ≥ 0.
    pub coefficient: f64,
    /// Viscous coefficient `σ_v` (N·s/m), ≥ 0.
    pub viscous: f64,
    /// Wrap angle of the guide pulleys between the sensor and the exit `θ_g` (rad), in [0, 2π].
    pub guide_wrap: f64,
    /// The law.
    pub law: PathLaw,
}

impl PathLaw {
    /// The law named `"dahl"` (the default) or `"coulomb"`, with its parameters where given and
    /// otherwise the defaults: smoothing 1 mm/s, presliding length 1 mm, exponent 1.
    pub fn named(
        name: Option<&str>,
        smoothing: Option<f64>,
        presliding: Option<f64>,
        exponent: Option<f64>,
    ) -> Result<Self> {
        match name.unwrap_or("dahl") {
            "coulomb" => Ok(Self::Coulomb {
                smoothing: smoothing.unwrap_or(1e-3),
            }),
            "dahl" => Ok(Self::Dahl {
                presliding: presliding.unwrap_or(1e-3),
                exponent: exponent.unwrap_or(1.0),
            }),
            other => Err(CableError::InvalidOption {
                name: "law".into(),
                value: other.into(),
                allowed: "coulomb, dahl".into(),
            }),
        }
    }
}

impl PathFriction {
    /// One path per cable from per-cable (or shared, length 1) coefficients, viscous
    /// coefficients and guide wraps, all with `law`; validated.
    pub fn per_cable(
        coefficient: &[f64],
        viscous: &[f64],
        guide_wrap: &[f64],
        law: PathLaw,
        m: usize,
    ) -> Result<Vec<Self>> {
        let pick = |what: &str, v: &[f64], i: usize| shared_or_own(what, v, i, m);
        (0..m)
            .map(|i| {
                let p = Self {
                    coefficient: pick("coefficient", coefficient, i)?,
                    viscous: pick("viscous", viscous, i)?,
                    guide_wrap: pick("guide_wrap", guide_wrap, i)?,
                    law,
                };
                p.validate().map(|()| p)
            })
            .collect()
    }

    /// Every parameter finite and in range.
    pub fn validate(&self) -> Result<()> {
        check::non_negative("coefficient", self.coefficient)?;
        check::non_negative("viscous", self.viscous)?;
        check::non_negative("guide_wrap", self.guide_wrap)?;
        if self.guide_wrap > std::f64::consts::TAU {
            return Err(CableError::InvalidParameter {
                name: "guide_wrap".into(),
                value: self.guide_wrap,
                requirement: "at most 2 pi rad",
            });
        }
        match self.law {
            PathLaw::Coulomb { smoothing } => {
                check::positive("smoothing", smoothing)?;
            }
            PathLaw::Dahl {
                presliding,
                exponent,
            } => {
                check::positive("presliding", presliding)?;
                check::positive("exponent", exponent)?;
            }
        }
        Ok(())
    }

    /// Normal force per newton of tension `N(θ)` with the exit pulley's wrap `exit_wrap`.
    pub fn normal_factor(&self, exit_wrap: f64) -> f64 {
        2.0 * (0.5 * self.guide_wrap).sin() + 2.0 * (0.5 * exit_wrap).sin()
    }
}

/// `dz/ds` of the normalised Dahl state.
pub(crate) fn dahl_slope(z: f64, dir: f64, presliding: f64, exponent: f64) -> f64 {
    let s = 1.0 - z * dir;
    s.abs().powf(exponent) * s.signum() / presliding
}

/// The Dahl state after hauling `ds` metres from `z`: RK4 in steps of at most a twentieth of
/// the presliding length, at most 1,024 of them (51 presliding lengths, where the state has
/// long settled; a longer haul in one sample integrates only its first 51 lengths).
fn dahl_advance(z: f64, ds: f64, presliding: f64, exponent: f64) -> f64 {
    if ds == 0.0 {
        return z;
    }
    let dir = ds.signum();
    let covered = ds.abs().min(1024.0 * 0.05 * presliding);
    let steps = ((covered / (0.05 * presliding)).ceil() as usize).clamp(1, 1024);
    let h = covered / steps as f64;
    let f = |z: f64| dir * dahl_slope(z, dir, presliding, exponent);
    let mut z = z;
    for _ in 0..steps {
        let k1 = f(z);
        let k2 = f(z + 0.5 * h * k1);
        let k3 = f(z + 0.5 * h * k2);
        let k4 = f(z + h * k3);
        z += h / 6.0 * (k1 + 2.0 * k2 + 2.0 * k3 + k4);
    }
    z.clamp(-1.0, 1.0)
}

/// The number of poses `T` of `poses` `(T, n)`, with `tensions` `(T, m)` finite.
fn rows_of(robot: &Robot, poses: &[f64], what: &str, tensions: &[f64]) -> Result<usize> {
    let (n, m) = (robot.dof(), robot.n_cables());
    if !poses.len().is_multiple_of(n) {
        return Err(CableError::Shape {
            what: "poses".into(),
            expected: format!("(T, {n})"),
            got: format!("{} values", poses.len()),
        });
    }
    let t = poses.len() / n;
    check::len(what, tensions, t * m)?;
    check::all_finite(what, tensions, tensions.len())?;
    Ok(t)
}

/// A path-friction run: per sample and cable (row-major `T × m`) the sensor's tension `pul`,
/// the friction `friction = pul − ee`, the cable speed towards the winch `speed` (m/s) and the
/// exit pulley's wrap `wrap` (rad).
#[derive(Debug, Clone, PartialEq)]
pub struct PathRun {
    /// Winch-side (sensor) tensions (N).
    pub pul: Vec<f64>,
    /// `pul − ee` (N).
    pub friction: Vec<f64>,
    /// Cable speed towards the winch (m/s).
    pub speed: Vec<f64>,
    /// Exit pulley wrap (rad).
    pub wrap: Vec<f64>,
}

/// The winch-side tensions along a trajectory: `poses` `(T, n)` sampled every `dt` s, the
/// platform-side tensions `ee` `(T, m)`, and the friction of each cable's path (`paths`: one
/// per cable, or one for all).
pub fn path_friction(
    robot: &Robot,
    poses: &[f64],
    ee: &[f64],
    dt: f64,
    paths: &[PathFriction],
) -> Result<PathRun> {
    let (n, m) = (robot.dof(), robot.n_cables());
    check::positive("dt", dt)?;
    let t = rows_of(robot, poses, "ee tensions", ee)?;
    if paths.len() != 1 && paths.len() != m {
        return Err(CableError::Shape {
            what: "path frictions".into(),
            expected: format!("1 or {m}"),
            got: format!("{}", paths.len()),
        });
    }
    for p in paths {
        p.validate()?;
    }
    let path = |i: usize| &paths[if paths.len() == 1 { 0 } else { i }];
    // lengths and exit wraps of every pose
    let (mut length, mut wrap) = (vec![0.0; t * m], vec![0.0; t * m]);
    let mut geo = CableGeometry::default();
    for k in 0..t {
        let pose = Pose::from_coordinates(robot.motion, &poses[k * n..(k + 1) * n])
            .map_err(|e| at_row(e, k))?;
        inverse_kinematics(robot, &pose, &mut geo).map_err(|e| at_row(e, k))?;
        length[k * m..(k + 1) * m].copy_from_slice(&geo.length[..m]);
        wrap[k * m..(k + 1) * m].copy_from_slice(&geo.wrap[..m]);
    }
    let mut speed = vec![0.0; t * m];
    for k in 0..t {
        let (a, b) = (k.saturating_sub(1), (k + 1).min(t - 1));
        if b > a {
            for i in 0..m {
                speed[k * m + i] = -(length[b * m + i] - length[a * m + i]) / ((b - a) as f64 * dt);
            }
        }
    }
    let (mut pul, mut friction) = (vec![0.0; t * m], vec![0.0; t * m]);
    let mut z = vec![0.0; m];
    for k in 0..t {
        for i in 0..m {
            let j = k * m + i;
            let p = path(i);
            let normal = ee[j] * p.normal_factor(wrap[j]);
            let state = match p.law {
                PathLaw::Coulomb { smoothing } => smooth_sign(speed[j], smoothing),
                PathLaw::Dahl {
                    presliding,
                    exponent,
                } => {
                    if k > 0 {
                        let hauled = -(length[j] - length[j - m]);
                        z[i] = dahl_advance(z[i], hauled, presliding, exponent);
                    }
                    z[i]
                }
            };
            friction[j] = p.coefficient * normal * state + p.viscous * speed[j];
            pul[j] = ee[j] + friction[j];
        }
    }
    check::all_finite("winch-side tensions", &pul, pul.len()).map_err(|_| {
        CableError::NonFiniteResult {
            what: "winch-side tensions".into(),
            index: pul.iter().position(|v| !v.is_finite()).unwrap_or(0),
            value: f64::INFINITY,
            location: String::new(),
            hint: "the tensions or the friction coefficients overflow",
        }
    })?;
    Ok(PathRun {
        pul,
        friction,
        speed,
        wrap,
    })
}

/// Measured tensions `(T, m)` moved to the nearest (least-squares) tensions that hold the
/// platform at the poses `(T, n)`: `f = f_meas − A⁺ᵀ·(w + Aᵀ·f_meas)` (seed 002 eq. 10 with the
/// measurement as `f_ref`), with `w` the external `wrenches` `(T, n)` (if any) plus the weight
/// (if `gravity`). What statics alone can take out of a friction-biased measurement: the part
/// of the error that unbalances the platform; the part in the null space of `Aᵀ` (internal
/// forces) stays.
pub fn equilibrium_projection(
    robot: &Robot,
    poses: &[f64],
    measured: &[f64],
    wrenches: Option<&[f64]>,
    gravity: bool,
) -> Result<Vec<f64>> {
    let (n, m) = (robot.dof(), robot.n_cables());
    let t = rows_of(robot, poses, "measured tensions", measured)?;
    if let Some(w) = wrenches {
        check::len("wrenches", w, t * n)?;
        check::all_finite("wrenches", w, w.len())?;
    }
    let mut geo = CableGeometry::default();
    let mut out = vec![0.0; t * m];
    for k in 0..t {
        let pose = Pose::from_coordinates(robot.motion, &poses[k * n..(k + 1) * n])
            .map_err(|e| at_row(e, k))?;
        inverse_kinematics(robot, &pose, &mut geo).map_err(|e| at_row(e, k))?;
        let mut w = [0.0; 6];
        if gravity {
            robot.gravity_wrench(&pose.rotation, &mut w);
        }
        if let Some(ext) = wrenches {
            for (a, e) in w[..n].iter_mut().zip(&ext[k * n..(k + 1) * n]) {
                *a += e;
            }
        }
        let f_meas = &measured[k * m..(k + 1) * m];
        project(
            geo.structure(),
            n,
            m,
            &w[..n],
            f_meas,
            &mut out[k * m..(k + 1) * m],
        )
        .map_err(|e| at_row(e, k))?;
    }
    check::all_finite("projected tensions", &out, out.len()).map_err(|_| {
        CableError::NonFiniteResult {
            what: "projected tensions".into(),
            index: out.iter().position(|v| !v.is_finite()).unwrap_or(0),
            value: f64::INFINITY,
            location: String::new(),
            hint: "the tensions or the wrenches overflow",
        }
    })?;
    Ok(out)
}

/// Cable `i`'s value of a column given shared `(1,)` or per cable `(m,)`.
pub(crate) fn shared_or_own(what: &str, v: &[f64], i: usize, m: usize) -> Result<f64> {
    match v.len() {
        1 => Ok(v[0]),
        len if len == m => Ok(v[i]),
        len => Err(CableError::Shape {
            what: what.into(),
            expected: format!("1 or {m} values"),
            got: format!("{len}"),
        }),
    }
}

#[cfg(test)]
mod tests {
    use super::*;

    #[test]
    fn dahl_state_relaxes_over_the_presliding_length_and_keeps_its_range() {
        // n = 1: z(s) = 1 − e^(−s/x_c) from rest
        for s in [1e-4, 1e-3, 5e-3, 0.1] {
            let z = dahl_advance(0.0, s, 1e-3, 1.0);
            assert!((z - (1.0 - (-s / 1e-3_f64).exp())).abs() < 1e-6, "{s}: {z}");
            assert!((dahl_advance(0.0, -s, 1e-3, 1.0) + z).abs() < 1e-15);
        }
        // reversal from saturation: −1 + 2·e^(−s/x_c)... from z = 1 hauling back by s
        let z = dahl_advance(1.0, -2e-3, 1e-3, 1.0);
        assert!((z - (-1.0 + 2.0 * (-2.0_f64).exp())).abs() < 1e-6, "{z}");
        assert!(dahl_advance(0.3, 1e9, 1e-9, 2.5).abs() <= 1.0);
    }
}
