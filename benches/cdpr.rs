//! criterion benches of the CDPR kinematics and tension distribution (issue #21) on the
//! IPAnema-like robot; budgets in `budgets.toml`. Python-side peers (NumPy closed form, scipy
//! HiGHS LP, quadprog QP) and the ratios: `cdpr_bench.py`.

use std::hint::black_box;

use cable_bench::ipanema_fixture;
use cable_core::cdpr::winch::Winch;
use cable_core::cdpr::{
    capacity_batch, capacity_margin, distribute_batch, improved_closed_form, inverse_kinematics,
    CableGeometry, CapacityMut, Distributor, Margins, Method, Pose, Requirement, TensionsMut,
};
use cable_core::control::{closed_loop, LoopOptions};
use cable_core::dynamics::{CdprPlant, Model, PlantOptions};
use criterion::{criterion_group, criterion_main, Criterion, Throughput};

fn per_pose(c: &mut Criterion) {
    let (robot, poses) = ipanema_fixture(64);
    let (n, m) = (6, 8);
    let lo = [10.0; 8];
    let hi = [3000.0; 8];
    // structure matrices and wrenches of the poses, computed once
    let mut cases = Vec::new();
    for q in poses.chunks(n) {
        let pose = Pose::from_coordinates(robot.motion, q).unwrap();
        let mut g = CableGeometry::default();
        inverse_kinematics(&robot, &pose, &mut g).unwrap();
        let mut w = [0.0; 6];
        robot.gravity_wrench(&pose.rotation, &mut w);
        cases.push((g.structure().to_vec(), w));
    }
    let mut g = c.benchmark_group("cdpr");
    g.throughput(Throughput::Elements(1));
    g.bench_function("ik_8x6", |b| {
        let mut geo = CableGeometry::default();
        let mut k = 0;
        b.iter(|| {
            k = (k + 1) % 64;
            let pose = Pose::from_coordinates(robot.motion, &poses[k * n..(k + 1) * n]).unwrap();
            inverse_kinematics(&robot, black_box(&pose), &mut geo).unwrap();
            black_box(&geo.length);
        })
    });
    g.bench_function("improved_cfm_8x6", |b| {
        let mut k = 0;
        b.iter(|| {
            k = (k + 1) % 64;
            let (at, w) = &cases[k];
            black_box(improved_closed_form(black_box(at), n, m, w, &lo, &hi).unwrap());
        })
    });
    g.bench_function("capacity_margin_8x6", |b| {
        let mut k = 0;
        let req = Requirement::default();
        b.iter(|| {
            k = (k + 1) % 64;
            let (at, w) = &cases[k];
            black_box(capacity_margin(black_box(at), n, m, &lo, &hi, w, &req).unwrap());
        })
    });
    g.bench_function("qp_cold_8x6", |b| {
        let mut k = 0;
        b.iter(|| {
            k = (k + 1) % 64;
            let (at, w) = &cases[k];
            let mut d = Distributor::new(n, m, None).unwrap();
            black_box(
                d.distribute(black_box(at), w, &lo, &hi, Method::Qp)
                    .unwrap(),
            );
        })
    });
    g.bench_function("qp_warm_8x6", |b| {
        let mut d = Distributor::new(n, m, None).unwrap();
        let mut k = 0;
        b.iter(|| {
            k = (k + 1) % 64;
            let (at, w) = &cases[k];
            black_box(
                d.distribute(black_box(at), w, &lo, &hi, Method::Qp)
                    .unwrap(),
            );
        })
    });
    // a trajectory: 1,000 neighbouring poses on a diagonal through the frame with a 1,500 N
    // side load (every pose feasible; cables reach their bounds on 10 % of them): the warm face
    // answers most poses without an interior-point solve
    let path: Vec<(Vec<f64>, [f64; 6])> = (0..1000)
        .map(|k| {
            let s = k as f64 / 999.0;
            let q = [
                -0.8 + 1.6 * s,
                -0.6 + 1.2 * s,
                1.0 + s,
                0.05,
                -0.05,
                0.1 * s,
            ];
            let pose = Pose::from_coordinates(robot.motion, &q).unwrap();
            let mut geo = CableGeometry::default();
            inverse_kinematics(&robot, &pose, &mut geo).unwrap();
            let mut w = [0.0; 6];
            robot.gravity_wrench(&pose.rotation, &mut w);
            w[0] += 1500.0;
            (geo.structure().to_vec(), w)
        })
        .collect();
    g.bench_function("qp_trajectory_8x6", |b| {
        let mut d = Distributor::new(n, m, None).unwrap();
        let mut k = 0;
        b.iter(|| {
            k = (k + 1) % path.len();
            let (at, w) = &path[k];
            black_box(
                d.distribute(black_box(at), w, &lo, &hi, Method::Qp)
                    .unwrap(),
            );
        })
    });
    g.finish();
}

