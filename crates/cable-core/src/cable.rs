//! Cable models: elastic laws, damping, pretension and slack.
//!
//! A **cable run** is one straight stretch of cable between two anchors (capstan and joint
//! pulley). Its tension as a function of its stretch `s` (m, positive = longer than at
//! pretension) and stretch rate `ṡ` (m/s) is
//!
//! ```text
//! T(s, ṡ) = max(0, T₀ + F(s) + c·ṡ)
//! ```
//!
//! * `T₀` pretension (N), `c` cable damping (N·s/m);
//! * `F` the elastic law:
//!   - linear: `F(s) = k·s`, with `k = E·A/L` ([`CableLaw::linear_from_material`]);
//!   - exponential (seed 001 eqs 2.5–2.6): `F(s) = k_e·ℓ·(exp(s/ℓ) − 1)` with length scale `ℓ`
//!     (1 m in the seed, whose law is written with the stretch in metres). Its small-stretch
//!     stiffness is `k_e`, and it stiffens as the cable is stretched.
//! * `max(0, ·)` is **slack**: a cable cannot push.
//!
//! A **cable loop** (antagonistic pair, as in every Raven-II and EndoWrist axis) is two runs that
//! see opposite stretches `+Δ` and `−Δ`. While both are taut the net tension is
//!
//! ```text
//! γ = T_a − T_b = F(Δ) − F(−Δ) + 2c·Δ̇
//! ```
//!
//! which for the exponential law with `ℓ = 1 m` is exactly eq. (2.6) of seed 001,
//! `γ = k_e(e^Δ − e^−Δ) + 2b_e·Δ̇`; with slack, the net tension saturates at the taut side's
//! tension. `expm1` is used so small stretches keep full relative precision.

use crate::error::{check, CableError, Result};
use crate::lanes::{madd, Lanes, LANES};

/// Elastic tension–stretch law `F(s)` of one cable run.
#[derive(Debug, Clone, Copy, PartialEq)]
pub enum CableLaw {
    /// `F(s) = k·s`, `k` in N/m.
    Linear {
        /// Axial stiffness `k = E·A/L` (N/m).
        stiffness: f64,
    },
    /// `F(s) = k_e·ℓ·(exp(s/ℓ) − 1)` (seed 001 eq. 2.6 per side).
    Exponential {
        /// Small-stretch stiffness `k_e` (N/m).
        stiffness: f64,
        /// Length scale `ℓ` (m); 1 m reproduces the seed.
        length_scale: f64,
    },
}

impl CableLaw {
    /// Linear law from material data: Young's modulus `E` (Pa), cross-section `A` (m²) and free
    /// length `L` (m): `k = E·A/L`.
    pub fn linear_from_material(youngs_modulus: f64, area: f64, length: f64) -> Result<Self> {
        let e = check::positive("cable.youngs_modulus", youngs_modulus)?;
        let a = check::positive("cable.area", area)?;
        let l = check::positive("cable.length", length)?;
        Ok(CableLaw::Linear {
            stiffness: e * a / l,
        })
    }

    /// Build a law from its name (`"linear"` or `"exponential"`), validating the numbers.
    pub fn from_name(name: &str, stiffness: f64, length_scale: f64, prefix: &str) -> Result<Self> {
        let k = check::positive(&format!("{prefix}.cable_stiffness"), stiffness)?;
        match name {
            "linear" => Ok(CableLaw::Linear { stiffness: k }),
            "exponential" => Ok(CableLaw::Exponential {
                stiffness: k,
                length_scale: check::positive(&format!("{prefix}.length_scale"), length_scale)?,
            }),
            other => Err(CableError::InvalidOption {
                name: format!("{prefix}.cable_law"),
                value: other.to_owned(),
                allowed: "\"linear\", \"exponential\"".to_owned(),
            }),
        }
    }

