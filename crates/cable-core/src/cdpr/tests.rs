use super::*;

/// An 8-cable spatial robot (the seed-002 frame): anchors at the corners of the frame, each
/// attached to the platform corner below (top anchors) or above (bottom anchors) it.
pub(crate) fn box_robot(pulleys: bool) -> Robot {
    let (fx, fy, fz) = (0.55, 0.40, 0.475);
    let p = 0.05;
    let corners = [(-1.0, -1.0), (1.0, -1.0), (1.0, 1.0), (-1.0, 1.0)];
    let mut cables = Vec::new();
    for z in [-1.0, 1.0] {
        for &(sx, sy) in &corners {
            cables.push(Cable {
                anchor: [sx * fx, sy * fy, z * fz],
                attachment: [sx * p, sy * p, -z * p],
                f_min: 1.0,
                f_max: 50.0,
                ea: 1e5,
                pulley: pulleys.then_some(Pulley {
                    radius: 0.02,
                    axis: [0.0, 0.0, z],
                }),
            });
        }
    }
    let platform = Platform {
        mass: 1.42,
        com: [0.0, 0.0, -0.01],
        inertia: [1e-3, 0.0, 0.0, 0.0, 1e-3, 0.0, 0.0, 0.0, 2e-3],
    };
    Robot::new(
        "box",
        Motion::Spatial,
        cables,
        platform,
        [0.0, 0.0, -9.80665],
    )
    .unwrap()
}

pub(crate) fn planar_robot() -> Robot {
    let (w, h) = (1.0, 0.8);
    let anchors = [[0.0, h], [w, h], [0.0, 0.0], [w, 0.0]];
    let attach = [[-0.05, 0.05], [0.05, 0.05], [-0.05, -0.05], [0.05, -0.05]];
    let cables = anchors
        .iter()
        .zip(attach)
        .map(|(a, b)| Cable {
            anchor: [a[0], a[1], 0.0],
            attachment: [b[0], b[1], 0.0],
            f_min: 2.0,
            f_max: 100.0,
            ea: 48.9e9 * 1.89e-6,
            pulley: None,
        })
        .collect();
    let platform = Platform {
        mass: 0.5,
        com: [0.0; 3],
        inertia: [0.0, 0.0, 0.0, 0.0, 0.0, 0.0, 0.0, 0.0, 1e-4],
    };
    Robot::new(
        "planar",
        Motion::Planar,
        cables,
        platform,
        [0.0, -9.80665, 0.0],
    )
    .unwrap()
}

fn ik(robot: &Robot, q: &[f64]) -> CableGeometry {
    let mut g = CableGeometry::default();
    inverse_kinematics(
        robot,
        &Pose::from_coordinates(robot.motion, q).unwrap(),
        &mut g,
    )
    .unwrap();
    g
}

/// The structure matrix is minus the Jacobian of the lengths with respect to world-frame
/// translation and rotation increments (with or without pulleys).
#[test]
fn structure_matrix_is_minus_the_length_jacobian() {
    for (robot, q) in [
        (box_robot(false), vec![0.05, -0.03, 0.02, 0.1, -0.05, 0.2]),
        (box_robot(true), vec![0.05, -0.03, 0.02, 0.1, -0.05, 0.2]),
        (planar_robot(), vec![0.45, 0.35, 0.2]),
    ] {
        let (n, m) = (robot.dof(), robot.n_cables());
        let g = ik(&robot, &q);
        let pose = Pose::from_coordinates(robot.motion, &q).unwrap();
        let h = 1e-6;
        for a in 0..n {
            let mut d = [0.0; 6];
            d[a] = h;
            let (mut gp, mut gm) = (CableGeometry::default(), CableGeometry::default());
            inverse_kinematics(
                &robot,
                &super::kinematics::step(robot.motion, &pose, &d),
                &mut gp,
            )
            .unwrap();
            d[a] = -h;
            inverse_kinematics(
                &robot,
                &super::kinematics::step(robot.motion, &pose, &d),
                &mut gm,
            )
            .unwrap();
            for i in 0..m {
                let fd = (gp.length[i] - gm.length[i]) / (2.0 * h);
                let at = g.structure()[a * m + i];
                assert!(
                    (fd + at).abs() < 1e-7,
                    "{} dof {a} cable {i}: {fd} vs {}",
                    robot.name,
                    -at
                );
            }
        }
    }
}