fn batch(c: &mut Criterion) {
    let t = 125_000;
    let (robot, poses) = ipanema_fixture(t);
    let mut g = c.benchmark_group("cdpr_batch");
    g.sample_size(10);
    g.throughput(Throughput::Elements(t as u64));
    let (mut f, mut method, mut feasible, mut residual) = (
        vec![0.0; t * 8],
        vec![Method::Auto; t],
        vec![false; t],
        vec![0.0; t],
    );
    g.bench_function("distribute_auto_125k", |b| {
        b.iter(|| {
            let out = TensionsMut {
                f: &mut f,
                method: &mut method,
                feasible: &mut feasible,
                residual: &mut residual,
            };
            distribute_batch(&robot, black_box(&poses), None, true, Method::Auto, out).unwrap();
            black_box(&feasible);
        })
    });
    // the workspace: a 50 x 50 x 50 grid over the frame at a fixed orientation
    let k = 50;
    let grid: Vec<f64> = (0..t)
        .flat_map(|i| {
            let (a, b, c) = (i % k, (i / k) % k, i / (k * k));
            let at = |j: usize, half: f64| -half + 2.0 * half * j as f64 / (k - 1) as f64;
            [
                at(a, 1.9),
                at(b, 1.4),
                0.05 + 2.9 * c as f64 / (k - 1) as f64,
                0.0,
                0.0,
                0.1,
            ]
        })
        .collect();
    let (mut margin, mut degenerate, mut weakest) =
        (vec![0.0; t], vec![false; t], vec![0.0; 6 * t]);
    let boxed = Requirement {
        half_width: [20.0, 20.0, 20.0, 2.0, 2.0, 2.0],
        ..Requirement::default()
    };
    let inside = Requirement {
        margins: Margins::Inside,
        ..Requirement::default()
    };
    for (name, req) in [
        ("workspace_static_125k", Requirement::default()),
        ("workspace_static_inside_125k", inside),
        ("workspace_wrench_box_125k", boxed),
    ] {
        g.bench_function(name, |b| {
            b.iter(|| {
                let out = CapacityMut {
                    margin: &mut margin,
                    feasible: &mut feasible,
                    degenerate: &mut degenerate,
                    weakest: &mut weakest,
                };
                capacity_batch(&robot, black_box(&grid), &req, out).unwrap();
                black_box(&margin);
            })
        });
    }
    g.finish();
}

/// The robot as a plant (issue #23): one derivative of the 60-state model, and one controller
/// period of the closed loop (distribution, lengths and currents, five RK4 steps), 8 cables.
fn plant(c: &mut Criterion) {
    let (robot, poses) = ipanema_fixture(64);
    let home = &poses[..6];
    let plant = CdprPlant::new(&robot, Winch::seed003(), home, PlantOptions::default()).unwrap();
    let mut g = c.benchmark_group("cdpr_plant");
    g.bench_function("derivative_8x6", |b| {
        let x = plant.rest_state();
        let u = vec![0.0; plant.n_inputs()];
        let mut dx = vec![0.0; plant.n_states()];
        b.iter(|| {
            plant.derivative(black_box(&x), &u, &mut dx);
            black_box(&dx);
        })
    });
    // 1,000 periods holding the home pose, timed per period
    let held: Vec<f64> = home.iter().copied().cycle().take(6 * 1000).collect();
    g.throughput(Throughput::Elements(1000));
    g.bench_function("closed_loop_1000_periods_8x6", |b| {
        let opts = LoopOptions::new(1e-3);
        b.iter(|| {
            black_box(closed_loop(&plant, black_box(&held), &opts, None, None, None).unwrap())
        })
    });
    g.finish();
}

criterion_group!(benches, per_pose, batch, plant);
criterion_main!(benches);