    /// Name of the law (`"linear"` / `"exponential"`).
    pub fn name(&self) -> &'static str {
        match self {
            CableLaw::Linear { .. } => "linear",
            CableLaw::Exponential { .. } => "exponential",
        }
    }

    /// Small-stretch stiffness `dF/ds` at `s = 0` (N/m).
    pub fn stiffness(&self) -> f64 {
        match *self {
            CableLaw::Linear { stiffness } | CableLaw::Exponential { stiffness, .. } => stiffness,
        }
    }

    /// The same law with its stiffness multiplied by `factor` (> 0).
    pub fn scaled(&self, factor: f64) -> Self {
        match *self {
            CableLaw::Linear { stiffness } => CableLaw::Linear {
                stiffness: stiffness * factor,
            },
            CableLaw::Exponential {
                stiffness,
                length_scale,
            } => CableLaw::Exponential {
                stiffness: stiffness * factor,
                length_scale,
            },
        }
    }

    /// Elastic force `F(s)` (N) at stretch `s` (m).
    #[inline]
    pub fn elastic(&self, s: f64) -> f64 {
        match *self {
            CableLaw::Linear { stiffness } => stiffness * s,
            CableLaw::Exponential {
                stiffness,
                length_scale,
            } => stiffness * length_scale * (s / length_scale).exp_m1(),
        }
    }

    /// Stiffness `dF/ds` at stretch `s` (N/m).
    #[inline]
    pub fn slope(&self, s: f64) -> f64 {
        match *self {
            CableLaw::Linear { stiffness } => stiffness,
            CableLaw::Exponential {
                stiffness,
                length_scale,
            } => stiffness * (s / length_scale).exp(),
        }
    }

    /// Elastic energy `∫₀ˢ F(σ) dσ` (J).
    pub fn energy(&self, s: f64) -> f64 {
        match *self {
            CableLaw::Linear { stiffness } => 0.5 * stiffness * s * s,
            CableLaw::Exponential {
                stiffness,
                length_scale,
            } => stiffness * length_scale * (length_scale * (s / length_scale).exp_m1() - s),
        }
    }
}

/// One cable run: elastic law, damping, pretension, slack.
#[derive(Debug, Clone, Copy, PartialEq)]
pub struct CableRun {
    /// Elastic law.
    pub law: CableLaw,
    /// Damping `c` (N·s/m), ≥ 0.
    pub damping: f64,
    /// Pretension `T₀` (N), ≥ 0.
    pub pretension: f64,
}

impl CableRun {
    /// Validated constructor; `prefix` names the run in error messages.
    pub fn new(law: CableLaw, damping: f64, pretension: f64, prefix: &str) -> Result<Self> {
        let run = Self {
            law,
            damping,
            pretension,
        };
        run.validate(prefix)?;
        Ok(run)
    }

    /// Check every field's range; `prefix` names the run in error messages.
    pub fn validate(&self, prefix: &str) -> Result<()> {
        check::positive(&format!("{prefix}.cable_stiffness"), self.law.stiffness())?;
        if let CableLaw::Exponential { length_scale, .. } = self.law {
            check::positive(&format!("{prefix}.length_scale"), length_scale)?;
        }
        check::non_negative(&format!("{prefix}.cable_damping"), self.damping)?;
        check::non_negative(&format!("{prefix}.pretension"), self.pretension)?;
        Ok(())
    }

    /// Tension `max(0, T₀ + F(s) + c·ṡ)` (N).
    #[inline]
    pub fn tension(&self, stretch: f64, stretch_rate: f64) -> f64 {
        (self.pretension + self.law.elastic(stretch) + self.damping * stretch_rate).max(0.0)
    }

    /// Tension with a creep relaxation state `w` (N): `max(0, T₀ + F(s) + c·ṡ − w)`; see
    /// [`Creep`].
    #[inline]
    pub fn relaxed_tension(&self, stretch: f64, stretch_rate: f64, relaxation: f64) -> f64 {
        (self.pretension + self.law.elastic(stretch) + self.damping * stretch_rate - relaxation)
            .max(0.0)
    }

