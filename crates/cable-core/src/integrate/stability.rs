//! Step-size advice from the stiffest mode of the linearised model.
//!
//! RK4 applied to `ẋ = λx` multiplies the state by
//! `R(z) = 1 + z + z²/2 + z³/6 + z⁴/24` with `z = hλ`; it is stable while `|R(z)| ≤ 1`. The
//! boundary crosses the negative real axis at `|z| ≈ 2.785` and the imaginary axis at
//! `|z| = 2√2 ≈ 2.828`. [`propose_step`] linearises the model at a state (central finite
//! differences), takes the eigenvalues `λ_i` of the Jacobian, finds for each the largest `h` with
//! `|R(hλ_i)| ≤ 1` along its ray, and returns the smallest such `h` with the number of RK4
//! sub-steps a sample interval needs. Eigenvalues in the open right half-plane (physically
//! unstable modes, e.g. an inverted link) have no stability bound; they are reported but do not
//! limit the step.

use nalgebra::DMatrix;

use crate::dynamics::Model;
use crate::error::{check, Result};

/// Result of [`propose_step`].
#[derive(Debug, Clone, Copy, PartialEq)]
pub struct StepAdvice {
    /// Largest stable RK4 step `h_max` (s) at the linearisation point (∞ if no mode limits it).
    pub max_stable_step: f64,
    /// The eigenvalue that sets `h_max` (real, imaginary parts; 1/s).
    pub stiffest_eigenvalue: (f64, f64),
    /// Sub-steps per sample interval: `ceil(dt / (safety · h_max))`, at least 1.
    pub substeps: usize,
}

/// `|R(z)|` of classical RK4 at `z = re + i·im`.
fn rk4_gain(re: f64, im: f64) -> f64 {
    // Horner in complex arithmetic: R = 1 + z(1 + z/2(1 + z/3(1 + z/4)))
    let mul = |(a, b): (f64, f64), (c, d): (f64, f64)| (a * c - b * d, a * d + b * c);
    let mut acc = (1.0, 0.0);
    for k in [4.0, 3.0, 2.0, 1.0] {
        let zk = (re / k, im / k);
        let p = mul(zk, acc);
        acc = (1.0 + p.0, p.1);
    }
    acc.0.hypot(acc.1)
}

/// Largest `r` such that `|R(r·e^{iα})| ≤ 1` on `[r_0, r]` for the unit direction of
/// `λ = (re, im)`, i.e. the stability radius of RK4 along that ray, in units of `|z|`. Returns
/// `f64::INFINITY` for directions in the open right half-plane or `λ = 0`.
pub fn rk4_stability_radius(re: f64, im: f64) -> f64 {
    let mag = re.hypot(im);
    if mag == 0.0 || re > 0.0 {
        return f64::INFINITY;
    }
    let (dr, di) = (re / mag, im / mag);
    // March outwards from a small radius to the first exit, then bisect. Near the imaginary
    // axis |R| ≈ 1 − r⁶/72 for small r, so start the march past the origin.
    let step = 1e-3;
    let mut r = step;
    while r < 4.0 {
        if rk4_gain(r * dr, r * di) > 1.0 + 1e-12 {
            let (mut lo, mut hi) = (r - step, r);
            for _ in 0..60 {
                let mid = 0.5 * (lo + hi);
                if rk4_gain(mid * dr, mid * di) > 1.0 + 1e-12 {
                    hi = mid;
                } else {
                    lo = mid;
                }
            }
            return lo;
        }
        r += step;
    }
    4.0
}

/// Jacobian `∂f/∂x` at `(x, u)` by central differences with steps `1e-6·max(1, |x_i|)`.
pub fn jacobian<M: Model + ?Sized>(model: &M, x: &[f64], u: &[f64]) -> DMatrix<f64> {
    let n = model.n_states();
    let mut jac = DMatrix::zeros(n, n);
    let (mut xp, mut fp, mut fm) = (x.to_vec(), vec![0.0; n], vec![0.0; n]);
    for j in 0..n {
        let h = 1e-6 * x[j].abs().max(1.0);
        xp[j] = x[j] + h;
        model.derivative(&xp, u, &mut fp);
        xp[j] = x[j] - h;
        model.derivative(&xp, u, &mut fm);
        xp[j] = x[j];
        for i in 0..n {
            jac[(i, j)] = (fp[i] - fm[i]) / (2.0 * h);
        }
    }
    jac
}

/// Step-size advice for sample interval `dt` at the linearisation point `(x, u)`.
///
/// `safety` in (0, 1] scales `h_max` (0.9 leaves a 10 % margin for the state-dependent
/// stiffness of slack cables and contact).
pub fn propose_step<M: Model + ?Sized>(
    model: &M,
    x: &[f64],
    u: &[f64],
    dt: f64,
    safety: f64,
) -> Result<StepAdvice> {
    check::positive("dt", dt)?;
    check::positive("safety", safety)?;
    check::len("x", x, model.n_states())?;
    check::len("u", u, model.n_inputs())?;
    check::all_finite("x", x, 1)?;
    check::all_finite("u", u, 1)?;
    let eig = jacobian(model, x, u).complex_eigenvalues();
    let mut best = (f64::INFINITY, (0.0, 0.0));
    for l in eig.iter() {
        let radius = rk4_stability_radius(l.re, l.im);
        let h = radius / l.re.hypot(l.im);
        if h < best.0 {
            best = (h, (l.re, l.im));
        }
    }
    let h_safe = best.0 * safety.min(1.0);
    let substeps = if h_safe.is_finite() {
        ((dt / h_safe).ceil() as usize).max(1)
    } else {
        1
    };
    Ok(StepAdvice {
        max_stable_step: best.0,
        stiffest_eigenvalue: best.1,
        substeps,
    })
}

#[cfg(test)]
#[allow(clippy::float_cmp)] // exact zeros are the claims under test (slack, no contact)
mod tests {
    use super::*;

    #[test]
    fn stability_radius_on_the_axes() {
        assert!((rk4_stability_radius(-1.0, 0.0) - 2.785_293_563).abs() < 1e-6);
        assert!((rk4_stability_radius(0.0, 1.0) - 2.0 * 2f64.sqrt()).abs() < 1e-6);
        assert!(rk4_stability_radius(1.0, 0.0).is_infinite());
    }

    #[test]
    fn advice_for_the_raven_shoulder_needs_substeps_at_1khz() {
        let model = crate::dynamics::raven2(1).unwrap();
        let x = model.rest_state();
        let adv = propose_step(&model, &x, &[0.0, 0.0], 1e-3, 0.9).unwrap();
        assert!(adv.substeps >= 2, "{adv:?}");
        // and the advice is right: at h_max·1.05 a step from rest grows, at 0.95 it does not
        let jac = jacobian(&model, &x, &[0.0, 0.0]);
        let lam = adv.stiffest_eigenvalue;
        let r_lo = rk4_gain(
            0.95 * adv.max_stable_step * lam.0,
            0.95 * adv.max_stable_step * lam.1,
        );
        let r_hi = rk4_gain(
            1.05 * adv.max_stable_step * lam.0,
            1.05 * adv.max_stable_step * lam.1,
        );
        assert!(r_lo <= 1.0 && r_hi > 1.0, "{r_lo} {r_hi} {jac}");
    }
}
