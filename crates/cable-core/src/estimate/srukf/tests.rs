//! Tests of the square-root UKF: the exact Kalman filter, specialised builds bit for bit,
//! recovery, divergence, the smoother.

use super::*;
use crate::estimate::{LinearObserve, LinearProcess};
use approx::assert_relative_eq;

/// Exact Kalman filter for `x' = A x + B u`, `y = H x` (row-major), covariances row-major.
struct Kf {
    n: usize,
    x: Vec<f64>,
    p: nalgebra::DMatrix<f64>,
}

fn dm(r: usize, c: usize, v: &[f64]) -> nalgebra::DMatrix<f64> {
    nalgebra::DMatrix::from_row_slice(r, c, v)
}

/// `v·I` (`n × n`).
fn diag(n: usize, v: f64) -> Vec<f64> {
    (0..n * n)
        .map(|k| if k % (n + 1) == 0 { v } else { 0.0 })
        .collect()
}

/// A slightly damped process matrix with cross-coupling of size `c` (row-major).
fn coupled(n: usize, c: f64) -> Vec<f64> {
    (0..n * n)
        .map(|k| {
            let (i, j) = (k / n, k % n);
            if i == j {
                0.98
            } else {
                c * (((i * 7 + j * 3) % 5) as f64 - 2.0)
            }
        })
        .collect()
}

/// A linear measurement that does not tell the filter its matrix, so the filter runs the
/// sigma-point update (eqs 3.16–3.21) on it.
#[derive(Clone)]
struct Opaque(LinearObserve);

impl Observe for Opaque {
    fn n_outputs(&self) -> usize {
        self.0.n_outputs()
    }
    fn observe(&mut self, x: &[f64], u: &[f64], y: &mut [f64]) {
        self.0.observe(x, u, y)
    }
}

#[test]
fn linear_measurement_in_closed_form_equals_the_sigma_point_update() {
    let n = 5;
    // a rotating, slightly damped process with cross-coupling
    let a = coupled(n, 0.05);
    let q: Vec<f64> = (0..n * n)
        .map(|k| if k % (n + 1) == 0 { 1e-4 } else { 0.0 })
        .collect();
    let p0: Vec<f64> = (0..n * n)
        .map(|k| if k % (n + 1) == 0 { 0.2 } else { 0.03 })
        .collect();
    let x0 = vec![0.3, -0.1, 0.2, 0.0, 0.5];
    let r = vec![1e-2, 1e-3, 0.0, 1e-3, 2e-2, 0.0, 0.0, 0.0, 5e-3];
    let dense = vec![
        1.0, 0.5, 0.0, -0.2, 0.0, //
        0.0, 0.0, 2.0, 0.0, 0.3, //
        0.1, 0.1, 0.1, 0.1, 0.1,
    ];
    let pick = vec![
        0.0, 0.0, 0.0, 1.0, 0.0, //
        1.0, 0.0, 0.0, 0.0, 0.0, //
        0.0, 0.0, 0.0, 0.0, 1.0,
    ];
    // (α, relative tolerance): at α = 1e-3 the sigma-point sums carry ~eps/γ² rounding
    for (alpha, tol) in [(0.5, 1e-12), (1e-3, 1e-8)] {
        for h in [&dense, &pick] {
            let scaling = SigmaScaling {
                alpha,
                ..SigmaScaling::default()
            };
            let process = LinearProcess::new(n, 0, a.clone(), vec![]).unwrap();
            let observe = LinearObserve::new(3, n, h.clone()).unwrap();
            assert!(observe.linear().is_some());
            let mut closed =
                SrUkf::new(process.clone(), observe.clone(), &x0, &p0, &q, &r, scaling).unwrap();
            let mut sigma =
                SrUkf::new(process, Opaque(observe), &x0, &p0, &q, &r, scaling).unwrap();
            for k in 0..60 {
                let t = k as f64;
                let y = [(0.3 * t).sin(), 0.2 * (0.1 * t).cos(), 0.05 * t.sqrt()];
                // every fourth step drops the middle channel (the masked path)
                let mask = [true, k % 4 != 0, true];
                closed.step(&[], &y, Some(&mask)).unwrap();
                sigma.step(&[], &y, Some(&mask)).unwrap();
                let (pc, ps) = (closed.covariance(), sigma.covariance());
                let scale = ps.iter().fold(0.0_f64, |m, v| m.max(v.abs()));
                for i in 0..n {
                    assert!(
                        (closed.x()[i] - sigma.x()[i]).abs() <= tol,
                        "x[{i}] step {k}"
                    );
                }
                for (c, s) in pc.iter().zip(&ps) {
                    assert!((c - s).abs() <= tol * scale, "P at step {k}");
                }
                assert!((closed.health().nis - sigma.health().nis).abs() <= tol * 1e3);
            }
        }
    }
}