#[test]
fn pulley_exit_points_lie_on_the_pulley_and_the_cable_leaves_tangentially() {
    let robot = box_robot(true);
    let g = ik(&robot, &[0.1, 0.05, -0.1, 0.0, 0.0, 0.3]);
    for (i, c) in robot.cables.iter().enumerate() {
        let p = c.pulley.unwrap();
        let e = g.exit[i];
        let u = g.direction[i];
        // the pulley centre is the exit point plus r along the inward normal; it lies at
        // distance r from the anchor, perpendicular to the axis
        let k = p.axis;
        let rad = [e[0] - c.anchor[0], e[1] - c.anchor[1], e[2] - c.anchor[2]];
        let along: f64 = rad.iter().zip(&k).map(|(a, b)| a * b).sum();
        assert!(g.wrap[i] > 0.0 && g.wrap[i] < std::f64::consts::TAU);
        assert!(
            along.abs() <= p.radius * (1.0 + 1e-9),
            "cable {i}: exit off the pulley"
        );
        // tangency: the free cable is perpendicular to the radius at the exit point
        let perp = [
            rad[0] - along * k[0],
            rad[1] - along * k[1],
            rad[2] - along * k[2],
        ];
        let norm = perp.iter().map(|v| v * v).sum::<f64>().sqrt();
        let e_r = perp.map(|v| v / norm);
        let centre = [0, 1, 2].map(|j| c.anchor[j] + p.radius * e_r[j]);
        let to_exit = [0, 1, 2].map(|j| e[j] - centre[j]);
        let r_exit = to_exit.iter().map(|v| v * v).sum::<f64>().sqrt();
        assert!((r_exit - p.radius).abs() < 1e-12, "cable {i}: {r_exit}");
        let dot: f64 = to_exit.iter().zip(&u).map(|(a, b)| a * b).sum();
        assert!(dot.abs() < 1e-9, "cable {i}: not tangent ({dot})");
        assert!(g.length[i] > g.free_length[i]);
    }
}

#[test]
fn forward_kinematics_recovers_the_pose_from_its_lengths() {
    for (robot, q, seed) in [
        (
            box_robot(false),
            vec![0.1, -0.05, 0.08, 0.15, -0.1, 0.25],
            vec![0.0; 6],
        ),
        (
            box_robot(true),
            vec![-0.1, 0.05, -0.08, -0.1, 0.1, -0.2],
            vec![0.0; 6],
        ),
        (planar_robot(), vec![0.3, 0.5, -0.3], vec![0.35, 0.45, -0.1]),
    ] {
        let g = ik(&robot, &q);
        let fk = forward_kinematics(&robot, &g.length[..robot.n_cables()], &seed, 1e-12).unwrap();
        assert!(fk.converged, "{}: {fk:?}", robot.name);
        for (a, b) in fk.pose.iter().zip(&q) {
            assert!(
                (a - b).abs() < 1e-8,
                "{}: {:?} vs {q:?}",
                robot.name,
                fk.pose
            );
        }
    }
}

#[test]
fn distributions_hold_the_wrench_and_the_improved_method_respects_the_bounds() {
    let robot = box_robot(false);
    let (n, m) = (6, 8);
    let lo = [1.0; 8];
    let hi = [50.0; 8];
    let mut repaired = 0;
    // poses checked feasible by an exact LP (scipy HiGHS); the third needs the improvement
    let poses = [
        [0.0; 6],
        [0.2, 0.1, -0.15, 0.05, 0.03, -0.1],
        [0.3, 0.2, 0.3, 0.0, 0.0, 0.0],
        [0.1, -0.05, 0.08, 0.05, -0.05, 0.1],
    ];
    for (k, q) in poses.iter().enumerate() {
        let g = ik(&robot, q);
        let pose = Pose::from_coordinates(robot.motion, q).unwrap();
        let mut w = [0.0; 6];
        robot.gravity_wrench(&pose.rotation, &mut w);
        let at = g.structure();
        let mn = minimum_norm(at, n, m, &w).unwrap();
        assert!(mn.residual < 1e-9, "pose {k}");
        let cf = closed_form(at, n, m, &w, &lo, &hi).unwrap();
        assert!(cf.residual < 1e-9);
        let icf = improved_closed_form(at, n, m, &w, &lo, &hi).unwrap();
        assert!(icf.residual < 1e-9 && icf.feasible, "pose {k}: {icf:?}");
        for (i, f) in icf.tensions().iter().enumerate() {
            assert!(*f >= lo[i] - 1e-9 && *f <= hi[i] + 1e-9);
        }
        if cf.feasible {
            assert_eq!(
                cf.tensions(),
                icf.tensions(),
                "the closed form is the first step"
            );
        } else {
            repaired += 1;
        }
    }
    assert_eq!(
        repaired, 1,
        "the third pose's closed form has a slack cable"
    );
    let g = ik(&robot, &[0.0; 6]);
    // a wrench beyond every cable's reach is flagged, not clamped
    let huge = [0.0, 0.0, -1e4, 0.0, 0.0, 0.0];
    let icf = improved_closed_form(g.structure(), n, m, &huge, &lo, &hi).unwrap();
    assert!(!icf.feasible);
    assert!(
        icf.residual < 1e-6 * 1e4,
        "the equilibrium still holds: {}",
        icf.residual
    );
}