    /// Tangent stiffness at `s` while taut (N/m), for step-size advice.
    pub fn slope(&self, stretch: f64) -> f64 {
        self.law.slope(stretch)
    }
}

/// Cable creep / stress relaxation as a standard linear solid (Zener) in relaxation form.
///
/// A cable held at a constant stretch loses a fraction `κ` of its elastic tension with time
/// constant `τ`; each run carries one relaxation state `w` (N):
///
/// ```text
/// T = max(0, T₀ + F(s) + c·ṡ − w),     ẇ = (κ·F(s) − w) / τ
/// ```
///
/// At rest `w → κ·F(s)` (relaxed tension `T₀ + (1 − κ)·F(s)`); fast motion sees the full
/// `F(s)`. Polymer (Dyneema, Vectran) and long steel routes creep; steel ropes on short runs
/// barely do.
#[derive(Debug, Clone, Copy, PartialEq)]
pub struct Creep {
    /// Relaxed fraction `κ` of the elastic tension, in `[0, 1)`.
    pub fraction: f64,
    /// Relaxation time constant `τ` (s), > 0.
    pub time_constant: f64,
}

impl Creep {
    /// Validated constructor.
    pub fn new(fraction: f64, time_constant: f64) -> Result<Self> {
        let k = check::non_negative("creep.fraction", fraction)?;
        if k >= 1.0 {
            return Err(CableError::InvalidParameter {
                name: "creep.fraction".into(),
                value: k,
                requirement: "in [0, 1)",
            });
        }
        Ok(Self {
            fraction: k,
            time_constant: check::positive("creep.time_constant", time_constant)?,
        })
    }

    /// `dw/dt` (N/s) at relaxation state `w` (N) and elastic force `F(s)` (N).
    #[inline]
    pub fn rate(&self, w: f64, elastic: f64) -> f64 {
        (self.fraction * elastic - w) / self.time_constant
    }
}

/// Antagonistic loop of two identical runs with stretches `+Δ` (side a) and `−Δ` (side b).
#[derive(Debug, Clone, Copy, PartialEq)]
pub struct CableLoop {
    /// Parameters shared by both sides.
    pub run: CableRun,
}

/// `(exp(x) − 1, exp(−x) − 1)`, the two sides of a loop at once. For `|x| < 1e-2` from the
/// even and odd parts of the Taylor polynomial to `x⁸/8!` (the next term is below `x·3e-22`,
/// under the rounding of the result): `expm1(±x) = E(x) ± O(x)`, two short polynomials in
/// `x²` for both signs, no division. Otherwise `m = f64::exp_m1(x)` and
/// `expm1(−x) = −m/(1 + m)` exactly (the quotient keeps full relative precision). Cable
/// stretches over their length scale are mostly this small (Raven-II: 1e-5…2e-3), and the
/// polynomials are a fraction of the libm call and vectorise across SIMD lanes.
#[inline(always)]
pub fn expm1_pair(x: f64) -> (f64, f64) {
    if x.abs() < EXPM1_TAYLOR_BELOW {
        expm1_taylor_pair(x)
    } else {
        let m = x.exp_m1();
        (m, -m / (1.0 + m))
    }
}

/// Where [`expm1_pair`] switches from its polynomials to `f64::exp_m1`.
const EXPM1_TAYLOR_BELOW: f64 = 1e-2;