#[test]
fn a_state_that_overflows_is_a_divergence_error_not_a_nan() {
    // x' = 1e200·x: finite for one step from x = 1, infinite after two; P overflows first
    for (x0, p0) in [(1.0, 1e-300), (1e-300, 1.0)] {
        let n = 2;
        let a = vec![1e200, 0.0, 0.0, 1e200];
        let mut f = SrUkf::new(
            LinearProcess::new(n, 0, a, vec![]).unwrap(),
            LinearObserve::select(n, &[0]).unwrap(),
            &[x0, x0],
            &[p0, 0.0, 0.0, p0],
            &[0.0; 4],
            &[1e-2],
            SigmaScaling {
                alpha: 0.5,
                ..SigmaScaling::default()
            },
        )
        .unwrap();
        let mut outcome = Ok(());
        for _ in 0..4 {
            outcome = f.predict(&[]);
            if outcome.is_err() {
                break;
            }
            assert!(f
                .x()
                .iter()
                .chain(f.sqrt_covariance())
                .all(|v| v.is_finite()));
        }
        assert!(
            matches!(outcome, Err(CableError::FilterDiverged { .. })),
            "{outcome:?}"
        );
        // the failed step is undone: the filter holds the last finite state
        assert!(f
            .x()
            .iter()
            .chain(f.sqrt_covariance())
            .all(|v| v.is_finite()));
    }
}

#[test]
fn linear_system_equals_the_kalman_filter_with_negative_w0() {
    let (n, m, p) = (4, 1, 2);
    let dt = 0.01;
    let a = vec![
        1.0,
        dt,
        0.0,
        0.0, //
        -dt * 40.0,
        1.0 - dt * 0.5,
        dt * 10.0,
        0.0, //
        0.0,
        0.0,
        1.0,
        dt, //
        dt * 10.0,
        0.0,
        -dt * 30.0,
        1.0 - dt * 0.2,
    ];
    let b = vec![0.0, dt, 0.0, 0.0];
    let h = vec![1.0, 0.0, 0.0, 0.0, 0.0, 0.0, 1.0, 0.0];
    let q: Vec<f64> = (0..n * n)
        .map(|k| if k % (n + 1) == 0 { 1e-6 } else { 0.0 })
        .collect();
    let r = vec![1e-4, 2e-5, 2e-5, 4e-4];
    let p0: Vec<f64> = (0..n * n)
        .map(|k| if k % (n + 1) == 0 { 0.1 } else { 0.01 })
        .collect();
    let x0 = vec![0.1, 0.0, -0.2, 0.0];
    let mut f = SrUkf::new(
        LinearProcess::new(n, m, a.clone(), b.clone()).unwrap(),
        LinearObserve::new(p, n, h.clone()).unwrap(),
        &x0,
        &p0,
        &q,
        &r,
        SigmaScaling::default(),
    )
    .unwrap();
    assert!(f.weights().wc.0 < 0.0, "seed α = 1e-3 gives a negative W0");
    let mut kf = Kf {
        n,
        x: x0.clone(),
        p: dm(n, n, &p0),
    };
    let (am, bm, hm, qm, rm) = (
        dm(n, n, &a),
        dm(n, m, &b),
        dm(p, n, &h),
        dm(n, n, &q),
        dm(p, p, &r),
    );
    for k in 0..300 {
        let u = [(k as f64 * 0.05).sin()];
        let y = [0.1 * (k as f64 * 0.03).cos(), -0.05 + 1e-3 * k as f64];
        f.step(&u, &y, None).unwrap();
        // exact KF
        let x = nalgebra::DVector::from_column_slice(&kf.x);
        let xp = &am * x + &bm * u[0];
        let pp = &am * &kf.p * am.transpose() + &qm;
        let s = &hm * &pp * hm.transpose() + &rm;
        let kgain = &pp * hm.transpose() * s.clone().try_inverse().unwrap();
        let innov = nalgebra::DVector::from_column_slice(&y) - &hm * &xp;
        let xn = &xp + &kgain * innov;
        kf.p = &pp - &kgain * s * kgain.transpose();
        kf.x = xn.as_slice().to_vec();
        let cov = f.covariance();
        for i in 0..kf.n {
            assert_relative_eq!(f.x()[i], kf.x[i], epsilon = 1e-9, max_relative = 1e-7);
            for j in 0..kf.n {
                assert_relative_eq!(
                    cov[i + j * n],
                    kf.p[(i, j)],
                    epsilon = 1e-12,
                    max_relative = 1e-6
                );
            }
        }
    }
    assert_eq!(f.health().recoveries_total, 0);
    assert!(f.health().nis.is_finite());
}