#[test]
fn degenerate_geometry_and_bad_bounds_are_named_errors() {
    // all cables in one plane through the platform: no moment about the plane's normal axes
    let at = [1.0, 0.0, -1.0, 0.0, 0.0, 1.0, 0.0, -1.0, 0.0, 0.0, 0.0, 0.0];
    let err = minimum_norm(&at, 3, 4, &[0.0, 0.0, 1.0]).unwrap_err();
    assert!(err.to_string().contains("full row rank"), "{err}");
    let g = ik(&planar_robot(), &[0.5, 0.4, 0.0]);
    let err = closed_form(g.structure(), 3, 4, &[0.0; 3], &[5.0; 4], &[1.0; 4]).unwrap_err();
    assert!(err.to_string().contains("f_max[0]"), "{err}");
    let err = closed_form(
        g.structure(),
        3,
        4,
        &[f64::NAN, 0.0, 0.0],
        &[0.0; 4],
        &[1.0; 4],
    )
    .unwrap_err();
    assert!(matches!(err, CableError::NotFinite { .. }), "{err}");
    let mut cables = planar_robot().cables;
    cables[1].f_min = -1.0;
    let p = planar_robot().platform;
    let err = Robot::new("x", Motion::Planar, cables, p, [0.0; 3]).unwrap_err();
    assert!(err.to_string().contains("cables[1].f_min"), "{err}");
    // a finite mass whose weight overflows (issue #38: gravity_wrench returned inf)
    let r = planar_robot();
    let mut heavy = r.platform;
    heavy.mass = 1e308;
    let err = Robot::new(
        "x",
        Motion::Planar,
        r.cables.clone(),
        heavy,
        [0.0, -9.80665, 0.0],
    )
    .unwrap_err();
    assert!(err.to_string().contains("platform.mass"), "{err}");
}

use crate::error::CableError;

/// `feasible` means equilibrium and the bounds for every method (issue #38): the minimum-norm
/// tensions, which ignore the bounds, are feasible only where they happen to respect them.
#[test]
fn minimum_norm_is_feasible_only_within_the_bounds() {
    let robot = box_robot(false);
    let g = ik(&robot, &[0.0; 6]);
    let pose = Pose::from_coordinates(robot.motion, &[0.0; 6]).unwrap();
    let mut w = [0.0; 6];
    robot.gravity_wrench(&pose.rotation, &mut w);
    let mut d = Distributor::new(6, 8, None).unwrap();
    let free = d
        .distribute(g.structure(), &w, &[0.0; 8], &[1e3; 8], Method::MinimumNorm)
        .unwrap();
    let within = free.tensions().iter().all(|&f| (0.0..=1e3).contains(&f));
    assert!(free.residual <= 1e-9, "{free:?}");
    assert_eq!(free.feasible, within, "{free:?}");
    // bounds every one of the same tensions violates: equilibrium holds, feasibility does not
    let lo = free.tensions().iter().fold(0.0, |a: f64, &b| a.max(b)) + 1.0;
    let tight = d
        .distribute(
            g.structure(),
            &w,
            &[lo; 8],
            &[lo + 1e3; 8],
            Method::MinimumNorm,
        )
        .unwrap();
    assert!(!tight.feasible && tight.residual <= 1e-9, "{tight:?}");
    assert_eq!(tight.tensions(), free.tensions());
}

/// Where the closed form is feasible it is the QP's optimum (same objective, no active bound):
/// the QP must agree; where it is not, the QP's answer holds the wrench within the bounds
/// exactly; warm solves give the cold answers; an impossible wrench is flagged with the least
/// wrench error, within the bounds.
#[test]
fn the_qp_agrees_with_the_closed_form_and_stays_feasible() {
    let robot = box_robot(false);
    let (n, m) = (6, 8);
    let (lo, hi) = ([1.0; 8], [50.0; 8]);
    let mut warm = Distributor::new(n, m, None).unwrap();
    let poses = [
        [0.0; 6],
        [0.2, 0.1, -0.15, 0.05, 0.03, -0.1],
        [0.3, 0.2, 0.3, 0.0, 0.0, 0.0],
        [0.1, -0.05, 0.08, 0.05, -0.05, 0.1],
    ];
    for q in &poses {
        let g = ik(&robot, q);
        let pose = Pose::from_coordinates(robot.motion, q).unwrap();
        let mut w = [0.0; 6];
        robot.gravity_wrench(&pose.rotation, &mut w);
        let d = warm
            .distribute(g.structure(), &w, &lo, &hi, Method::Qp)
            .unwrap();
        assert!(d.feasible && d.method == Method::Qp, "{d:?}");
        assert!(d.residual <= 1e-9, "{}", d.residual);
        assert!(d.tensions().iter().all(|f| (1.0..=50.0).contains(f)));
        let cold = Distributor::new(n, m, None)
            .unwrap()
            .distribute(g.structure(), &w, &lo, &hi, Method::Qp)
            .unwrap();
        for (a, b) in d.tensions().iter().zip(cold.tensions()) {
            assert!((a - b).abs() < 1e-7, "warm {a} vs cold {b}");
        }
        let cf = closed_form(g.structure(), n, m, &w, &lo, &hi).unwrap();
        if cf.feasible {
            for (a, b) in d.tensions().iter().zip(cf.tensions()) {
                assert!((a - b).abs() < 1e-6, "qp {a} vs closed form {b}");
            }
        }
        let auto = warm
            .distribute(g.structure(), &w, &lo, &hi, Method::Auto)
            .unwrap();
        assert!(auto.feasible && auto.method == Method::ImprovedClosedForm);
    }
    assert!(warm.is_warm());
    assert_eq!(
        warm.solves + warm.warm_hits,
        4,
        "auto answered by the closed form"
    );
    assert!(
        warm.warm_hits >= 1,
        "neighbouring poses share the all-free face"
    );
    let g = ik(&robot, &[0.0; 6]);
    let huge = [0.0, 0.0, -1e4, 0.0, 0.0, 0.0];
    let d = warm
        .distribute(g.structure(), &huge, &lo, &hi, Method::Auto)
        .unwrap();
    assert!(!d.feasible && d.method == Method::LeastWrenchError, "{d:?}");
    assert!(d.tensions().iter().all(|f| (1.0..=50.0).contains(f)));
    // the least error pulls the platform up as hard as the bounds allow: the upper cables
    // (the last four, anchored above) at their maximum
    assert!(
        d.tensions()[4..].iter().all(|f| *f > 49.0),
        "{:?}",
        d.tensions()
    );
}

