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
    drive(c);
}

/// The real-instrument jaw torque model (issue #22 §3) as `cablekit` fits it by default: five
/// Maxwell-slip elements driven by the motor, five by the spindle, the angle-dependent friction;
/// on a run of 1,000 samples at 1 kHz (budget: 1 µs per sample).
fn drive(c: &mut Criterion) {
    use cable_core::forceps::drive::{AngleFriction, DriveModel, DriveRun};
    let n = 4000;
    let t: Vec<f64> = (0..n).map(|k| k as f64 * 1e-3).collect();
    let mut runs = Vec::new();
    for load in [0.01, 0.03, 0.05] {
        let th: Vec<f64> = t.iter().map(|&t| 0.5 * (1.0 - (6.0 * t).cos())).collect();
        let tj: Vec<f64> = th.iter().map(|a| -load - 0.01 * a).collect();
        let ts: Vec<f64> = th
            .iter()
            .zip(&tj)
            .enumerate()
            .map(|(k, (a, j))| 0.02 * a - j + 1e-3 * ((k % 7) as f64))
            .collect();
        // the motor leads the spindle by 15 ms (the compliant coupling)
        let motor: Vec<f64> = t
            .iter()
            .map(|&t| 0.5 * (1.0 - (6.0 * (t + 0.015)).cos()))
            .collect();
        runs.push((th, ts, tj, motor));
    }
    let views: Vec<DriveRun<'_>> = runs
        .iter()
        .map(|(th, ts, tj, motor)| DriveRun {
            spindle_angle: th,
            spindle_torque: ts,
            motor_angle: motor,
            jaw_torque: Some(tj),
            jaw_angle: Some(th),
            dt: 1e-3,
        })
        .collect();
    let travels = [0.1f64, 0.5, 2.0, 8.0, 32.0].map(f64::to_radians);
    let model = DriveModel::fit_with(
        &views,
        None,
        &travels,
        20,
        0.5,
        AngleFriction::FittedRange,
        &travels,
    )
    .unwrap();
    let mut run = views[1];
    run.spindle_angle = &runs[1].0[..1000];
    run.spindle_torque = &runs[1].1[..1000];
    run.motor_angle = &runs[1].3[..1000];
    run.jaw_torque = None;
    run.jaw_angle = None;
    let mut g = c.benchmark_group("forceps");
    g.throughput(Throughput::Elements(1000));
    g.bench_function("drive_estimate_1000", |b| {
        b.iter(|| black_box(model.estimate(black_box(&run)).unwrap()))
    });
    g.finish();
}

criterion_group!(benches, single, forceps);
criterion_main!(benches);
