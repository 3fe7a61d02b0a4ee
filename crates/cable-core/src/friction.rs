//! Friction models for motors, joints and cable–pulley contacts.
//!
//! All memoryless models are functions of a velocity `v` (rad/s or m/s) returning a force or
//! torque (N or N·m) that **opposes** the motion, i.e. it has the sign of `v` and is subtracted in
//! the equations of motion.
//!
//! * Smoothed sign (used wherever `sgn v` appears):
//!   `σ_ε(v) = v / sqrt(v² + ε²)`, with smoothing velocity `ε > 0`. It equals `sgn v` to within
//!   `ε²/(2v²)` for `|v| ≫ ε` and is linear (slope `1/ε`) near zero, which keeps the
//!   equations Lipschitz so RK4 converges. A small `ε` makes the model stiff: the Coulomb slope
//!   `F_c/ε` divided by the inertia is an eigenvalue the step must resolve
//!   (see [`crate::integrate::propose_step`]). Stiction (sticking at rest) is not represented.
//! * Coulomb: `F = F_c · σ_ε(v)`.
//! * Viscous: `F = b · v`.
//! * Stribeck: `F = (F_c + (F_s − F_c)·exp(−|v/v_s|^δ)) · σ_ε(v) + b·v`.
//! * Dahl (stateful, eq. (8) of seed 002):
//!   `dF/dx = σ₀ · |1 − (F/F_c)·sgn ẋ|^n · sgn(1 − (F/F_c)·sgn ẋ)`, so in time
//!   `dF/dt = σ₀ · |1 − (F/F_c)·sgn v|^n · sgn(1 − (F/F_c)·sgn v) · v`.
//! * Capstan (Euler–Eytelwein) for a cable wrapped by angle `φ` over a pulley with friction
//!   coefficient `μ`: `T_out = T_in · exp(−μ·φ·sgn v)`, where `v > 0` means the *in* end is hauling
//!   the cable in (the cable slides towards the in end). At steady sliding the hauling side
//!   carries `exp(μφ)` times the tension of the other side.

use crate::error::{check, Result};
use crate::lanes::{madd, Lanes, LANES};

/// Smoothed sign `v / sqrt(v² + ε²)`; see the module docs. `eps` > 0 (m/s or rad/s).
#[inline]
pub fn smooth_sign(v: f64, eps: f64) -> f64 {
    v / (v * v + eps * eps).sqrt()
}

/// Coulomb friction `F_c · σ_ε(v)` (N or N·m).
#[inline]
pub fn coulomb(v: f64, coulomb_level: f64, eps: f64) -> f64 {
    coulomb_level * smooth_sign(v, eps)
}

/// Viscous friction `b · v` (N or N·m).
#[inline]
pub fn viscous(v: f64, coefficient: f64) -> f64 {
    coefficient * v
}

/// Stribeck curve without the viscous part:
/// `(F_c + (F_s − F_c)·exp(−|v/v_s|^δ)) · σ_ε(v)`.
#[inline]
pub fn stribeck(
    v: f64,
    coulomb_level: f64,
    static_level: f64,
    v_s: f64,
    delta: f64,
    eps: f64,
) -> f64 {
    let decay = (-(v / v_s).abs().powf(delta)).exp();
    (coulomb_level + (static_level - coulomb_level) * decay) * smooth_sign(v, eps)
}

/// Capstan tension ratio `T_out / T_in = exp(−μ·φ·σ_ε(v))` (dimensionless).
///
/// `mu` friction coefficient, `wrap_rad` wrap angle φ (rad), `v` cable velocity towards the in end
/// (m/s), `eps` smoothing velocity (m/s). With `eps → 0` this is the Euler–Eytelwein law with
/// `sgn v`.
#[inline]
pub fn capstan_ratio(mu: f64, wrap_rad: f64, v: f64, eps: f64) -> f64 {
    (-mu * wrap_rad * smooth_sign(v, eps)).exp()
}

/// Combined memoryless friction: Stribeck + Coulomb + viscous with a smoothed sign.
///
/// `force(v) = (F_c + (F_s − F_c)·exp(−|v/v_s|^δ))·σ_ε(v) + b·v`. With `F_s == F_c` (the default
/// built by [`StaticFriction::coulomb_viscous`]) the exponential is skipped and the model is
/// Coulomb + viscous.
#[derive(Debug, Clone, Copy, PartialEq)]
pub struct StaticFriction {
    /// Coulomb level `F_c` (N or N·m), ≥ 0.
    pub coulomb: f64,
    /// Static (breakaway) level `F_s` (N or N·m), ≥ 0.
    pub static_level: f64,
    /// Stribeck velocity `v_s` (m/s or rad/s), > 0.
    pub stribeck_velocity: f64,
    /// Stribeck exponent `δ`, > 0 (2 is the Gaussian shape).
    pub stribeck_exponent: f64,
    /// Viscous coefficient `b` (N·s/m or N·m·s/rad), ≥ 0.
    pub viscous: f64,
    /// Smoothing velocity `ε` of the sign (m/s or rad/s), > 0.
    pub smoothing: f64,
}