/// Neighbouring poses of a trajectory share their face: the warm start answers them without an
/// interior-point solve, with the same tensions a cold solve gives.
#[test]
fn warm_faces_answer_a_trajectory_without_interior_point_solves() {
    let robot = box_robot(false);
    let (lo, hi) = ([1.0; 8], [50.0; 8]);
    let mut d = Distributor::new(6, 8, None).unwrap();
    let mut feasible = 0;
    for k in 0..500 {
        let s = k as f64 / 499.0;
        let q = [
            -0.2 + 0.4 * s,
            -0.15 + 0.3 * s,
            -0.1 + 0.2 * s,
            0.02,
            -0.02,
            0.05 * s,
        ];
        let g = ik(&robot, &q);
        let pose = Pose::from_coordinates(robot.motion, &q).unwrap();
        let mut w = [0.0; 6];
        robot.gravity_wrench(&pose.rotation, &mut w);
        w[0] += 8.0;
        let r = d
            .distribute(g.structure(), &w, &lo, &hi, Method::Qp)
            .unwrap();
        feasible += usize::from(r.feasible);
        if k % 97 == 0 {
            let mut cold = Distributor::new(6, 8, None).unwrap();
            let c = cold
                .distribute(g.structure(), &w, &lo, &hi, Method::Qp)
                .unwrap();
            for (a, b) in r.tensions().iter().zip(c.tensions()) {
                assert!((a - b).abs() < 1e-9, "warm {a} vs cold {b}");
            }
        }
    }
    assert_eq!(feasible, 500);
    assert!(
        d.solves <= 5 && d.warm_hits >= 495,
        "{} solves, {} warm",
        d.solves,
        d.warm_hits
    );
}

/// A small deterministic generator for test poses (xorshift).
struct Rng(u64);

impl Rng {
    fn uniform(&mut self, lo: f64, hi: f64) -> f64 {
        self.0 ^= self.0 << 13;
        self.0 ^= self.0 >> 7;
        self.0 ^= self.0 << 17;
        lo + (hi - lo) * ((self.0 >> 11) as f64 / (1u64 << 53) as f64)
    }
}

fn holds(robot: &Robot, q: &[f64], w: &[f64]) -> bool {
    let (n, m) = (robot.dof(), robot.n_cables());
    let lo: Vec<f64> = robot.cables.iter().map(|c| c.f_min).collect();
    let hi: Vec<f64> = robot.cables.iter().map(|c| c.f_max).collect();
    let g = ik(robot, q);
    Distributor::new(n, m, None)
        .unwrap()
        .distribute(g.structure(), w, &lo, &hi, Method::Qp)
        .unwrap()
        .feasible
}

/// The capacity margin's sign is the QP's feasibility; inside, every wrench within the margin
/// is held and the weakest direction leaves the set just past it; a wrench box is inside
/// exactly when all its corners are held; the moment length changes the margin, not the sign.
#[test]
fn capacity_margin_is_the_distance_to_the_edge_of_the_available_wrenches() {
    let mut rng = Rng(0x9e37_79b9_7f4a_7c15);
    for robot in [box_robot(false), box_robot(true), planar_robot()] {
        let n = robot.dof();
        let (mut inside, mut outside) = (0, 0);
        let mut geo = CableGeometry::default();
        for _ in 0..100 {
            let q: Vec<f64> = (0..n)
                .map(|k| match (n, k) {
                    (3, 0) => rng.uniform(0.0, 1.0),
                    (3, 1) => rng.uniform(0.0, 0.8),
                    (3, _) => rng.uniform(-0.4, 0.4),
                    (_, 0) => rng.uniform(-0.5, 0.5),
                    (_, 1) => rng.uniform(-0.35, 0.35),
                    (_, 2) => rng.uniform(-0.4, 0.4),
                    _ => rng.uniform(-0.3, 0.3),
                })
                .collect();
            let pose = Pose::from_coordinates(robot.motion, &q).unwrap();
            let req = Requirement::default();
            let c = capacity(&robot, &pose, &req, &mut geo).unwrap();
            assert!(!c.degenerate);
            let facets = if n == 3 { 6 } else { 56 };
            assert_eq!(c.facets, facets);
            let mut w = [0.0; 6];
            robot.gravity_wrench(&pose.rotation, &mut w);
            let w = &w[..n];
            if c.margin.abs() > 1e-6 {
                assert_eq!(holds(&robot, &q, w), c.margin > 0.0, "{q:?}: {c:?}");
            }
            let scaled = Requirement {
                moment_length: 0.1,
                ..req
            };
            let c2 = capacity(&robot, &pose, &scaled, &mut geo).unwrap();
            if c.margin.abs() > 1e-6 {
                assert_eq!(c2.feasible, c.feasible);
            }
            if c.margin > 1e-3 {
                inside += 1;
                let at = |t: f64| -> Vec<f64> {
                    w.iter()
                        .zip(&c.weakest)
                        .map(|(a, b)| a + t * c.margin * b)
                        .collect()
                };
                assert!(holds(&robot, &q, &at(0.99)), "{q:?}: {c:?}");
                assert!(!holds(&robot, &q, &at(1.01)), "{q:?}: {c:?}");
                for _ in 0..5 {
                    let e: Vec<f64> = (0..n).map(|_| rng.uniform(-1.0, 1.0)).collect();
                    let len = e.iter().map(|v| v * v).sum::<f64>().sqrt();
                    let w2: Vec<f64> = w
                        .iter()
                        .zip(&e)
                        .map(|(a, b)| a + 0.99 * c.margin * b / len)
                        .collect();
                    assert!(holds(&robot, &q, &w2), "{q:?}: {c:?}");
                }
                // a box of half width h per component: inside iff all corners are held
                let h = 0.5 * c.margin / (n as f64).sqrt() * rng.uniform(0.5, 3.0);
                let boxed = Requirement {
                    half_width: [h; 6],
                    ..req
                };
                let cb = capacity(&robot, &pose, &boxed, &mut geo).unwrap();
                let all = (0..1usize << n).all(|corner| {
                    let wc: Vec<f64> = (0..n)
                        .map(|k| w[k] + if corner >> k & 1 == 1 { h } else { -h })
                        .collect();
                    holds(&robot, &q, &wc)
                });
                if cb.margin.abs() > 1e-6 {
                    assert_eq!(all, cb.feasible, "{q:?}: box {h}: {cb:?}");
                }
                assert!(cb.margin <= c.margin);
            } else if c.margin < -1e-3 {
                outside += 1;
            }
        }
        assert!(
            inside > 10 && outside > 10,
            "{inside} inside, {outside} outside"
        );
    }
}

