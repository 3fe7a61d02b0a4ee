//! criterion benches of network inference (issue #5); budgets in `budgets.toml`, checked by
//! `check_budgets.py`. Python-side figures and the torch/NumPy ratios: `nn_bench.py`.

use std::hint::black_box;

use cable_bench::mlp_fixture;
use criterion::{criterion_group, criterion_main, Criterion, Throughput};

fn single(c: &mut Criterion) {
    let mut g = c.benchmark_group("mlp");
    g.throughput(Throughput::Elements(1));
    for sizes in [&[4usize, 10, 4][..], &[14, 20, 8][..]] {
        let mut m = mlp_fixture(sizes);
        let x: Vec<f64> = (0..sizes[0]).map(|i| 0.1 * i as f64 - 0.3).collect();
        let mut out = vec![0.0; sizes[sizes.len() - 1]];
        let name = format!(
            "forward_{}",
            sizes
                .iter()
                .map(|s| s.to_string())
                .collect::<Vec<_>>()
                .join("_")
        );
        g.bench_function(name, |b| {
            b.iter(|| {
                m.forward(black_box(&x), &mut out).unwrap();
                black_box(&out);
            })
        });
    }
    g.finish();

    let mut g = c.benchmark_group("mlp_batch");
    g.sample_size(20);
    let rows = 1_000_000;
    g.throughput(Throughput::Elements(rows as u64));
    let m = mlp_fixture(&[4, 10, 4]);
    let x: Vec<f64> = (0..rows * 4).map(|i| ((i as f64) * 1e-3).sin()).collect();
    let mut out = vec![0.0; rows * 4];
    g.bench_function("forward_4_10_4_1e6", |b| {
        b.iter(|| {
            m.forward_batch(black_box(&x), &mut out).unwrap();
            black_box(&out);
        })
    });
    g.finish();
}

/// Seed 000's estimator at control rate: the 4-10-4 free-motion network (PSO-BPNN, Table 1)
/// and the joint torque disturbance observer, one sample; and the physics-informed estimator's
/// sample (issue #22: ≤ 1 µs excluding I/O).
fn forceps(c: &mut Criterion) {
    use cable_core::forceps::{Geometry, Jtdo, SEED_THRESHOLD};
    let mut g = c.benchmark_group("forceps");
    g.throughput(Throughput::Elements(1));
    let mut m = mlp_fixture(&[4, 10, 4]);
    let geometry = Geometry {
        r2: 4e-3,
        arm_a: 12e-3,
        arm_b: 14e-3,
    };
    let jtdo = Jtdo::new(geometry, SEED_THRESHOLD, [0.0; 2]).unwrap();
    let motors = [0.5e-3, 0.8e-3, -0.5e-3, -0.8e-3];
    let measured = [12.3, 6.9, 14.2, 5.8];
    let mut free = [0.0; 4];
    g.bench_function("jtdo_step_with_4_10_4", |b| {
        b.iter(|| {
            m.forward(black_box(&motors), &mut free).unwrap();
            black_box(jtdo.estimate(black_box(&measured), &free).unwrap());
        })
    });
    // the physics-informed estimator (issue #22 §2): two direction states, capstan and joint
    // friction, spring and stretch per forceps; alternate motion so the states keep moving
    let mut physics = cable_core::forceps::physics::PhysicsObserver::new(
        geometry,
        [cable_core::forceps::physics::Losses::START; 2],
        SEED_THRESHOLD,
    )
    .unwrap();
    let mut k = 0u32;
    g.bench_function("physics_step", |b| {
        b.iter(|| {
            k = k.wrapping_add(1);
            let x = 1e-3 + 1e-6 * f64::from(k % 64);
            let m = [x, 0.5e-3, x, 0.5e-3];
            black_box(physics.step(black_box(&m), black_box(&measured)).unwrap());
        })
    });
    g.finish();
}

criterion_group!(benches, single, forceps);
criterion_main!(benches);