/// `x₀ ← x₀ + c·x₁²`, `x₁ ← x₁`: the sigma points' mean moves by `c·P₁₁`, so the 0th
/// point's downdate is `|W(c)_0|·(c·P₁₁)² ≈ 1e6·c²` in `x₀`, as large as the spread it
/// cancels.
#[derive(Clone)]
struct Quadratic(f64);

impl Process for Quadratic {
    fn n_states(&self) -> usize {
        2
    }
    fn n_inputs(&self) -> usize {
        0
    }
    fn propagate(&mut self, x: &mut [f64], _u: &[f64]) {
        x[0] += self.0 * x[1] * x[1];
    }
}

#[test]
fn the_folded_0th_point_gives_the_sequential_update() {
    // c = 1e-3: half of the predicted spread of x0 is cancelled by the 0th point; x0 is
    // measured, so S_y, P_xy and S all take the fold's corrections
    let mk = |observe| {
        SrUkf::new(
            Quadratic(1e-3),
            observe,
            &[0.0, 1.0],
            &[1.0, 0.0, 0.0, 1.0],
            &[0.0; 4],
            &[0.1],
            SigmaScaling::default(),
        )
        .unwrap()
    };
    for observe in [
        LinearObserve::select(2, &[0]).unwrap(),
        LinearObserve::new(1, 2, vec![1.0, 0.5]).unwrap(),
    ] {
        let (mut folded, mut split) = (mk(observe.clone()), mk(observe));
        assert!(folded.weights().wc.0 < -1e5);
        for k in 0..5 {
            let y = [0.3 * k as f64];
            // the cancelled spread: S' holds 1 + 1e6·c² ≈ 2 in x0, v0 ≈ 1
            if k == 0 {
                folded.predict_spread::<0>(&[]);
                let v0: f64 = folded.chi[0] - folded.x[0];
                let w0 = -folded.weights().wc.0;
                assert!((w0 * v0 * v0 - 1.0).abs() < 1e-3, "{}", w0 * v0 * v0);
                folded.reset(&[0.0, 1.0], &[1.0, 0.0, 0.0, 1.0]).unwrap();
            }
            folded.step(&[], &y, None).unwrap();
            split.predict(&[]).unwrap();
            split.update(&[], &y, None).unwrap();
            // a fold that dropped a correction would be off by ~50 %
            for (a, b) in folded.x().iter().zip(split.x()) {
                assert_relative_eq!(a, b, epsilon = 1e-12, max_relative = 1e-10);
            }
            for (a, b) in folded.covariance().iter().zip(&split.covariance()) {
                assert_relative_eq!(a, b, epsilon = 1e-12, max_relative = 1e-10);
            }
            assert_relative_eq!(
                folded.health().nis,
                split.health().nis,
                max_relative = 1e-10
            );
            assert_eq!(folded.health().recoveries_total, 0);
        }
    }
}

#[test]
fn a_downdate_lost_to_rounding_is_recovered_and_counted() {
    // a near-perfect measurement of x0: the posterior variance 1e-30 is below the
    // resolution of the prior's 1.0, so the rank-one downdate fails in floating point
    let n = 2;
    let mut f = SrUkf::new(
        LinearProcess::new(n, 0, vec![1.0, 0.0, 0.0, 1.0], vec![]).unwrap(),
        LinearObserve::select(n, &[0]).unwrap(),
        &[0.0, 0.0],
        &[1.0, 0.0, 0.0, 1.0],
        &[0.0; 4],
        &[1e-30],
        SigmaScaling::default(),
    )
    .unwrap();
    f.step(&[], &[0.5], None).unwrap();
    let h = f.health();
    assert!(h.recovered >= 1 && h.recoveries_total >= 1);
    let cov = f.covariance();
    assert!(cov.iter().all(|v| v.is_finite()));
    assert!(
        cov[0] >= 0.0 && cov[0] < 1e-6,
        "x0 is now known: {}",
        cov[0]
    );
    assert_relative_eq!(cov[3], 1.0, epsilon = 1e-9);
    assert_relative_eq!(f.x()[0], 0.5, epsilon = 1e-9);
}