/// The controller's steps are the batch's answers, pose by pose, and report the jumps.
#[test]
fn the_controller_answers_like_the_batch_and_reports_jumps() {
    let robot = box_robot(false);
    let poses: Vec<f64> = (0..40)
        .flat_map(|k| {
            let s = k as f64 / 39.0;
            [0.3 * s, -0.2 * s, 0.1, 0.0, 0.05 * s, 0.0]
        })
        .collect();
    let t = 40;
    let (mut f, mut method, mut feasible, mut residual) = (
        vec![0.0; t * 8],
        vec![Method::Auto; t],
        vec![false; t],
        vec![0.0; t],
    );
    let out = TensionsMut {
        f: &mut f,
        method: &mut method,
        feasible: &mut feasible,
        residual: &mut residual,
    };
    distribute_batch(&robot, &poses, None, true, Method::Auto, out).unwrap();
    let mut ctl = Controller::new(&robot, Method::Auto, true).unwrap();
    let mut prev: Option<Vec<f64>> = None;
    for (k, q) in poses.chunks(6).enumerate() {
        let s = ctl.step(q, None).unwrap();
        let d = s.distribution;
        assert_eq!(d.method, method[k]);
        for (a, b) in d.tensions().iter().zip(&f[k * 8..(k + 1) * 8]) {
            assert!((a - b).abs() < 1e-9, "{a} vs {b}");
        }
        let want = prev.map_or(0.0, |p| {
            p.iter()
                .zip(d.tensions())
                .map(|(a, b)| (a - b).abs())
                .fold(0.0, f64::max)
        });
        assert!(
            (s.jump - want).abs() <= 1e-12 * want.max(1.0),
            "{} vs {want}",
            s.jump
        );
        prev = Some(d.tensions().to_vec());
    }
    assert!(ctl.step(&[0.0; 5], None).is_err());
    assert!(ctl.step(&[0.0; 6], Some(&[f64::NAN; 6])).is_err());
}

/// Determinant of a small square matrix (partial pivoting), for the reference below.
fn det(mut a: Vec<Vec<f64>>) -> f64 {
    let q = a.len();
    let mut d = 1.0;
    for k in 0..q {
        let p = (k..q)
            .max_by(|&x, &y| a[x][k].abs().total_cmp(&a[y][k].abs()))
            .unwrap();
        if a[p][k] == 0.0 {
            return 0.0;
        }
        if p != k {
            a.swap(p, k);
            d = -d;
        }
        d *= a[k][k];
        for r in k + 1..q {
            let f = a[r][k] / a[k][k];
            for c in k..q {
                a[r][c] -= f * a[k][c];
            }
        }
    }
    d
}

