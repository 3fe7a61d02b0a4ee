//! criterion bench of the square-root UKF (issue #4): predict + update of the Raven-II 3-link
//! transmission (n = 12 states, m = 3 motor encoders), RK4 process model; budget in
//! `budgets.toml`.

use std::hint::black_box;

use cable_bench::raven_fixture;
use cable_core::dynamics::Model;
use cable_core::estimate::{LinearObserve, ModelProcess, Process, SigmaScaling, SrUkf};
use cable_core::integrate::{simulate, InputHold, SimOptions};
use criterion::{criterion_group, criterion_main, Criterion, Throughput};

fn srukf(c: &mut Criterion) {
    let (model, x0, u) = raven_fixture();
    let n = model.n_states();
    let mut g = c.benchmark_group("srukf_raven3");
    g.throughput(Throughput::Elements(1));
    // (filter period, RK4 substeps): 10 kHz with one RK4 step, 1 kHz with Raven's advised 4
    for (label, dt, sub) in [("step_10khz_1rk4", 1e-4, 1), ("step_1khz_4rk4", 1e-3, 4)] {
        // a measured trajectory to filter, cycled
        let steps = 2000;
        let inputs: Vec<f64> = (0..steps)
            .flat_map(|k| {
                let s = (k as f64 * dt * 6.0).sin();
                [u[0] * s, u[1] * s, u[2] * s, 0.0, 0.0, 0.0]
            })
            .collect();
        let opts = SimOptions::new(dt, sub, InputHold::Zoh).expect("valid");
        let traj = simulate(&model, &inputs, &x0, &opts).expect("stable");
        let ys: Vec<[f64; 3]> = (0..steps)
            .map(|k| {
                let s = &traj.states[k * n..(k + 1) * n];
                [s[0], s[4], s[8]]
            })
            .collect();
        let p0: Vec<f64> = (0..n * n)
            .map(|k| if k % (n + 1) == 0 { 1e-6 } else { 0.0 })
            .collect();
        let q: Vec<f64> = p0.iter().map(|v| v * 1e-3).collect();
        let r: Vec<f64> = (0..9)
            .map(|k| if k % 4 == 0 { 1e-8 } else { 0.0 })
            .collect();
        let process = ModelProcess::new(model.clone(), dt, sub).expect("valid");
        let observe = LinearObserve::select(n, &[0, 4, 8]).expect("valid");
        let mut f =
            SrUkf::new(process, observe, &x0, &p0, &q, &r, SigmaScaling::default()).expect("valid");
        let mut k = 0usize;
        g.bench_function(label, |b| {
            b.iter(|| {
                let i = k % steps;
                f.step(
                    black_box(&inputs[i * 6..(i + 1) * 6]),
                    black_box(&ys[i]),
                    None,
                )
                .expect("finite");
                k += 1;
                if i == steps - 1 {
                    f.reset(&x0, &p0).expect("valid");
                }
                black_box(f.x());
            })
        });
    }
    // the filter's own arithmetic: the same sizes with a linear process
    let a: Vec<f64> = (0..n * n)
        .map(|k| if k % (n + 1) == 0 { 0.999 } else { 1e-4 })
        .collect();
    let process = cable_core::estimate::LinearProcess::new(n, 0, a, vec![]).expect("valid");
    let observe = LinearObserve::select(n, &[0, 4, 8]).expect("valid");
    let eye: Vec<f64> = (0..n * n)
        .map(|k| if k % (n + 1) == 0 { 1e-6 } else { 0.0 })
        .collect();
    let r: Vec<f64> = (0..9)
        .map(|k| if k % 4 == 0 { 1e-8 } else { 0.0 })
        .collect();
    let q: Vec<f64> = eye.iter().map(|v| v * 1e-3).collect();
    let mut f =
        SrUkf::new(process, observe, &x0, &eye, &q, &r, SigmaScaling::default()).expect("valid");
    let mut k = 0u32;
    g.bench_function("step_linear_process", |b| {
        b.iter(|| {
            k = k.wrapping_add(1);
            let y = [x0[0] + 1e-4 * f64::from(k % 7), x0[4], x0[8]];
            f.step(&[], black_box(&y), None).expect("finite");
            black_box(f.x());
        })
    });
    // the time update's propagation alone: 25 sigma points through one RK4 step, four at a
    // time in SIMD lanes (what the filter does) vs one at a time
    let (model, x0, u) = raven_fixture();
    let mut process = ModelProcess::new(model, 1e-4, 1).expect("valid");
    let points: Vec<f64> = (0..2 * n + 1)
        .flat_map(|i| x0.iter().map(move |v| v + 1e-6 * i as f64))
        .collect();
    let mut work = points.clone();
    g.bench_function("propagate_25_lanes", |b| {
        b.iter(|| {
            work.copy_from_slice(&points);
            process.propagate_many(black_box(&mut work), &u);
            black_box(&work);
        })
    });
    g.bench_function("propagate_25_one_by_one", |b| {
        b.iter(|| {
            work.copy_from_slice(&points);
            for x in work.chunks_exact_mut(n) {
                process.propagate(black_box(x), &u);
            }
            black_box(&work);
        })
    });
    // the two square-root kernels alone at the filter's sizes: the LQ factor of the time
    // update's compound (12 × 36, triangular tail) and the rank-3 downdate of eq 3.25
    {
        use cable_core::estimate::linalg::{cholupdate_columns, lq_lower, padded};
        let n = 12;
        let cols = 36;
        let ld = padded(n);
        let base: Vec<f64> = (0..ld * cols)
            .map(|k| {
                if k % ld < n {
                    ((k * 7 + 3) % 11) as f64 - 5.0 + 0.01 * k as f64
                } else {
                    0.0
                }
            })
            .collect();
        let mut work = base.clone();
        let mut v = vec![0.0; ld];
        let mut l = vec![0.0; n * n];
        g.bench_function("lq_12x36", |b| {
            b.iter(|| {
                work.copy_from_slice(&base);
                lq_lower(black_box(&mut work), n, cols, 24, &mut v, &mut l);
                black_box(&l);
            })
        });
        let mut l0 = vec![0.0; n * n];
        for i in 0..n {
            l0[i * (n + 1)] = 10.0;
        }
        let vs: Vec<f64> = (0..n * 3).map(|k| 0.1 * (k as f64).sin()).collect();
        let mut w = vs.clone();
        g.bench_function("downdate3_12", |b| {
            b.iter(|| {
                l.copy_from_slice(&l0);
                w.copy_from_slice(&vs);
                cholupdate_columns(black_box(&mut l), n, &mut w, n, 3, -1.0).unwrap();
                black_box(&l);
            })
        });
    }
    g.finish();
}

criterion_group!(benches, srukf);
criterion_main!(benches);