/// [`expm1_taylor_pair`] of `W` arguments, written lane-wise (each step one vector
/// operation over the lanes, in the order [`taylor_odd`] and [`taylor_even`] use). When
/// `FUSED`, each Horner step `y·(c + t)` becomes `y·q` with `q ← q·y + c` fused (one rounding
/// per step instead of two; the last bits differ).
#[inline(always)]
fn taylor_pair_lanes<const FUSED: bool, const W: usize>(x: &[f64; W]) -> ([f64; W], [f64; W]) {
    type V<const W: usize> = [f64; W];
    let y: V<W> = std::array::from_fn(|l| x[l] * x[l]);
    // y·(c₀ + y·(c₁ + … + y·c_last)), innermost first
    let horner = |c: &[f64]| -> V<W> {
        let (last, rest) = c.split_last().expect("coefficients");
        if FUSED {
            let mut q: V<W> = [*last; W];
            for k in rest.iter().rev() {
                q = std::array::from_fn(|l| madd::<true>(q[l], y[l], *k));
            }
            return std::array::from_fn(|l| y[l] * q[l]);
        }
        let mut t: V<W> = std::array::from_fn(|l| y[l] * last);
        for k in rest.iter().rev() {
            t = std::array::from_fn(|l| y[l] * (k + t[l]));
        }
        t
    };
    let odd_tail = horner(&ODD_TAIL);
    let even = horner(&EVEN);
    let odd: V<W> = if FUSED {
        std::array::from_fn(|l| madd::<true>(x[l], odd_tail[l], x[l]))
    } else {
        std::array::from_fn(|l| x[l] * (1.0 + odd_tail[l]))
    };
    (
        std::array::from_fn(|l| even[l] + odd[l]),
        std::array::from_fn(|l| even[l] - odd[l]),
    )
}

/// [`expm1_pair`] lane by lane, off the hot path (some `|x|` at or above the polynomials'
/// range).
#[cold]
#[inline(never)]
fn expm1_pair_lanes_cold<const W: usize>(x: &[f64; W]) -> ([f64; W], [f64; W]) {
    let m = x.map(expm1_pair);
    (m.map(|m| m.0), m.map(|m| m.1))
}

#[inline(always)]
fn expm1_taylor_pair(x: f64) -> (f64, f64) {
    let (odd, even) = (taylor_odd(x), taylor_even(x));
    (even + odd, even - odd)
}

/// `1/3!, 1/5!, 1/7!`: the odd part of the `exp` series is `x·(1 + y·(c₀ + y·(c₁ + y·c₂)))`
/// with `y = x²`.
const ODD_TAIL: [f64; 3] = [1.0 / 6.0, 1.0 / 120.0, 1.0 / 5040.0];

/// `1/2!, 1/4!, 1/6!, 1/8!`: the even part less one is `y·(c₀ + y·(c₁ + y·(c₂ + y·c₃)))`.
const EVEN: [f64; 4] = [1.0 / 2.0, 1.0 / 24.0, 1.0 / 720.0, 1.0 / 40320.0];

/// `y·(c₀ + y·(c₁ + … + y·c_last))`, innermost first (the order the lane version keeps).
#[inline(always)]
fn horner(y: f64, c: &[f64]) -> f64 {
    let (last, rest) = c.split_last().expect("coefficients");
    rest.iter().rev().fold(y * last, |t, k| y * (k + t))
}

/// Odd part of the `exp` series to `x⁷/7!`: `x + x³/3! + x⁵/5! + x⁷/7!`.
#[inline(always)]
fn taylor_odd(x: f64) -> f64 {
    x * (1.0 + horner(x * x, &ODD_TAIL))
}

/// Even part of the `exp` series to `x⁸/8!`, less one: `x²/2! + x⁴/4! + x⁶/6! + x⁸/8!`.
#[inline(always)]
fn taylor_even(x: f64) -> f64 {
    horner(x * x, &EVEN)
}

impl CableLoop {
    /// Side tensions `(T_a, T_b)` (N) at loop stretch `Δ` (m) and rate `Δ̇` (m/s).
    ///
    /// The exponential law evaluates both sides' `expm1(±Δ/ℓ)` together ([`expm1_pair`]):
    /// the exponentials were a third of an RK4 step of the Raven model.
    #[inline]
    pub fn tensions(&self, delta: f64, delta_rate: f64) -> (f64, f64) {
        let run = &self.run;
        let (fa, fb) = match run.law {
            CableLaw::Linear { stiffness } => (stiffness * delta, -(stiffness * delta)),
            CableLaw::Exponential {
                stiffness,
                length_scale,
            } => {
                let (ma, mb) = expm1_pair(delta / length_scale);
                let kl = stiffness * length_scale;
                (kl * ma, kl * mb)
            }
        };
        let c = run.damping * delta_rate;
        (
            (run.pretension + fa + c).max(0.0),
            (run.pretension + fb - c).max(0.0),
        )
    }