/// The hyperplane shifting method as textbooks write it: for every set of `n − 1` columns of
/// `Aᵀ` (moment rows divided by the moment length), the normal `c` is their generalised cross
/// product (signed cofactors), and the margin is the least over `±c` of
/// `(Σᵢ max(f_minᵢ·c·aᵢ, f_maxᵢ·c·aᵢ) + c·w − Σₖ |cₖ|·δₖ) / ‖c‖`.
fn brute_force_margin(
    at: &[f64],
    n: usize,
    m: usize,
    lo: &[f64],
    hi: &[f64],
    w: &[f64],
    req: &Requirement,
) -> f64 {
    let first_moment = if n == 3 { 2 } else { 3 };
    let s = |r: usize| {
        if n >= 3 && r >= first_moment {
            1.0 / req.moment_length
        } else {
            1.0
        }
    };
    let col = |i: usize| -> Vec<f64> { (0..n).map(|r| at[r * m + i] * s(r)).collect() };
    let mut best = f64::INFINITY;
    for set in 0u32..1 << m {
        if set.count_ones() as usize != n - 1 {
            continue;
        }
        let cols: Vec<Vec<f64>> = (0..m).filter(|i| set >> i & 1 == 1).map(col).collect();
        let c: Vec<f64> = (0..n)
            .map(|k| {
                let minor = (0..n)
                    .filter(|&r| r != k)
                    .map(|r| cols.iter().map(|v| v[r]).collect())
                    .collect();
                if k % 2 == 0 {
                    det(minor)
                } else {
                    -det(minor)
                }
            })
            .collect();
        let norm = c.iter().map(|v| v * v).sum::<f64>().sqrt();
        let size: f64 = cols
            .iter()
            .map(|v| v.iter().map(|x| x * x).sum::<f64>().sqrt())
            .product();
        if norm <= 1e-9 * size {
            continue;
        }
        for sign in [1.0, -1.0] {
            let support: f64 = (0..m)
                .filter(|i| set >> i & 1 == 0)
                .map(|i| {
                    let p: f64 = col(i).iter().zip(&c).map(|(a, b)| sign * a * b).sum();
                    (lo[i] * p).max(hi[i] * p)
                })
                .sum();
            let cw: f64 = (0..n)
                .map(|k| sign * c[k] * (w[k] + req.center[k]) * s(k))
                .sum();
            let width: f64 = (0..n).map(|k| c[k].abs() * req.half_width[k] * s(k)).sum();
            best = best.min((support + cw - width) / norm);
        }
    }
    best
}

/// The capacity margin (one elimination, facets in basis coordinates) equals the textbook
/// hyperplane shifting method on random structure matrices, bounds, wrenches and boxes, for
/// 1 to 4 redundant cables, planar and spatial, with and without a moment length.
#[test]
fn capacity_margin_equals_the_textbook_hyperplane_shifting_method() {
    let mut rng = Rng(0x2545_f491_4f6c_dd1d);
    let mut checked = 0;
    for (n, m) in [
        (2, 3),
        (3, 4),
        (3, 5),
        (3, 7),
        (6, 7),
        (6, 8),
        (6, 9),
        (6, 10),
    ] {
        for case in 0..40 {
            let at: Vec<f64> = (0..n * m).map(|_| rng.uniform(-1.0, 1.0)).collect();
            let lo: Vec<f64> = (0..m).map(|_| rng.uniform(0.0, 20.0)).collect();
            let hi: Vec<f64> = lo.iter().map(|l| l + rng.uniform(1.0, 200.0)).collect();
            let w: Vec<f64> = (0..n).map(|_| rng.uniform(-100.0, 100.0)).collect();
            let mut req = Requirement {
                moment_length: if case % 3 == 0 { 0.2 } else { 1.0 },
                ..Requirement::default()
            };
            if case % 2 == 1 {
                for k in 0..n {
                    req.center[k] = rng.uniform(-20.0, 20.0);
                    req.half_width[k] = rng.uniform(0.0, 10.0);
                }
            }
            let c = capacity_margin(&at, n, m, &lo, &hi, &w, &req).unwrap();
            let reference = brute_force_margin(&at, n, m, &lo, &hi, &w, &req);
            let scale = hi.iter().fold(1.0_f64, |a, b| a.max(*b));
            assert!(
                (c.margin - reference).abs() <= 1e-9 * scale,
                "n {n}, m {m}, case {case}: {} against {reference}",
                c.margin
            );
            assert_eq!(c.feasible, c.margin >= 0.0);
            checked += 1;
        }
    }
    assert_eq!(checked, 320);
}

/// A pose built through the rotation cache is the uncached pose, whether the orientation
/// repeats or changes between calls.
#[test]
fn cached_rotation_is_the_uncached_pose() {
    let mut rng = Rng(0x5851_f42d_4c95_7f2d);
    let mut cache = None;
    let mut orientation = [0.1, -0.2, 0.3];
    for i in 0..200 {
        if i % 7 == 0 {
            orientation = [
                rng.uniform(-1.0, 1.0),
                rng.uniform(-1.0, 1.0),
                rng.uniform(-3.0, 3.0),
            ];
        }
        let q = [
            rng.uniform(-1.0, 1.0),
            rng.uniform(-1.0, 1.0),
            rng.uniform(-1.0, 1.0),
            orientation[0],
            orientation[1],
            orientation[2],
        ];
        let cached = Pose::from_coordinates_cached(Motion::Spatial, &q, &mut cache).unwrap();
        assert_eq!(cached, Pose::from_coordinates(Motion::Spatial, &q).unwrap());
        let planar = [q[0], q[1], q[5]];
        let mut planar_cache = cache;
        let p = Pose::from_coordinates_cached(Motion::Planar, &planar, &mut planar_cache).unwrap();
        assert_eq!(p, Pose::from_coordinates(Motion::Planar, &planar).unwrap());
    }
    assert!(Pose::from_coordinates_cached(Motion::Spatial, &[f64::NAN; 6], &mut cache).is_err());
}