impl StaticFriction {
    /// No friction at all (smoothing 1, irrelevant).
    pub const NONE: StaticFriction = StaticFriction {
        coulomb: 0.0,
        static_level: 0.0,
        stribeck_velocity: 1.0,
        stribeck_exponent: 2.0,
        viscous: 0.0,
        smoothing: 1.0,
    };

    /// Coulomb + viscous friction, validated. `name` prefixes error messages.
    pub fn coulomb_viscous(name: &str, coulomb: f64, viscous: f64, smoothing: f64) -> Result<Self> {
        Self::stribeck(name, coulomb, coulomb, 1.0, 2.0, viscous, smoothing)
    }

    /// Full Stribeck + viscous friction, validated.
    pub fn stribeck(
        name: &str,
        coulomb: f64,
        static_level: f64,
        stribeck_velocity: f64,
        stribeck_exponent: f64,
        viscous: f64,
        smoothing: f64,
    ) -> Result<Self> {
        let f = Self {
            coulomb,
            static_level,
            stribeck_velocity,
            stribeck_exponent,
            viscous,
            smoothing,
        };
        f.validate(name)?;
        Ok(f)
    }

    /// Check every field's range; `name` prefixes error messages.
    pub fn validate(&self, name: &str) -> Result<()> {
        check::non_negative(&format!("{name}.coulomb"), self.coulomb)?;
        check::non_negative(&format!("{name}.static_level"), self.static_level)?;
        check::positive(&format!("{name}.stribeck_velocity"), self.stribeck_velocity)?;
        check::positive(&format!("{name}.stribeck_exponent"), self.stribeck_exponent)?;
        check::non_negative(&format!("{name}.viscous"), self.viscous)?;
        check::positive(&format!("{name}.smoothing"), self.smoothing)?;
        Ok(())
    }

    /// Friction force/torque opposing velocity `v`.
    #[inline]
    pub fn force(&self, v: f64) -> f64 {
        let dry = if self.is_coulomb_viscous() {
            coulomb(v, self.coulomb, self.smoothing)
        } else {
            stribeck(
                v,
                self.coulomb,
                self.static_level,
                self.stribeck_velocity,
                self.stribeck_exponent,
                self.smoothing,
            )
        };
        dry + viscous(v, self.viscous)
    }

    /// No Stribeck bump: the static level equals the Coulomb level, so the exponential is
    /// skipped (exact equality is intended: the two are equal only when built that way).
    #[allow(clippy::float_cmp)]
    fn is_coulomb_viscous(&self) -> bool {
        self.static_level == self.coulomb
    }

    /// The parameters broadcast to SIMD lanes, for [`FrictionLanes::force`].
    pub fn lanes(&self) -> FrictionLanes {
        FrictionLanes {
            plain: self.is_coulomb_viscous(),
            coulomb: [self.coulomb; LANES],
            eps2: [self.smoothing * self.smoothing; LANES],
            viscous: [self.viscous; LANES],
            scalar: *self,
        }
    }

    /// Largest slope `|dF/dv|` (at `v = 0`), used to bound the stiffness this friction adds.
    pub fn max_slope(&self) -> f64 {
        self.coulomb.max(self.static_level) / self.smoothing + self.viscous
    }
}

/// [`StaticFriction`] with its parameters broadcast to [`LANES`] lanes once (at model
/// construction), so that a vectorised derivative reads them as vector operands instead of
/// broadcasting scalars on every call.
#[derive(Debug, Clone, Copy, PartialEq)]
pub struct FrictionLanes {
    plain: bool,
    coulomb: Lanes,
    eps2: Lanes,
    viscous: Lanes,
    scalar: StaticFriction,
}

impl FrictionLanes {
    /// [`StaticFriction::force`] of `W` velocities (a multiple of [`LANES`]): the same
    /// operations, in SIMD lanes for the Coulomb + viscous form, lane by lane for the Stribeck
    /// form. Products and sums are fused when `FUSED` (one rounding each; the last bits
    /// differ).
    #[inline(always)]
    pub fn force<const FUSED: bool, const W: usize>(&self, v: &[f64; W]) -> [f64; W] {
        if !self.plain {
            return self.force_stribeck(v);
        }
        let (c, e2, b) = (&self.coulomb, &self.eps2, &self.viscous);
        std::array::from_fn(|l| {
            let k = l % LANES;
            let dry = c[k] * (v[l] / madd::<FUSED>(v[l], v[l], e2[k]).sqrt());
            madd::<FUSED>(b[k], v[l], dry)
        })
    }