#[test]
fn masked_channels_are_not_used_and_nan_is_refused_unless_masked() {
    let n = 2;
    let mk = || {
        SrUkf::new(
            LinearProcess::new(n, 0, vec![1.0, 0.0, 0.0, 1.0], vec![]).unwrap(),
            LinearObserve::select(n, &[0, 1]).unwrap(),
            &[0.0, 0.0],
            &[1.0, 0.0, 0.0, 1.0],
            &[0.0; 4],
            &[0.01, 0.0, 0.0, 0.01],
            SigmaScaling::default(),
        )
        .unwrap()
    };
    let mut f = mk();
    assert!(matches!(
        f.step(&[], &[1.0, f64::NAN], None),
        Err(CableError::NotFinite { index: 1, .. })
    ));
    let mut f = mk();
    f.step(&[], &[1.0, f64::NAN], Some(&[true, false])).unwrap();
    assert_relative_eq!(f.x()[0], 1.0 / 1.01, epsilon = 1e-9);
    assert!(f.x()[1].abs() < 1e-300);
    assert_relative_eq!(f.covariance()[3], 1.0, epsilon = 1e-12);
    assert_eq!(f.health().measured, 1);
}

#[test]
fn bad_covariances_are_typed_errors() {
    let n = 2;
    let mk = |p0: &[f64], r: &[f64]| {
        SrUkf::new(
            LinearProcess::new(n, 0, vec![1.0, 0.0, 0.0, 1.0], vec![]).unwrap(),
            LinearObserve::select(n, &[0]).unwrap(),
            &[0.0, 0.0],
            p0,
            &[0.0; 4],
            r,
            SigmaScaling::default(),
        )
    };
    assert!(matches!(
        mk(&[1.0, 2.0, 2.0, 1.0], &[1.0]),
        Err(CableError::InvalidParameter { .. })
    ));
    assert!(matches!(
        mk(&[1.0, 0.5, 0.0, 1.0], &[1.0]),
        Err(CableError::InvalidParameter { .. })
    ));
    assert!(matches!(
        mk(&[1.0, 0.0, 0.0, 1.0], &[0.0]),
        Err(CableError::InvalidParameter { .. })
    ));
    assert!(matches!(
        mk(&[1.0, 0.0, 0.0], &[1.0]),
        Err(CableError::Shape { .. })
    ));
}

/// Largest `|xᵢ − x'ᵢ| / σᵢ` and `|Pᵢⱼ − P'ᵢⱼ| / (σᵢσⱼ)` between two filters (`σ` from `a`).
fn gap<P: Process, H: Observe>(a: &SrUkf<P, H>, b: &SrUkf<P, H>) -> (f64, f64) {
    let n = a.n_states();
    let (pa, pb) = (a.covariance(), b.covariance());
    let sd = |i: usize| pa[i * (n + 1)].sqrt();
    let (mut gx, mut gp) = (0.0_f64, 0.0_f64);
    for i in 0..n {
        gx = gx.max((a.x()[i] - b.x()[i]).abs() / sd(i));
        for j in 0..n {
            gp = gp.max((pa[i + j * n] - pb[i + j * n]).abs() / (sd(i) * sd(j)));
        }
    }
    (gx, gp)
}

