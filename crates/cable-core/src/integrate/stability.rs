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

use super::MAX_SUBSTEPS;
use crate::dynamics::Model;
use crate::error::{check, CableError, Result};

/// Iteration cap of the Schur decomposition behind the eigenvalues (nalgebra's default is
/// unbounded; a NaN or badly scaled Jacobian would loop for ever).
const SCHUR_MAX_ITERATIONS: usize = 10_000;

/// Result of [`propose_step`].
#[derive(Debug, Clone, Copy, PartialEq)]
pub struct StepAdvice {
    /// Largest stable RK4 step `h_max` (s) at the linearisation point (∞ if no mode limits it).
    pub max_stable_step: f64,
    /// The eigenvalue that sets `h_max` (real, imaginary parts; 1/s).
    pub stiffest_eigenvalue: (f64, f64),
    /// Sub-steps per sample interval: `ceil(dt / (safety · h_max))`, at least 1 and at most
    /// [`MAX_SUBSTEPS`] (more is an error).
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

/// [`jacobian`] as a row-major `n × n` buffer, with `x` and `u` checked (length, finite) and
/// the result checked finite.
pub fn jacobian_rows<M: Model + ?Sized>(model: &M, x: &[f64], u: &[f64]) -> Result<Vec<f64>> {
    let n = model.n_states();
    check::len("x", x, n)?;
    check::len("u", u, model.n_inputs())?;
    check::all_finite("x", x, 1)?;
    check::all_finite("u", u, 1)?;
    let rows = jacobian(model, x, u).transpose().as_slice().to_vec();
    check::result_finite(
        "jacobian",
        &rows,
        n,
        "the model's derivative overflows near this state; check the state and the parameters",
    )?;
    Ok(rows)
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
    let n = model.n_states();
    let jac = DMatrix::from_row_slice(n, n, &jacobian_rows(model, x, u)?);
    // a bounded Schur iteration: a matrix it cannot reduce is an error, never a hang (a model
    // without states — a replay driven wholly by its inputs — has no mode to limit the step)
    let eig: Vec<nalgebra::Complex<f64>> = if n == 0 {
        Vec::new()
    } else {
        jac.try_schur(f64::EPSILON, SCHUR_MAX_ITERATIONS)
            .ok_or_else(|| CableError::NotConverged {
                what: "eigenvalues of the jacobian".into(),
                limit: SCHUR_MAX_ITERATIONS,
                hint: "the linearised model is too badly scaled; check the parameters",
            })?
            .complex_eigenvalues()
            .iter()
            .copied()
            .collect()
    };
    let mut best = (f64::INFINITY, (0.0, 0.0));
    for l in eig.iter() {
        let radius = rk4_stability_radius(l.re, l.im);
        let h = radius / l.re.hypot(l.im);
        if h < best.0 {
            best = (h, (l.re, l.im));
        }
    }
    let h_safe = best.0 * safety.min(1.0);
    let need = dt / h_safe; // +inf when h_safe underflows to 0; 0 when no mode limits h
    if need.is_nan() || need > MAX_SUBSTEPS as f64 {
        return Err(CableError::InvalidParameter {
            name: "dt".into(),
            value: dt,
            requirement: "at most 100000 (MAX_SUBSTEPS) stable RK4 steps long at this state; \
                          use a smaller dt or check the stiffness parameters",
        });
    }
    let substeps = (need.ceil() as usize).max(1);
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
    fn a_model_without_states_needs_one_step() {
        // a parallel robot's drive replayed from its drum angle and platform: no state at all
        let doc = serde_json::json!({
            "pulleys": [{"name": "p", "radius": 0.01}],
            "motors": [
                {"name": "drum", "drive": "position", "capstan_radius": 0.02},
                {"name": "end", "drive": "position", "capstan_radius": 1.0}
            ],
            "cables": [{"name": "c", "motor": "drum", "end_motor": "end", "stiffness": 1e4,
                        "routing": [{"pulley": "p", "wrap": 1.0}]}]
        });
        let spec = crate::dynamics::network::NetworkSpec::from_json(&doc.to_string()).unwrap();
        let net = crate::dynamics::network::Network::new(&spec).unwrap();
        assert_eq!(net.n_states(), 0);
        let advice = propose_step(&net, &[], &[0.0; 4], 1e-3, 0.9).unwrap();
        assert_eq!(advice.substeps, 1);
    }

    #[test]
    fn advice_refuses_an_overflowing_jacobian_and_a_dt_past_the_cap() {
        let model = crate::dynamics::raven2(3).unwrap();
        let u = [0.0; 6];
        // a NaN Jacobian once sent the unbounded Schur iteration into an endless loop
        let huge = vec![1e154; 12];
        let got = propose_step(&model, &huge, &u, 1e-3, 0.9);
        assert!(
            matches!(got, Err(CableError::NonFiniteResult { .. })),
            "{got:?}"
        );
        let rest = model.rest_state();
        let got = propose_step(&model, &rest, &u, 1e300, 0.9);
        assert!(matches!(got, Err(CableError::InvalidParameter { ref name, .. }) if name == "dt"));
        let ok = propose_step(&model, &rest, &u, 1e-3, 0.9).unwrap();
        assert!((1..=MAX_SUBSTEPS).contains(&ok.substeps));
        // the cap's number in the error text is the constant's
        let err = check::substeps("substeps", MAX_SUBSTEPS + 1).unwrap_err();
        assert!(err.to_string().contains(&MAX_SUBSTEPS.to_string()), "{err}");
        assert_eq!(check::substeps("substeps", MAX_SUBSTEPS), Ok(MAX_SUBSTEPS));
        assert!(check::substeps("substeps", 0).is_err());
    }

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