    /// The Stribeck form lane by lane, out of line (it would bloat the vectorised callers).
    #[inline(never)]
    fn force_stribeck<const W: usize>(&self, v: &[f64; W]) -> [f64; W] {
        v.map(|v| self.scalar.force(v))
    }
}

/// Dahl friction, eq. (8) of seed 002: a first-order hysteretic model with state `F`.
#[derive(Debug, Clone, Copy, PartialEq)]
pub struct Dahl {
    /// Rest stiffness `σ₀` (N/m or N·m/rad), > 0.
    pub sigma0: f64,
    /// Coulomb level `F_c` (N or N·m), > 0.
    pub coulomb: f64,
    /// Shape exponent `n`, > 0 (1 is the classic Dahl model).
    pub exponent: f64,
}

impl Dahl {
    /// Validated constructor.
    pub fn new(sigma0: f64, coulomb: f64, exponent: f64) -> Result<Self> {
        Ok(Self {
            sigma0: check::positive("dahl.sigma0", sigma0)?,
            coulomb: check::positive("dahl.coulomb", coulomb)?,
            exponent: check::positive("dahl.exponent", exponent)?,
        })
    }

    /// `dF/dt` at friction state `f` and velocity `v`. The sign of `v` is exact here: the rate is
    /// multiplied by `v`, so it is continuous at `v = 0`.
    #[inline]
    pub fn rate(&self, f: f64, v: f64) -> f64 {
        let s = 1.0 - f / self.coulomb * sign(v);
        self.sigma0 * s.abs().powf(self.exponent) * sign(s) * v
    }
}

/// Exact sign with `sgn 0 = 0`.
#[inline]
pub fn sign(x: f64) -> f64 {
    if x > 0.0 {
        1.0
    } else if x < 0.0 {
        -1.0
    } else {
        0.0
    }
}

#[cfg(test)]
#[allow(clippy::float_cmp)] // exact zeros are the claims under test (slack, no contact)
mod tests {
    use super::*;
    use approx::assert_relative_eq;

    #[test]
    fn smooth_sign_is_odd_bounded_and_converges() {
        for &v in &[1e-6, 1e-3, 0.1, 1.0, 10.0] {
            let s = smooth_sign(v, 1e-3);
            assert_relative_eq!(s, -smooth_sign(-v, 1e-3));
            assert!(s.abs() < 1.0);
        }
        assert!((1.0 - smooth_sign(1.0, 1e-3)).abs() < 1e-6);
        assert_eq!(smooth_sign(0.0, 1e-3), 0.0);
    }

    #[test]
    fn stribeck_peaks_above_coulomb_at_low_speed() {
        let f = StaticFriction::stribeck("f", 1.0, 1.5, 0.01, 2.0, 0.0, 1e-6).unwrap();
        assert!(f.force(0.001) > 1.4);
        assert_relative_eq!(f.force(1.0), 1.0, epsilon = 1e-9);
    }

    #[test]
    fn dahl_saturates_at_coulomb_level() {
        let d = Dahl::new(1e4, 2.0, 1.0).unwrap();
        let (mut f, dt, v) = (0.0, 1e-5, 0.1);
        for _ in 0..200_000 {
            f += dt * d.rate(f, v);
        }
        assert_relative_eq!(f, 2.0, epsilon = 1e-6);
        // reversal: the rate has the sign of the new velocity and twice the rest stiffness
        assert_relative_eq!(d.rate(f, -v), -2.0 * 1e4 * v, epsilon = 1e-3);
    }

    #[test]
    fn capstan_ratio_matches_euler_eytelwein() {
        assert_relative_eq!(
            capstan_ratio(0.1, 3.0, 1.0, 1e-9),
            (-0.3f64).exp(),
            epsilon = 1e-12
        );
        assert_relative_eq!(
            capstan_ratio(0.1, 3.0, -1.0, 1e-9),
            (0.3f64).exp(),
            epsilon = 1e-12
        );
    }

    #[test]
    fn invalid_parameters_are_rejected() {
        assert!(StaticFriction::coulomb_viscous("m", -1.0, 0.0, 1.0).is_err());
        assert!(StaticFriction::coulomb_viscous("m", 1.0, f64::NAN, 1.0).is_err());
        assert!(StaticFriction::coulomb_viscous("m", 1.0, 0.0, 0.0).is_err());
        assert!(Dahl::new(0.0, 1.0, 1.0).is_err());
    }
}