/// Runs `steps` steps five ways. `step()` (the build specialised for `n`, with the CPU's
/// lanes), `step()` with the portable lanes and the general build of `step()` must agree
/// bit for bit. `predict()` + `update()` runs the 0th point's downdate on its own where
/// `step()` folds it into the measurement's: it must agree to rounding, i.e. be no further
/// from `step()` (over the whole run) than ten times the distance between two sequential
/// runs whose `P₀` differ by 4e-16 relative (with the seed's α = 1e-3, a filter's sums
/// amplify rounding by up to ~1/α; a strongly nonlinear model more).
fn three_builds_agree<P: Process + Clone, H: Observe + Clone>(
    f: SrUkf<P, H>,
    steps: usize,
    input: impl Fn(usize) -> Vec<f64>,
    measure: impl Fn(usize, &[f64]) -> (Vec<f64>, Option<Vec<bool>>),
) {
    let mut nudged = f.clone();
    let p0: Vec<f64> = f.covariance().iter().map(|v| v * (1.0 + 4e-16)).collect();
    nudged.reset(f.x(), &p0).unwrap();
    let (mut fast, mut portable, mut general, mut split) = (f.clone(), f.clone(), f.clone(), f);
    portable.avx2 = false;
    let (mut folded_gap, mut rounding_gap) = ((0.0_f64, 0.0_f64), (0.0_f64, 0.0_f64));
    for k in 0..steps {
        let u = input(k);
        let (y, mask) = measure(k, general.x());
        let mask = mask.as_deref();
        fast.step(&u, &y, mask).unwrap();
        portable.step(&u, &y, mask).unwrap();
        general.step_unchecked::<0>(&u, &y, mask).unwrap();
        for seq in [&mut split, &mut nudged] {
            seq.predict(&u).unwrap();
            seq.update(&u, &y, mask).unwrap();
        }
        for other in [&fast, &portable] {
            let bits = |v: &[f64]| v.iter().map(|v| v.to_bits()).collect::<Vec<_>>();
            assert_eq!(bits(other.x()), bits(general.x()), "x at step {k}");
            let (so, sg) = (other.sqrt_covariance(), general.sqrt_covariance());
            assert_eq!(bits(so), bits(sg), "S at step {k}");
            assert_eq!(other.health().nis.to_bits(), general.health().nis.to_bits());
        }
        let (g, r) = (gap(&split, &general), gap(&split, &nudged));
        folded_gap = (folded_gap.0.max(g.0), folded_gap.1.max(g.1));
        rounding_gap = (rounding_gap.0.max(r.0), rounding_gap.1.max(r.1));
    }
    assert!(general.x().iter().all(|v| v.is_finite()));
    let n = general.n_states();
    assert!(
        folded_gap.0 <= 10.0 * rounding_gap.0.max(1e-8)
            && folded_gap.1 <= 10.0 * rounding_gap.1.max(1e-11),
        "n = {n}: step() vs predict() + update() {folded_gap:?}, rounding {rounding_gap:?}"
    );
}

#[test]
fn specialised_steps_equal_the_general_build_bit_for_bit() {
    use crate::dynamics::{raven2, Model};
    use crate::estimate::ModelProcess;
    // the Raven-II transmission (n = 12), motor encoders, every third step one masked
    let model = raven2(3).unwrap();
    let n = model.n_states();
    let mut x0 = vec![0.0; n];
    let mut q_m = [0.0; 3];
    model.joint_to_motor(&[0.2, 1.4, 0.3], &mut q_m);
    for i in 0..3 {
        x0[4 * i] = q_m[i];
        x0[4 * i + 2] = [0.2, 1.4, 0.3][i];
    }
    let f = SrUkf::new(
        ModelProcess::new(model, 1e-4, 1).unwrap(),
        LinearObserve::select(n, &[0, 4, 8]).unwrap(),
        &x0,
        &diag(n, 1e-6),
        &diag(n, 1e-9),
        &diag(3, 1e-8),
        SigmaScaling::default(),
    )
    .unwrap();
    let x_ref = x0.clone();
    three_builds_agree(
        f,
        60,
        |k| {
            let s = (k as f64 * 0.3).sin();
            vec![0.2 * s, -0.1 * s, 0.05 * s, 0.0, 0.0, 0.0]
        },
        |k, _| {
            let y = vec![x_ref[0] + 1e-4 * k as f64, x_ref[4], x_ref[8] - 1e-5];
            let mask = (k % 3 == 2).then(|| vec![true, false, true]);
            (y, mask)
        },
    );
    // linear processes of sizes with and without whole SIMD blocks, selections and a
    // general H (the sigma-point update through an opaque model), past the specialised
    // sizes too
    for n in [1, 3, 5, 8, 13, SPECIALISED_UP_TO, SPECIALISED_UP_TO + 1] {
        let a = coupled(n, 0.01);
        let p = n.min(3);
        let picks: Vec<usize> = (0..p).map(|i| (i * 5) % n).collect();
        let x0: Vec<f64> = (0..n).map(|i| 0.1 * i as f64).collect();
        fn mk<H: Observe>(
            n: usize,
            a: &[f64],
            x0: &[f64],
            p: usize,
            obs: H,
        ) -> SrUkf<LinearProcess, H> {
            SrUkf::new(
                LinearProcess::new(n, 0, a.to_vec(), vec![]).unwrap(),
                obs,
                x0,
                &diag(n, 0.5),
                &diag(n, 1e-3),
                &diag(p, 1e-2),
                SigmaScaling::default(),
            )
            .unwrap()
        }
        let measure = |k: usize, _: &[f64]| {
            let y = (0..p).map(|i| (0.1 * (k + i) as f64).cos()).collect();
            (y, None)
        };
        let picked = LinearObserve::select(n, &picks).unwrap();
        three_builds_agree(mk(n, &a, &x0, p, picked.clone()), 20, |_| vec![], measure);
        let h: Vec<f64> = (0..p * n).map(|k| 0.3 + 0.1 * (k % 4) as f64).collect();
        let general_h = LinearObserve::new(p, n, h).unwrap();
        three_builds_agree(mk(n, &a, &x0, p, general_h), 20, |_| vec![], measure);
        three_builds_agree(mk(n, &a, &x0, p, Opaque(picked)), 20, |_| vec![], measure);
    }
}

