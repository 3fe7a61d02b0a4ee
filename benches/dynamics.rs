//! criterion benches of the dynamics surface; budgets in `budgets.toml`, checked by
//! `check_budgets.py`.

use std::hint::black_box;

use cable_bench::raven_fixture;
use cable_core::dynamics::Model;
use cable_core::integrate::{simulate, InputHold, Rk4, SimOptions};
use criterion::{criterion_group, criterion_main, Criterion, Throughput};

fn dynamics(c: &mut Criterion) {
    let (model, x, u) = raven_fixture();
    let mut g = c.benchmark_group("raven3");
    g.throughput(Throughput::Elements(1));
    let mut dx = vec![0.0; model.n_states()];
    g.bench_function("derivative", |b| {
        b.iter(|| {
            model.derivative(black_box(&x), black_box(&u), &mut dx);
            black_box(&dx);
        })
    });
    let mut ws = Rk4::for_model(&model);
    let mut xs = x.clone();
    g.bench_function("rk4_step", |b| {
        b.iter(|| {
            xs.copy_from_slice(&x);
            ws.step(&model, black_box(&mut xs), black_box(&u), black_box(1e-4));
            black_box(&xs);
        })
    });
    g.finish();

    let mut g = c.benchmark_group("raven3_trajectory");
    let steps = 100_000;
    let inputs: Vec<f64> = (0..steps)
        .flat_map(|k| {
            let s = (k as f64 * 1e-4 * 6.0).sin();
            [0.1 * s, 0.05 * s, 0.2 * s, 0.0, 0.0, 0.0]
        })
        .collect();
    let opts = SimOptions::new(1e-4, 1, InputHold::Zoh).expect("valid");
    g.throughput(Throughput::Elements(steps as u64));
    g.sample_size(20);
    g.bench_function("simulate_100k", |b| {
        b.iter(|| black_box(simulate(&model, black_box(&inputs), &x, &opts).expect("stable")))
    });
    g.finish();
}

criterion_group!(benches, dynamics);
criterion_main!(benches);