    /// The loop's parameters broadcast to SIMD lanes, for [`CableLanes::tensions`].
    pub fn lanes(&self) -> CableLanes {
        let run = &self.run;
        let law = match run.law {
            CableLaw::Linear { stiffness } => LawLanes::Linear {
                stiffness: [stiffness; LANES],
            },
            CableLaw::Exponential {
                stiffness,
                length_scale,
            } => LawLanes::Exponential {
                length_scale: [length_scale; LANES],
                kl: [stiffness * length_scale; LANES],
            },
        };
        CableLanes {
            law,
            damping: [run.damping; LANES],
            pretension: [run.pretension; LANES],
        }
    }

    /// Potential energy of both sides while taut, pretension work excluded (it cancels): J.
    pub fn energy(&self, delta: f64) -> f64 {
        self.run.law.energy(delta) + self.run.law.energy(-delta)
    }
}

/// A [`CableLoop`] with its parameters broadcast to [`LANES`] lanes once (at model
/// construction), so that a vectorised derivative reads them as vector operands.
#[derive(Debug, Clone, Copy, PartialEq)]
pub struct CableLanes {
    law: LawLanes,
    damping: Lanes,
    pretension: Lanes,
}

/// [`CableLaw`] in lanes; the exponential law keeps `k_e·ℓ` as one product, as
/// [`CableLoop::tensions`] forms it.
#[derive(Debug, Clone, Copy, PartialEq)]
enum LawLanes {
    Linear { stiffness: Lanes },
    Exponential { length_scale: Lanes, kl: Lanes },
}

impl CableLanes {
    /// [`CableLoop::tensions`] of `W` stretches at once (a multiple of [`LANES`]; same
    /// operations, so the same bits; the polynomial branch of [`expm1_pair`] runs in SIMD
    /// lanes when every lane takes it). With `FUSED` the products and sums are fused (the last
    /// bits differ).
    #[inline(always)]
    pub fn tensions<const FUSED: bool, const W: usize>(
        &self,
        delta: &[f64; W],
        delta_rate: &[f64; W],
    ) -> ([f64; W], [f64; W]) {
        type V<const W: usize> = [f64; W];
        let (b, t0) = (&self.damping, &self.pretension);
        let c: V<W> = std::array::from_fn(|l| b[l % LANES] * delta_rate[l]);
        // T₀ + F(±Δ) as one multiply-add when fused
        let (ta0, tb0): (V<W>, V<W>) = match &self.law {
            // unfused, `(−k)·Δ + T₀` is `T₀ + −(k·Δ)` to the bit (negation is exact)
            LawLanes::Linear { stiffness: k } => (
                std::array::from_fn(|l| madd::<FUSED>(k[l % LANES], delta[l], t0[l % LANES])),
                std::array::from_fn(|l| madd::<FUSED>(-k[l % LANES], delta[l], t0[l % LANES])),
            ),
            LawLanes::Exponential { length_scale, kl } => {
                let x: V<W> = std::array::from_fn(|l| delta[l] / length_scale[l % LANES]);
                let (ma, mb) = if x.iter().all(|x| x.abs() < EXPM1_TAYLOR_BELOW) {
                    taylor_pair_lanes::<FUSED, W>(&x)
                } else {
                    expm1_pair_lanes_cold(&x)
                };
                (
                    std::array::from_fn(|l| madd::<FUSED>(kl[l % LANES], ma[l], t0[l % LANES])),
                    std::array::from_fn(|l| madd::<FUSED>(kl[l % LANES], mb[l], t0[l % LANES])),
                )
            }
        };
        (
            std::array::from_fn(|l| (ta0[l] + c[l]).max(0.0)),
            std::array::from_fn(|l| (tb0[l] - c[l]).max(0.0)),
        )
    }
}

