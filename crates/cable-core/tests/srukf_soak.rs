//! Long soak of the square-root UKF (issue #4): 10⁷ steps of the 12-state Raven-II filter with
//! random excitation. Not in the default test run; run it with
//! `cargo test --release -p cable-core --test srukf_soak -- --ignored --nocapture`
//! (`SOAK_STEPS` overrides the step count).

use std::time::Instant;

use cable_core::dynamics::{raven2, Model};
use cable_core::estimate::{LinearObserve, ModelProcess, SigmaScaling, SrUkf};
use cable_core::integrate::Rk4;

/// xorshift64*: deterministic random numbers without a dependency.
struct Rng(u64);
impl Rng {
    fn uniform(&mut self) -> f64 {
        self.0 ^= self.0 >> 12;
        self.0 ^= self.0 << 25;
        self.0 ^= self.0 >> 27;
        (self.0.wrapping_mul(0x2545_F491_4F6C_DD1D) >> 11) as f64 / (1u64 << 53) as f64
    }
    fn normal(&mut self) -> f64 {
        let (u, v) = (self.uniform().max(1e-300), self.uniform());
        (-2.0 * u.ln()).sqrt() * (2.0 * std::f64::consts::PI * v).cos()
    }
}

#[test]
#[ignore = "10⁷ steps: a soak, run explicitly"]
fn ten_million_steps_without_recovery_or_nan() {
    let steps: usize = std::env::var("SOAK_STEPS")
        .ok()
        .and_then(|s| s.parse().ok())
        .unwrap_or(10_000_000);
    let model = raven2(3).expect("shipped parameters");
    let n = model.n_states();
    let dt = 1e-4;
    let p0: Vec<f64> = (0..n * n)
        .map(|k| if k % (n + 1) == 0 { 1e-6 } else { 0.0 })
        .collect();
    let q: Vec<f64> = (0..n * n)
        .map(|k| {
            if k % (n + 1) == 0 {
                [0.0, 1e-4, 0.0, 1e-4][(k / (n + 1)) % 4] * dt
            } else {
                0.0
            }
        })
        .collect();
    let sigma = 5e-5;
    let r: Vec<f64> = (0..9)
        .map(|k| if k % 4 == 0 { sigma * sigma } else { 0.0 })
        .collect();
    let mut f = SrUkf::new(
        ModelProcess::new(model.clone(), dt, 1).expect("valid"),
        LinearObserve::select(n, &[0, 4, 8]).expect("valid"),
        &vec![0.0; n],
        &p0,
        &q,
        &r,
        SigmaScaling {
            alpha: 0.5,
            beta: 2.0,
            kappa: 0.0,
        },
    )
    .expect("valid");
    // the "robot": the same model driven by random torques (a filtered random walk)
    let mut rng = Rng(0x9E37_79B9_7F4A_7C15);
    let mut x = vec![0.0; n];
    let mut ws = Rk4::for_model(&model);
    let mut u = [0.0; 6];
    let mut worst_nis = 0.0_f64;
    let mut nis_sum = 0.0;
    let t0 = Instant::now();
    let mut slowest_million = 0.0_f64;
    let mut chunk = Instant::now();
    for k in 0..steps {
        for (i, ui) in u.iter_mut().take(3).enumerate() {
            // mean-reverting torque around ±0.05 N·m keeps the axes inside their range
            let pull = -0.5 * x[4 * i] / [136.0, 121.0, 2158.0][i];
            *ui = 0.999 * *ui + 0.002 * rng.normal() + 1e-3 * pull;
        }
        ws.step(&model, &mut x, &u, dt);
        let y = [
            x[0] + sigma * rng.normal(),
            x[4] + sigma * rng.normal(),
            x[8] + sigma * rng.normal(),
        ];
        f.step(&u, &y, None).expect("the filter stays finite");
        let h = f.health();
        assert_eq!(h.recoveries_total, 0, "downdate recovery at step {k}");
        assert!(
            f.x().iter().all(|v| v.is_finite()),
            "non-finite state at step {k}"
        );
        worst_nis = worst_nis.max(h.nis);
        nis_sum += h.nis;
        if (k + 1) % 1_000_000 == 0 {
            slowest_million = slowest_million.max(chunk.elapsed().as_secs_f64());
            chunk = Instant::now();
        }
    }
    let total = t0.elapsed().as_secs_f64();
    let mean_nis = nis_sum / steps as f64;
    println!(
        "soak: {steps} steps in {total:.1} s ({:.2} µs/step), slowest million {slowest_million:.2} s, \
         mean NIS {mean_nis:.3} (3 channels), worst NIS {worst_nis:.1}, recoveries 0",
        1e6 * total / steps as f64
    );
    assert!((2.0..4.0).contains(&mean_nis), "mean NIS {mean_nis}");
}