/// A process that fails (as a front end's callback that raised) at one call.
struct Flaky {
    inner: LinearProcess,
    calls: usize,
    fail_at: usize,
    failed: bool,
}

impl Process for Flaky {
    fn n_states(&self) -> usize {
        self.inner.n_states()
    }
    fn n_inputs(&self) -> usize {
        self.inner.n_inputs()
    }
    fn propagate(&mut self, x: &mut [f64], u: &[f64]) {
        self.calls += 1;
        if self.calls == self.fail_at {
            self.failed = true; // the state is left as it came: only the flag says so
        } else {
            self.inner.propagate(x, u);
        }
    }
    fn failed(&self) -> bool {
        self.failed
    }
}

/// Measures `x[0]²` row by row in [`Observe::observe`], and all points at once (in reverse
/// order, to tell the two paths apart) in [`Observe::observe_many`].
struct Square {
    many: bool,
}

impl Observe for Square {
    fn n_outputs(&self) -> usize {
        1
    }
    fn observe(&mut self, x: &[f64], _u: &[f64], y: &mut [f64]) {
        y[0] = x[0] * x[0];
    }
    fn observe_many(&mut self, xs: &[f64], u: &[f64], ys: &mut [f64]) {
        if !self.many {
            for (x, y) in xs.chunks_exact(2).zip(ys.chunks_exact_mut(1)) {
                self.observe(x, u, y);
            }
            return;
        }
        let k = ys.len();
        for i in (0..k).rev() {
            ys[i] = xs[2 * i] * xs[2 * i];
        }
    }
}

#[test]
fn a_model_that_reports_a_failure_fails_the_step_and_the_filter_undoes_it() {
    let inner = LinearProcess::new(2, 0, coupled(2, 0.1), vec![]).unwrap();
    let process = Flaky {
        inner,
        calls: 0,
        fail_at: 8, // in the second step's five sigma points
        failed: false,
    };
    let h = LinearObserve::new(1, 2, vec![1.0, 0.0]).unwrap();
    let s = SigmaScaling::default();
    let mut f = SrUkf::new(
        process,
        h,
        &[0.1, 0.0],
        &diag(2, 0.1),
        &diag(2, 1e-4),
        &[1e-3],
        s,
    )
    .unwrap();
    f.step(&[], &[0.2], None).unwrap();
    let (x, sq) = (f.x().to_vec(), f.sqrt_covariance().to_vec());
    let err = f.step(&[], &[0.2], None).unwrap_err();
    assert!(
        matches!(err, CableError::FilterDiverged { step: 1 }),
        "{err}"
    );
    assert_eq!((f.x(), f.sqrt_covariance()), (&x[..], &sq[..]));
    assert_eq!(f.health().steps, 1);
    f.process.failed = false;
    f.step(&[], &[0.2], None).unwrap();
    assert_eq!(f.health().steps, 2);
}

#[test]
fn a_model_measured_all_at_once_gives_the_per_point_filter() {
    let s = SigmaScaling {
        alpha: 0.5,
        beta: 2.0,
        kappa: 0.0,
    };
    let run = |many: bool| {
        let process = LinearProcess::new(2, 0, coupled(2, 0.2), vec![]).unwrap();
        let mut f = SrUkf::new(
            process,
            Square { many },
            &[0.5, 0.1],
            &diag(2, 0.05),
            &diag(2, 1e-4),
            &[1e-3],
            s,
        )
        .unwrap();
        for k in 0..50 {
            f.step(&[], &[0.25 + 0.01 * (k as f64).sin()], None)
                .unwrap();
        }
        (f.x().to_vec(), f.sqrt_covariance().to_vec())
    };
    assert_eq!(run(true), run(false));
}