/// `Margins::Inside` (stop at the first crossed facet) keeps every membership and every inside
/// margin of the full scan, per pose and in a batch; outside it reports a crossed facet's
/// distance, never above zero and never below the exact margin, and that facet's cables are the
/// full scan's own facet when the two margins agree.
#[test]
fn inside_margins_stop_at_a_crossed_facet_and_change_no_membership() {
    let mut rng = Rng(0x2545_f491_4f6c_dd1d);
    for robot in [box_robot(false), box_robot(true), planar_robot()] {
        let n = robot.dof();
        let full = Requirement {
            gravity: true,
            center: [3.0, -2.0, 1.0, 0.1, 0.0, 0.05],
            ..Requirement::default()
        };
        let inside = Requirement {
            margins: Margins::Inside,
            ..full
        };
        let poses: Vec<f64> = (0..400)
            .flat_map(|_| {
                (0..n)
                    .map(|k| match (n, k) {
                        (3, 0) => rng.uniform(-0.2, 1.2),
                        (3, 1) => rng.uniform(-0.2, 1.0),
                        (3, _) => rng.uniform(-0.6, 0.6),
                        (_, 0) => rng.uniform(-0.6, 0.6),
                        (_, 1) => rng.uniform(-0.45, 0.45),
                        (_, 2) => rng.uniform(-0.45, 0.45),
                        _ => rng.uniform(-0.4, 0.4),
                    })
                    .collect::<Vec<_>>()
            })
            .collect();
        let t = poses.len() / n;
        let (mut margin, mut feasible, mut degenerate, mut weakest) = (
            vec![0.0; t],
            vec![false; t],
            vec![false; t],
            vec![0.0; t * n],
        );
        let out = CapacityMut {
            margin: &mut margin,
            feasible: &mut feasible,
            degenerate: &mut degenerate,
            weakest: &mut weakest,
        };
        capacity_batch(&robot, &poses, &inside, out).unwrap();
        let (mut geo, mut outside, mut stopped) = (CableGeometry::default(), 0, 0);
        for (row, q) in poses.chunks(n).enumerate() {
            let pose = Pose::from_coordinates(robot.motion, q).unwrap();
            let c = capacity(&robot, &pose, &full, &mut geo).unwrap();
            let s = capacity(&robot, &pose, &inside, &mut geo).unwrap();
            assert_eq!((s.feasible, s.degenerate), (c.feasible, c.degenerate));
            assert_eq!((feasible[row], degenerate[row]), (c.feasible, c.degenerate));
            assert_eq!(c.facet_cables.count_ones() as usize, n - 1, "{c:?}");
            if c.feasible {
                assert_eq!(s.margin.to_bits(), c.margin.to_bits());
                assert_eq!(margin[row].to_bits(), c.margin.to_bits());
                assert_eq!(s.facets, c.facets);
            } else if !c.degenerate {
                outside += 1;
                for m in [s.margin, margin[row]] {
                    assert!(
                        m < 0.0 && m >= c.margin - 1e-9 * c.margin.abs(),
                        "{m} vs {c:?}"
                    );
                }
                stopped += usize::from(s.facets < c.facets);
                if (s.margin - c.margin).abs() < 1e-12 * c.margin.abs() {
                    assert_eq!(s.facet_cables, c.facet_cables);
                }
            }
        }
        assert!(
            outside > 40 && stopped > 20,
            "{outside} outside, {stopped} stopped early"
        );
    }
}

