//! Layer activations with MATLAB's names (the seeds trained their networks in MATLAB).

use crate::error::{CableError, Result, WeightsErrorKind};

/// A layer's transfer function.
#[derive(Debug, Clone, Copy, PartialEq, Eq)]
pub enum Activation {
    /// `logsig(n) = 1 / (1 + e⁻ⁿ)`, the logistic sigmoid (seed 002, eq. 9).
    Logsig,
    /// `tansig(n) = 2 / (1 + e⁻²ⁿ) − 1 = tanh(n)`, MATLAB's default hidden transfer function.
    Tansig,
    /// `purelin(n) = n`, the linear output layer.
    Purelin,
}

impl Activation {
    /// All activations, in the order of their names.
    pub const ALL: [Activation; 3] = [Self::Logsig, Self::Tansig, Self::Purelin];

    /// The name used in weight files and in the Python API.
    pub fn name(self) -> &'static str {
        match self {
            Self::Logsig => "logsig",
            Self::Tansig => "tansig",
            Self::Purelin => "purelin",
        }
    }

    /// Parse a name from a weight file; unknown names are a metadata error naming `item`.
    pub fn parse(name: &str, item: &str) -> Result<Self> {
        Self::ALL
            .into_iter()
            .find(|a| a.name() == name)
            .ok_or_else(|| CableError::Weights {
                kind: WeightsErrorKind::Metadata,
                item: item.to_owned(),
                reason: format!("unknown activation {name:?}; known: logsig, tansig, purelin"),
            })
    }

    /// Apply in place to a layer's net inputs. Built on [`exp_parts`] with one division per
    /// neuron, branch-free, so the compiler vectorises it across the layer; agrees with
    /// `f64::tanh` and `1/(1+f64::exp(−n))` to ~1e-16 absolute (tested below).
    #[inline(always)]
    pub fn apply(self, z: &mut [f64]) {
        let f = self.fold_factor();
        z.iter_mut().for_each(|v| *v *= f);
        self.apply_folded(z);
    }

    /// The factor a layer's weights and bias are multiplied by so that its net inputs arrive
    /// as the argument of `exp` (exact: ±1 and 2 are powers of two).
    pub(crate) fn fold_factor(self) -> f64 {
        match self {
            Self::Logsig => -1.0,
            Self::Tansig => 2.0,
            Self::Purelin => 1.0,
        }
    }

    /// [`Activation::apply`] on net inputs already multiplied by [`Activation::fold_factor`].
    #[inline(always)]
    pub(crate) fn apply_folded(self, z: &mut [f64]) {
        match self {
            // 1/(1 + e⁻ⁿ) with e⁻ⁿ = s·N/D  →  D / (D + s·N)
            Self::Logsig => z.iter_mut().for_each(|v| {
                let (num, den, scale) = exp_parts(*v);
                *v = den / (den + scale * num);
            }),
            // tanh n = (e²ⁿ − 1)/(e²ⁿ + 1) with e²ⁿ = s·N/D  →  (s·N − D)/(s·N + D)
            Self::Tansig => z.iter_mut().for_each(|v| {
                let (num, den, scale) = exp_parts(*v);
                let sn = scale * num;
                *v = (sn - den) / (sn + den);
            }),
            Self::Purelin => {}
        }
    }
}