#[cfg(test)]
#[allow(clippy::float_cmp)] // exact zeros are the claims under test (slack, no contact)
mod tests {
    use super::*;
    use approx::assert_relative_eq;

    fn exp_loop() -> CableLoop {
        CableLoop {
            run: CableRun::new(
                CableLaw::Exponential {
                    stiffness: 720e3,
                    length_scale: 1.0,
                },
                4000.0,
                5e3,
                "l",
            )
            .unwrap(),
        }
    }

    #[test]
    fn small_argument_expm1_is_exact_to_rounding() {
        // across the switch at 1e-2 and down to subnormal-free tiny values, both signs
        let mut x = 1e-12;
        while x < 1e-1 {
            for v in [x, -x] {
                let (got, got_neg) = expm1_pair(v);
                for (got, want) in [(got, v.exp_m1()), (got_neg, (-v).exp_m1())] {
                    assert!(
                        (got - want).abs() <= 2.0 * f64::EPSILON * want.abs(),
                        "x = {v}: {got} vs {want}"
                    );
                }
            }
            x *= 1.37;
        }
        assert_eq!(expm1_pair(0.0), (0.0, 0.0));
    }

    #[test]
    fn taut_loop_reproduces_seed_eq_2_6() {
        let lp = exp_loop();
        for &(d, dd) in &[(1e-5, 0.0), (-3e-4, 0.01), (2e-3, -0.2)] {
            let (a, b) = lp.tensions(d, dd);
            let seed = 720e3 * (f64::exp(d) - f64::exp(-d)) + 2.0 * 4000.0 * dd;
            assert_relative_eq!(a - b, seed, max_relative = 1e-9);
        }
    }

    #[test]
    fn loop_tensions_equal_two_single_runs() {
        let lp = exp_loop();
        let lin = CableLoop {
            run: CableRun::new(CableLaw::Linear { stiffness: 3e4 }, 7.0, 12.0, "r").unwrap(),
        };
        for l in [lp, lin] {
            for &(d, dd) in &[
                (0.0, 0.0),
                (1e-9, 1e-3),
                (-2e-6, 0.4),
                (3e-3, -2.0),
                (-0.2, 0.0),
            ] {
                let (a, b) = l.tensions(d, dd);
                assert_relative_eq!(
                    a,
                    l.run.tension(d, dd),
                    max_relative = 1e-15,
                    epsilon = 1e-12
                );
                assert_relative_eq!(
                    b,
                    l.run.tension(-d, -dd),
                    max_relative = 1e-15,
                    epsilon = 1e-12
                );
            }
        }
    }

    #[test]
    fn slack_side_never_pushes() {
        let run = CableRun::new(CableLaw::Linear { stiffness: 1e4 }, 10.0, 5.0, "r").unwrap();
        assert_eq!(run.tension(-1e-3, 0.0), 0.0);
        assert_relative_eq!(run.tension(1e-3, 0.0), 15.0);
        assert_eq!(run.tension(-1.0, -10.0), 0.0);
    }

    #[test]
    fn material_constructor_is_ea_over_l() {
        let law = CableLaw::linear_from_material(200e9, 1e-7, 0.5).unwrap();
        assert_relative_eq!(law.stiffness(), 40e3);
        assert!(CableLaw::linear_from_material(-1.0, 1e-7, 0.5).is_err());
    }

    #[test]
    fn energy_is_integral_of_force() {
        let law = CableLaw::Exponential {
            stiffness: 1e3,
            length_scale: 0.01,
        };
        let (s, n) = (0.004, 100_000);
        let h = s / n as f64;
        let quad: f64 = (0..n).map(|i| law.elastic((i as f64 + 0.5) * h) * h).sum();
        assert_relative_eq!(law.energy(s), quad, max_relative = 1e-8);
    }
}