/// Path friction (seed 002 eqs 7–8) along a straight move there and back: the speed is the
/// cable's hauling rate; with the Coulomb law the friction is `μ·T·N(θ)·σ_ε(v) + σ_v·v` (the
/// hauled-in cables read high, the paid-out ones low); the Dahl state reaches the same value
/// a few presliding lengths after each reversal, and lags it just after one.
#[test]
fn path_friction_follows_eqs_7_and_8() {
    let robot = box_robot(true);
    let (n, m) = (robot.dof(), robot.n_cables());
    let dt = 0.01;
    let t = 201;
    let mut poses = vec![0.0; t * n];
    for k in 0..t {
        // 0.1 m out along x in 1 s, then back
        let s = k as f64 * dt;
        poses[k * n] = if s <= 1.0 { 0.1 * s } else { 0.1 * (2.0 - s) };
    }
    let ee = vec![10.0; t * m];
    let coulomb = PathFriction {
        coefficient: 0.1,
        viscous: 5.0,
        guide_wrap: std::f64::consts::FRAC_PI_2,
        law: PathLaw::Coulomb { smoothing: 1e-6 },
    };
    let run = path_friction(&robot, &poses, &ee, dt, &[coulomb]).unwrap();
    let mut geo = CableGeometry::default();
    let mut lengths = vec![0.0; t * m];
    for k in 0..t {
        let pose = Pose::from_coordinates(robot.motion, &poses[k * n..(k + 1) * n]).unwrap();
        inverse_kinematics(&robot, &pose, &mut geo).unwrap();
        lengths[k * m..(k + 1) * m].copy_from_slice(&geo.length[..m]);
    }
    for k in [10, 50, 150, 190] {
        for i in 0..m {
            let j = k * m + i;
            let v = -(lengths[j + m] - lengths[j - m]) / (2.0 * dt);
            assert!((run.speed[j] - v).abs() < 1e-12, "{k} {i}");
            let normal = 10.0 * coulomb.normal_factor(run.wrap[j]);
            let want = 0.1 * normal * v.signum() + 5.0 * v;
            assert!(
                (run.friction[j] - want).abs() < 1e-6,
                "{k} {i}: {} vs {want}",
                run.friction[j]
            );
            assert!((run.pul[j] - 10.0 - run.friction[j]).abs() < 1e-12);
            if v.abs() > 1e-3 {
                assert_eq!(run.pul[j] > 10.0, v > 0.0);
            }
        }
    }
    // Dahl: the same Coulomb part once the state has saturated, less just after the reversal
    let dahl = PathFriction {
        law: PathLaw::Dahl {
            presliding: 1e-3,
            exponent: 1.0,
        },
        ..coulomb
    };
    let d = path_friction(&robot, &poses, &ee, dt, &[dahl]).unwrap();
    for i in 0..m {
        let j = 90 * m + i; // 0.9 s: far from the start and the reversal
        if run.speed[j].abs() > 0.02 {
            assert!((d.friction[j] - run.friction[j]).abs() < 1e-6, "{i}");
            let after = 101 * m + i; // one sample after the reversal: the state is still turning
            let coulomb_part = |f: f64, k: usize| f - 5.0 * run.speed[k * m + i];
            assert!(
                coulomb_part(d.friction[after], 101).abs()
                    < coulomb_part(run.friction[after], 101).abs(),
                "{i}"
            );
        }
    }
    // shapes and parameters
    assert!(path_friction(&robot, &poses, &ee[1..], dt, &[coulomb]).is_err());
    assert!(path_friction(&robot, &poses, &ee, dt, &[coulomb, coulomb]).is_err());
    assert!(path_friction(&robot, &poses, &ee, 0.0, &[coulomb]).is_err());
    let bad = PathFriction {
        coefficient: -0.1,
        ..coulomb
    };
    assert!(path_friction(&robot, &poses, &ee, dt, &[bad]).is_err());
    assert!(PathFriction::per_cable(&[0.1; 3], &[1.0], &[0.0], dahl.law, m).is_err());
    assert_eq!(
        PathFriction::per_cable(&[0.1], &[1.0], &[0.0], dahl.law, m)
            .unwrap()
            .len(),
        m
    );
}

/// The equilibrium projection holds the wrench, leaves tensions already in equilibrium as they
/// are, and removes exactly the part of an error that unbalances the platform (an internal
/// force, in the null space of `Aᵀ`, stays).
#[test]
fn equilibrium_projection_removes_the_unbalancing_part_of_an_error() {
    let robot = box_robot(true);
    let (n, m) = (robot.dof(), robot.n_cables());
    let mut rng = Rng(0x1234_5678_9abc_def1);
    for _ in 0..20 {
        let q: Vec<f64> = (0..n)
            .map(|k| {
                if k < 3 {
                    rng.uniform(-0.2, 0.2)
                } else {
                    rng.uniform(-0.1, 0.1)
                }
            })
            .collect();
        let g = ik(&robot, &q);
        let at = g.structure();
        let mut w = [0.0; 6];
        let pose = Pose::from_coordinates(robot.motion, &q).unwrap();
        robot.gravity_wrench(&pose.rotation, &mut w);
        let ext: Vec<f64> = (0..n).map(|_| rng.uniform(-2.0, 2.0)).collect();
        for (a, e) in w.iter_mut().zip(&ext) {
            *a += e;
        }
        // tensions in equilibrium: the minimum-norm ones plus an internal force
        let base = minimum_norm(at, n, m, &w[..n]).unwrap();
        let err: Vec<f64> = (0..m).map(|_| rng.uniform(-1.0, 1.0)).collect();
        let meas: Vec<f64> = (0..m).map(|i| base.f[i] + err[i]).collect();
        let got = equilibrium_projection(&robot, &q, &meas, Some(&ext), true).unwrap();
        // holds the wrench
        for a in 0..n {
            let s: f64 = (0..m).map(|i| at[a * m + i] * got[i]).sum::<f64>() + w[a];
            assert!(s.abs() < 1e-9, "row {a}: {s}");
        }
        // the correction lies in the row space of Aᵀ (orthogonal to every internal force):
        // projecting again changes nothing, and projecting the base changes nothing
        let again = equilibrium_projection(&robot, &q, &got, Some(&ext), true).unwrap();
        let same = equilibrium_projection(&robot, &q, &base.f[..m], Some(&ext), true).unwrap();
        for i in 0..m {
            assert!((again[i] - got[i]).abs() < 1e-9);
            assert!((same[i] - base.f[i]).abs() < 1e-9);
        }
        // never further from the truth (here: the base plus the error's internal part) than the
        // measurement
        let dist = |a: &[f64]| -> f64 { (0..m).map(|i| (a[i] - base.f[i]).powi(2)).sum() };
        assert!(dist(&got) <= dist(&meas) + 1e-12);
    }
    assert!(equilibrium_projection(&robot, &[0.0; 6], &[1.0; 7], None, true).is_err());
    assert!(equilibrium_projection(&robot, &[0.0; 6], &[f64::NAN; 8], None, true).is_err());
}