/// `eˣ` as `scale · num / den`, for `x` clamped to [−700, 700] (beyond, both sigmoids are
/// saturated to the last bit): Cephes' rational approximation with `x = n·ln2 + r`,
/// |r| ≤ ln2/2 (Cody–Waite split of ln2), `eʳ = (Q(r²) + r·P(r²)) / (Q(r²) − r·P(r²))` and
/// `scale = 2ⁿ` assembled in the exponent bits. No table, no branch, no libm call, so a
/// layer's neurons go through SIMD lanes together; callers fold the division into their own.
// Cephes' coefficients are kept verbatim, digits beyond f64 included, to be checkable.
#[allow(clippy::excessive_precision)]
#[inline(always)]
pub fn exp_parts(x: f64) -> (f64, f64, f64) {
    const LOG2E: f64 = std::f64::consts::LOG2_E;
    const C1: f64 = 6.931_457_519_531_25e-1;
    const C2: f64 = 1.428_606_820_309_417_232_12e-6;
    const P: [f64; 3] = [
        1.261_771_930_748_105_908_78e-4,
        3.029_944_077_074_419_613_00e-2,
        9.999_999_999_999_999_999_10e-1,
    ];
    const Q: [f64; 4] = [
        3.001_985_051_386_644_550_42e-6,
        2.524_483_403_496_841_041_92e-3,
        2.272_655_482_081_550_287_66e-1,
        2.000_000_000_000_000_000_09,
    ];
    // 1.5·2⁵²: adding it rounds to the nearest integer and leaves that integer in the low bits.
    const SHIFTER: f64 = 6_755_399_441_055_744.0;
    let x = x.clamp(-700.0, 700.0);
    let t = x * LOG2E + SHIFTER;
    let n = t - SHIFTER;
    let r = x - n * C1 - n * C2;
    let rr = r * r;
    let px = r * ((P[0] * rr + P[1]) * rr + P[2]);
    let qx = ((Q[0] * rr + Q[1]) * rr + Q[2]) * rr + Q[3];
    let k = t.to_bits().wrapping_sub(SHIFTER.to_bits());
    (qx + px, qx - px, f64::from_bits(k.wrapping_add(1023) << 52))
}

#[cfg(test)]
#[allow(clippy::float_cmp)] // saturation and range ends are exact by construction
mod tests {
    use super::*;

    /// `eˣ` from [`exp_parts`]; relative error ≤ 2⁻⁵² over [−699, 699] (tested against `f64::exp`).
    fn exp(x: f64) -> f64 {
        let (num, den, scale) = exp_parts(x);
        scale * (num / den)
    }

    #[test]
    fn names_round_trip_and_unknown_is_a_metadata_error() {
        for a in Activation::ALL {
            assert_eq!(Activation::parse(a.name(), "x").unwrap(), a);
        }
        let err = Activation::parse("relu", "architecture").unwrap_err();
        assert!(matches!(
            err,
            CableError::Weights { kind: WeightsErrorKind::Metadata, ref item, .. } if item == "architecture"
        ));
    }

    #[test]
    fn exp_is_accurate_to_the_last_bits_over_its_range() {
        let mut worst: f64 = 0.0;
        for i in 0..=2_000_000 {
            let x = -699.0 + 1398.0 * (i as f64) / 2_000_000.0 + 1e-7 * (i % 7) as f64;
            let (a, b) = (exp(x), x.exp());
            worst = worst.max(((a - b) / b).abs());
        }
        for x in [0.0, 1e-300, -1e-300, 0.5, -0.5, 0.34657359, -0.34657359] {
            worst = worst.max(((exp(x) - x.exp()) / x.exp()).abs());
        }
        assert!(worst < 4.5e-16, "worst relative error {worst:e}");
        assert!((exp(-1e9) / (-700f64).exp() - 1.0).abs() < 1e-15);
        assert!(exp(1e9).is_finite());
    }

    #[test]
    fn values_match_matlab_definitions_including_saturation() {
        let mut z = [-800.0, -2.0, 0.0, 0.5, 800.0];
        let src = z;
        Activation::Tansig.apply(&mut z);
        for (v, n) in z.iter().zip(src) {
            let matlab = 2.0 / (1.0 + (-2.0 * n).exp()) - 1.0;
            assert!((v - matlab).abs() < 1e-15, "{v} vs {matlab}");
        }
        let mut z = src;
        Activation::Logsig.apply(&mut z);
        assert!(z[0] < 1e-300);
        assert_eq!(z[2], 0.5);
        assert_eq!(z[4], 1.0);
        assert!(z.iter().all(|v| v.is_finite()));
    }
}
