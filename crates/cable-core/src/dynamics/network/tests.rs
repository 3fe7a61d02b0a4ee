use super::*;
use crate::cable::CableLaw;
use crate::dynamics::{raven2, AntagonisticJoint};
use crate::integrate::{simulate, InputHold, SimOptions};

fn joint() -> AntagonisticJoint {
    let run =
        |k: f64, t0: f64| CableRun::new(CableLaw::Linear { stiffness: k }, 3.0, t0, "c").unwrap();
    AntagonisticJoint::new(
        4e-3,
        run(12_000.0, 10.0),
        run(9_000.0, 8.0),
        1e-5,
        StaticFriction::coulomb_viscous("f", 2e-3, 1e-4, 0.05).unwrap(),
        0.08,
        1.2,
        1e-3,
        None,
    )
    .unwrap()
}

fn max_rel(a: &[f64], b: &[f64]) -> f64 {
    let scale = a.iter().fold(0.0_f64, |m, v| m.max(v.abs())).max(1e-300);
    a.iter()
        .zip(b)
        .fold(0.0_f64, |m, (x, y)| m.max((x - y).abs()))
        / scale
}

#[test]
fn the_antagonistic_joint_as_a_network_simulates_the_same() {
    let j = joint();
    let net = Network::new(&NetworkSpec::from_joint(&j).unwrap()).unwrap();
    assert_eq!(net.n_states(), 2);
    assert_eq!(net.n_inputs(), 3); // q_m, q̇_m, τ_ext
    let (dt, len) = (1e-3, 1500);
    let mut u_joint = Vec::new();
    let mut u_net = Vec::new();
    for k in 0..len {
        let t = k as f64 * dt;
        let (x, v) = (
            2e-3 * (7.0 * t).sin() + 5e-4 * (31.0 * t).sin(),
            14e-3 * (7.0 * t).cos() + 15.5e-3 * (31.0 * t).cos(),
        );
        u_joint.extend([x, v]);
        u_net.extend([x, v, 0.0]);
    }
    let opts = SimOptions::new(dt, 8, InputHold::Foh).unwrap();
    let a = simulate(&j, &u_joint, &[0.0, 0.0], &opts).unwrap();
    let b = simulate(&net, &u_net, &[0.0, 0.0], &opts).unwrap();
    assert!(
        max_rel(&a.states, &b.states) < 1e-12,
        "{}",
        max_rel(&a.states, &b.states)
    );
    // outputs: joint [T_m1, T_m2, T_j1, T_j2, θ, F_c]; network [q, q_m, T1, T2, Tm1, Tm2, τ]
    let (pa, pb) = (6, 8);
    let pick = |y: &[f64], p: usize, i: usize| (0..len).map(|k| y[k * p + i]).collect::<Vec<_>>();
    for (ia, ib) in [(0, 4), (1, 5), (2, 2), (3, 3), (4, 0)] {
        let (ya, yb) = (pick(&a.outputs, pa, ia), pick(&b.outputs, pb, ib));
        assert!(
            max_rel(&ya, &yb) < 1e-12,
            "output {ia}: {}",
            max_rel(&ya, &yb)
        );
    }
    // τ = r·(T1 − T2)
    let tau = pick(&b.outputs, pb, 6);
    let (t1, t2) = (pick(&b.outputs, pb, 2), pick(&b.outputs, pb, 3));
    for k in 0..len {
        assert!((tau[k] - j.radius * (t1[k] - t2[k])).abs() < 1e-12 * (1.0 + tau[k].abs()));
    }
}

#[test]
fn the_raven_transmission_as_a_network_simulates_the_same() {
    let tx = raven2(3).unwrap();
    let net = Network::new(&NetworkSpec::from_transmission(&tx).unwrap()).unwrap();
    assert_eq!((net.n_states(), net.n_inputs()), (12, 6));
    let (dt, len, n) = (1e-3, 800, 3);
    let mut u = Vec::new();
    for k in 0..len {
        let t = k as f64 * dt;
        u.extend([
            0.3 * (5.0 * t).sin(),
            -0.2 * (3.0 * t).sin(),
            0.25 * (4.0 * t).cos(),
            0.0,
            0.05,
            0.0,
        ]);
    }
    let opts = SimOptions::new(dt, 10, InputHold::Zoh).unwrap();
    let a = simulate(&tx, &u, &[0.0; 12], &opts).unwrap();
    let b = simulate(&net, &u, &[0.0; 12], &opts).unwrap();
    // transmission state per link [q_m, q̇_m, q_l, q̇_l]; network [q_l, q̇_l]×n then [q_m, q̇_m]×n
    for i in 0..n {
        for (sa, sb) in [
            (4 * i, 2 * n + 2 * i),
            (4 * i + 2, 2 * i),
            (4 * i + 3, 2 * i + 1),
        ] {
            let ya: Vec<f64> = (0..len).map(|k| a.states[k * 12 + sa]).collect();
            let yb: Vec<f64> = (0..len).map(|k| b.states[k * 12 + sb]).collect();
            assert!(
                max_rel(&ya, &yb) < 1e-9,
                "link {i} state {sa}: {}",
                max_rel(&ya, &yb)
            );
        }
    }
}

#[test]
fn length_map_jacobian_and_torques_agree() {
    let tx = raven2(3).unwrap();
    let net = Network::new(&NetworkSpec::from_transmission(&tx).unwrap()).unwrap();
    let q = [0.3, -0.2, 0.05];
    let dl = net.length_change(&q).unwrap();
    let (m, n) = (net.n_cables(), net.n_joints());
    let arms = net.moment_arms();
    // finite differences of l(q) give −J
    for j in 0..n {
        let mut qp = q;
        qp[j] += 1e-6;
        let lp = net.length_change(&qp).unwrap();
        for c in 0..m {
            let d = (lp[c] - dl[c]) / 1e-6;
            assert!((d + arms[c * n + j]).abs() < 1e-8, "cable {c} joint {j}");
        }
    }
    // virtual work: τ·δq = −T·δl
    let t: Vec<f64> = (0..m).map(|c| 5.0 + c as f64).collect();
    let tau = net.joint_torques(&t).unwrap();
    let dq = [1e-3, -2e-3, 5e-4];
    let dlen = net.length_change(&dq).unwrap();
    let w_joint: f64 = tau.iter().zip(&dq).map(|(a, b)| a * b).sum();
    let w_cable: f64 = -t.iter().zip(&dlen).map(|(a, b)| a * b).sum::<f64>();
    assert!((w_joint - w_cable).abs() < 1e-12);
}

#[test]
fn energy_is_conserved_without_losses() {
    let mut j = joint();
    j.friction = StaticFriction::NONE;
    j.capstan_mu = 0.0; // the routing's friction acts on a torque-driven motor
    for r in [&mut j.drive, &mut j.ret] {
        r.damping = 0.0;
        r.pretension = 50.0; // no slack over the motion
    }
    let mut spec = NetworkSpec::from_joint(&j).unwrap();
    spec.motors[0].drive = Drive::Torque;
    spec.motors[0].inertia = 2e-6;
    spec.motors[0].capstan_radius = 0.01; // a motor mode RK4 resolves at this step
    let net = Network::new(&spec).unwrap();
    let opts = SimOptions::new(1e-4, 4, InputHold::Zoh).unwrap();
    let u = vec![0.0; 2 * 3000];
    let x0 = [0.05, 0.0, 0.0, 0.0];
    let tr = simulate(&net, &u, &x0, &opts).unwrap();
    let e0 = net.energy(&x0, &[0.0, 0.0]);
    let e1 = net.energy(&tr.states[tr.states.len() - 4..], &[0.0, 0.0]);
    assert!(e0 > 0.0);
    assert!(((e1 - e0) / e0).abs() < 1e-7, "{e0} -> {e1}");
}

fn finger() -> NetworkSpec {
    let run = CableRun::new(CableLaw::Linear { stiffness: 5e4 }, 10.0, 5.0, "t").unwrap();
    let body = |name: &str| BodySpec {
        name: name.into(),
        inertia: 1e-5,
    };
    let joint = |name: &str, parent: &str, child: &str| JointSpec {
        name: name.into(),
        kind: "revolute".into(),
        parent: parent.into(),
        child: child.into(),
        coulomb: 0.0,
        viscous: 1e-4,
        smoothing: 1e-2,
        gravity: Gravity::NONE,
    };
    let pulley = |name: &str, j: &str, r: f64| PulleySpec {
        name: name.into(),
        joint: Some(j.into()),
        radius: r,
    };
    let contact = |p: &str, sense: f64| ContactSpec {
        pulley: p.into(),
        wrap: 1.0,
        sense,
        mu: 0.0,
    };
    let motor = |name: &str| MotorSpec {
        name: name.into(),
        drive: Drive::Position,
        inertia: 0.0,
        gear_ratio: 1.0,
        capstan_radius: 0.01,
        friction: StaticFriction::NONE,
    };
    let cable = |name: &str, routing: Vec<ContactSpec>, m: &str| CableSpec {
        name: name.into(),
        routing,
        run,
        motor: Some(m.into()),
        motor_sense: 1.0,
        end_motor: None,
        end_sense: 1.0,
        free_length: None,
        path: None,
    };
    NetworkSpec {
        bodies: vec![body("proximal"), body("distal")],
        joints: vec![
            joint("mcp", "base", "proximal"),
            joint("pip", "proximal", "distal"),
        ],
        pulleys: vec![pulley("p_mcp", "mcp", 8e-3), pulley("p_pip", "pip", 6e-3)],
        cables: vec![
            cable(
                "t1",
                vec![contact("p_mcp", 1.0), contact("p_pip", 1.0)],
                "m1",
            ),
            cable(
                "t2",
                vec![contact("p_mcp", -1.0), contact("p_pip", 1.0)],
                "m2",
            ),
            cable(
                "t3",
                vec![contact("p_mcp", -1.0), contact("p_pip", -1.0)],
                "m3",
            ),
        ],
        motors: vec![motor("m1"), motor("m2"), motor("m3")],
        sensors: Vec::new(),
        capstan_smoothing: 1e-3,
        signals: Vec::new(),
    }
}

fn network_error(spec: &NetworkSpec) -> (String, String) {
    match Network::new(spec) {
        Err(CableError::Network { element, reason }) => (element, reason),
        other => panic!("expected a network error, got {other:?}"),
    }
}

#[test]
fn bad_networks_are_refused_naming_the_element() {
    assert!(Network::new(&finger()).is_ok());
    let mut s = finger();
    s.cables[1].routing.clear();
    assert_eq!(network_error(&s).0, "cable \"t2\"");
    let mut s = finger();
    s.cables[2].routing[1].wrap = -0.5;
    let (el, why) = network_error(&s);
    assert!(
        el.contains("cable \"t3\".routing[1]") && why.contains("wrap"),
        "{el} {why}"
    );
    let mut s = finger();
    s.bodies.push(BodySpec {
        name: "loose".into(),
        inertia: 1.0,
    });
    let (el, why) = network_error(&s);
    assert_eq!(el, "body \"loose\"");
    assert!(why.contains("disconnected"));
    let mut s = finger();
    s.joints[0].parent = "distal".into(); // mcp on distal, pip on proximal: a loop
    let (el, why) = network_error(&s);
    assert!(el.starts_with("body") && why.contains("loop"), "{el} {why}");
    // a singular coupling: every tendon turns both joints alike (rows of J proportional)
    let mut s = finger();
    s.pulleys[1].radius = 8e-3;
    s.cables[1].routing[1].sense = -1.0;
    let (el, why) = network_error(&s);
    assert!(
        el.starts_with("joint") && why.contains("singular"),
        "{el} {why}"
    );
    let mut s = finger();
    s.cables[0].routing[0].pulley = "nowhere".into();
    let (el, why) = network_error(&s);
    assert!(el.contains("t1") && why.contains("nowhere"), "{el} {why}");
    let mut s = finger();
    s.cables[0].motor = Some("m9".into());
    assert!(network_error(&s).1.contains("m9"));
    let mut s = finger();
    for c in &mut s.cables {
        c.routing.retain(|k| k.pulley != "p_pip");
    }
    let (el, why) = network_error(&s);
    assert_eq!(el, "joint \"pip\"");
    assert!(why.contains("nothing moves it"));
    let mut s = finger();
    s.cables[2].motor = Some("m1".into());
    assert_eq!(
        network_error(&s),
        ("motor \"m3\"".into(), "hauls no cable".into())
    );
    let mut s = finger();
    s.bodies[0].inertia = -1.0;
    assert!(matches!(
        Network::new(&s),
        Err(CableError::InvalidParameter { .. })
    ));
}

#[test]
fn tension_closure_of_pairs_and_tendons() {
    // an antagonistic pair: both cables at half the total, margin 1/2
    let j = Network::new(&NetworkSpec::from_joint(&joint()).unwrap()).unwrap();
    let (s, t) = j.tension_closure().unwrap();
    assert!(
        (s - 0.5).abs() < 1e-6 && (t[0] - 0.5).abs() < 1e-6,
        "{s} {t:?}"
    );
    // the test finger's three tendons on two joints: Jᵀ·T = 0 forces the middle one slack
    let (s, t) = Network::new(&finger()).unwrap().tension_closure().unwrap();
    assert!(s < 1e-6 && t[1] < 1e-6, "{s} {t:?}");
    // with moment arms (9, 4), (−3, 4), (−6, −8) mm, T = (1, 1, 1)/3 is torque-free
    let mut spec = finger();
    let arms = [(9e-3, 4e-3), (3e-3, 4e-3), (6e-3, 8e-3)];
    spec.pulleys.clear();
    for (c, (a, b)) in arms.iter().enumerate() {
        for (joint, r, k) in [("mcp", *a, 0), ("pip", *b, 1)] {
            let name = format!("{joint}{c}");
            spec.pulleys.push(PulleySpec {
                name: name.clone(),
                joint: Some(joint.into()),
                radius: r,
            });
            spec.cables[c].routing[k].pulley = name;
        }
    }
    let f = Network::new(&spec).unwrap();
    let (s, t) = f.tension_closure().unwrap();
    assert!((s - 1.0 / 3.0).abs() < 1e-6, "{s} {t:?}");
    let tau = f.joint_torques(&t).unwrap();
    assert!(tau.iter().all(|v| v.abs() < 1e-9), "{tau:?}");
}

/// The joint's network with its friction removed, driven by its motor along `motion(t)` (m of
/// capstan): the inputs `[q_m, q̇_m, τ_ext]` over `len` samples of `dt`.
fn driven(motion: impl Fn(f64) -> (f64, f64), len: usize, dt: f64) -> Vec<f64> {
    (0..len)
        .flat_map(|k| {
            let (q, v) = motion(k as f64 * dt);
            [q, v, 0.0]
        })
        .collect()
}

/// A pre-sliding (Dahl) element with a break-away displacement far below the motion is the
/// Coulomb friction of its level; its state stays within the level.
#[test]
fn presliding_friction_tends_to_coulomb_and_stays_bounded() {
    let mut j = joint();
    let level = 2e-3;
    j.friction = StaticFriction::coulomb_viscous("f", level, 1e-4, 1e-3).unwrap();
    let coulomb = Network::new(&NetworkSpec::from_joint(&j).unwrap()).unwrap();
    j.friction = StaticFriction::coulomb_viscous("f", 0.0, 1e-4, 1e-3).unwrap();
    let mut dahl = Network::new(&NetworkSpec::from_joint(&j).unwrap()).unwrap();
    dahl.set_presliding(0, Presliding::dahl(level, 1e-4));
    assert_eq!(dahl.n_states(), 3);
    assert_eq!(dahl.state_names()[2], "z:joint");
    let w = 2.0 * std::f64::consts::PI;
    let (dt, len) = (1e-3, 1500);
    let u = driven(
        |t| (2e-4 * (w * t).sin(), 2e-4 * w * (w * t).cos()),
        len,
        dt,
    );
    let opts = SimOptions::new(dt, 64, InputHold::Foh).unwrap();
    let a = simulate(&coulomb, &u, &[0.0; 2], &opts).unwrap();
    let b = simulate(&dahl, &u, &[0.0; 3], &opts).unwrap();
    let p = coulomb.n_outputs();
    let angle = |y: &[f64]| (0..len).map(|k| y[k * p]).collect::<Vec<_>>();
    let (qa, qb) = (angle(&a.outputs), angle(&b.outputs));
    let span = qa.iter().fold(0.0_f64, |m, v| m.max(v.abs()));
    let err = qa
        .iter()
        .zip(&qb)
        .fold(0.0_f64, |m, (x, y)| m.max((x - y).abs()));
    assert!(span > 1e-2 && err < 0.05 * span, "{err} of {span}");
    let z_max = b
        .states
        .chunks(3)
        .map(|x| x[2].abs())
        .fold(0.0_f64, f64::max);
    assert!(z_max <= level * 1.001 && z_max > 0.9 * level, "{z_max}");
}

/// A creeping cable held at a constant stretch loses `κ` of its elastic tension with time
/// constant `τ` (the whole form: of its pretension too).
#[test]
fn creep_relaxes_the_tension_at_constant_stretch() {
    let mut j = joint();
    j.inertia = 1e3; // the joint stays put over the run
    j.friction = StaticFriction::NONE;
    let base = Network::new(&NetworkSpec::from_joint(&j).unwrap()).unwrap();
    let (dt, len, tau, kappa) = (1e-3, 3000, 0.5, 0.4);
    let e = 1e-4;
    let u = driven(|_| (e, 0.0), len, dt);
    for whole in [false, true] {
        let mut net = base.clone();
        net.set_creep(
            0,
            TensionCreep {
                fraction: kappa,
                time_constant: tau,
                whole,
                stretch: false,
            },
        );
        assert_eq!(net.state_names()[2], "creep:drive");
        let out = simulate(
            &net,
            &u,
            &[0.0; 4],
            &SimOptions::new(dt, 4, InputHold::Zoh).unwrap(),
        )
        .unwrap();
        let p = net.n_outputs();
        let t_end = out.outputs[(len - 1) * p + 2];
        let (t0, f) = (10.0, 12_000.0 * e);
        let target = if whole { kappa * (t0 + f) } else { kappa * f };
        let decay = (-((len - 1) as f64 * dt) / tau).exp();
        let expect = t0 + f - target * (1.0 - decay);
        // the joint creeps a little under the unbalanced pair: 1 % of the relaxed part
        assert!(
            (t_end - expect).abs() < 0.01 * target,
            "{whole}: {t_end} vs {expect}"
        );
    }
}

/// A position motor with play of half-width `δ`: a motion within the play leaves the joint at
/// rest; beyond it the joint follows the motor less the play.
#[test]
fn motor_play_is_a_dead_band_between_motor_and_joint() {
    let mut j = joint();
    j.friction = StaticFriction::coulomb_viscous("f", 0.0, 1e-3, 1e-3).unwrap();
    let mut net = Network::new(&NetworkSpec::from_joint(&j).unwrap()).unwrap();
    let delta = 2e-4;
    // the pair balances with the capstan this far back (unequal pretensions)
    let offset = (10.0 - 8.0) / (12_000.0 + 9_000.0);
    net.set_play(0, delta);
    let (dt, len) = (1e-3, 2000);
    let opts = SimOptions::new(dt, 8, InputHold::Foh).unwrap();
    let p = net.n_outputs();
    // within the play (its balance point included): back and forth by 0.3 δ
    let w = 2.0 * std::f64::consts::PI;
    let inside = driven(
        |t| (0.3 * delta * (w * t).sin(), 0.3 * delta * w * (w * t).cos()),
        len,
        dt,
    );
    let x0 = [offset / j.radius, 0.0];
    let out = simulate(&net, &inside, &x0, &opts).unwrap();
    let moved = (0..len)
        .map(|k| (out.outputs[k * p] - x0[0]).abs())
        .fold(0.0_f64, f64::max);
    assert!(moved < 1e-3 * delta / j.radius, "{moved}");
    // a slow ramp to 5 δ: the joint ends δ/r short of where it ends without the play
    let ramp = driven(|t| (5.0 * delta * t / 2.0, 5.0 * delta / 2.0), len, dt);
    let with = simulate(&net, &ramp, &x0, &opts).unwrap().outputs[(len - 1) * p];
    net.set_play(0, 0.0);
    let without = simulate(&net, &ramp, &x0, &opts).unwrap().outputs[(len - 1) * p];
    let short = (without - with) * j.radius;
    assert!((short - delta).abs() < 0.03 * delta, "{short} vs {delta}");
}

/// A routing with pre-sliding of a break-away far below the motion is the capstan of its level
/// (the motor-side tension agrees with the sign law away from reversals); one far above the
/// motion barely loads the motor side; its state stays in [−1, 1].
#[test]
fn routing_presliding_tends_to_the_capstan_and_stays_bounded() {
    let j = joint();
    let sharp = {
        let mut n = Network::new(&NetworkSpec::from_joint(&j).unwrap()).unwrap();
        for c in 0..2 {
            n.set_routing_friction(c, 0.0, 1e-7);
        }
        n
    };
    let mu_phi: Vec<f64> = (0..2).map(|c| sharp.cable_capstan(c)).collect();
    assert!(mu_phi.iter().all(|a| *a > 0.05), "{mu_phi:?}");
    let dahl = |x_d: f64| {
        let mut n = sharp.clone();
        for (c, a) in mu_phi.iter().enumerate() {
            n.set_routing_friction(c, -a, 1e-7);
            n.set_routing_dahl(c, *a, x_d);
        }
        n
    };
    let w = 2.0 * std::f64::consts::PI;
    let (dt, len, amp) = (1e-3, 2000, 4e-4);
    let u = driven(|t| (amp * (w * t).sin(), amp * w * (w * t).cos()), len, dt);
    let opts = SimOptions::new(dt, 32, InputHold::Foh).unwrap();
    let p = sharp.n_outputs();
    let m = sharp.n_cables();
    let (n_j, n_m) = (sharp.n_joints(), sharp.n_motors());
    let motor_side = |y: &[f64], k: usize| y[k * p + n_j + n_m + m];
    let joint_side = |y: &[f64], k: usize| y[k * p + n_j + n_m];
    let a = simulate(&sharp, &u, &[0.0; 2], &opts).unwrap();
    let small = dahl(1e-3 * amp);
    assert_eq!(small.n_states(), 4);
    assert_eq!(small.state_names()[2], "z_routing:drive");
    let b = simulate(&small, &u, &[0.0; 4], &opts).unwrap();
    // away from the reversals (speed above a tenth of its peak) the ratios agree
    let mut worst: f64 = 0.0;
    for k in len / 4..len {
        let speed = (w * k as f64 * dt).cos().abs();
        if speed > 0.1 {
            let ra = motor_side(&a.outputs, k) / joint_side(&a.outputs, k);
            let rb = motor_side(&b.outputs, k) / joint_side(&b.outputs, k);
            worst = worst.max((ra - rb).abs() / (ra - 1.0).abs().max(1e-12));
        }
    }
    assert!(worst < 0.02, "{worst}");
    // a break-away a hundred times the motion: the ratio stays within a few % of its swing
    let big = simulate(&dahl(100.0 * amp), &u, &[0.0; 4], &opts).unwrap();
    let swing = (0..len)
        .map(|k| (motor_side(&big.outputs, k) / joint_side(&big.outputs, k) - 1.0).abs())
        .fold(0.0_f64, f64::max);
    assert!(swing < 0.05 * (mu_phi[0].exp() - 1.0), "{swing}");
    let z_max = b
        .states
        .chunks(4)
        .map(|x| x[2].abs().max(x[3].abs()))
        .fold(0.0_f64, f64::max);
    assert!(z_max <= 1.0 + 1e-9 && z_max > 0.99, "{z_max}");
}

/// A parallel robot's cable drive as a network without joints: a torque-driven winch hauls a
/// cable over two fixed pulleys to an end a position-driven "motor" moves (the platform's
/// attachment, metres of path). `free_length` makes the stiffness a rod's `E·A/L` of the free
/// length the winch leaves; a tension sensor between the pulleys reads the tension through the
/// friction beyond it.
fn winch(drum_drive: &str) -> serde_json::Value {
    serde_json::json!({
        "name": "winch",
        "capstan_smoothing": 1e-6,
        "pulleys": [{"name": "u", "radius": 0.01}, {"name": "d", "radius": 0.01}],
        "motors": [
            {"name": "drum", "drive": drum_drive, "inertia": 1e-4, "capstan_radius": 0.02},
            {"name": "end", "drive": "position", "capstan_radius": 1.0}
        ],
        "cables": [{
            "name": "c", "motor": "drum", "end_motor": "end", "free_length": 0.8,
            "stiffness": 2.5e4, "pretension": 20.0, "damping": 0.0,
            "routing": [{"pulley": "u", "wrap": 1.5, "mu": 0.1}, {"pulley": "d", "wrap": 1.0, "mu": 0.05}]
        }],
        "sensors": [
            {"name": "drum_angle", "kind": "encoder", "target": "drum"},
            {"name": "cell", "kind": "tension", "target": "c", "at": "u"}
        ]
    })
}

#[test]
fn a_winch_without_joints_stretches_its_free_length_and_taps_between_contacts() {
    let net = Network::new(&NetworkSpec::from_json(&winch("torque").to_string()).unwrap()).unwrap();
    assert_eq!(net.n_joints(), 0);
    assert_eq!(net.n_states(), 2);
    // inputs: the end's [q, q̇], the drum's torque (no joint loads)
    assert_eq!(net.n_inputs(), 3);
    let names = net.output_names();
    assert_eq!(names.last().unwrap(), "T@u:c");
    assert_eq!(
        net.sensor_outputs()[1],
        ("cell".to_owned(), names.len() - 1)
    );
    let (alpha, end) = (2.0, 1e-3); // the drum has wound 4 cm in, the platform pulls 1 mm
    let x = [alpha, 0.3]; // hauling in at 6 mm/s
    let u = [end, 0.0, 0.0];
    let mut y = vec![0.0; net.n_outputs()];
    net.output(&x, &u, &mut y);
    let e = 0.02 * alpha + end;
    let t = (20.0 + 2.5e4 * e) * 0.8 / (0.8 - 0.02 * alpha);
    let (t_el, t_motor, tap) = (y[2], y[3], y[names.len() - 1]);
    assert!((t_el - t).abs() < 1e-9 * t, "{t_el} vs {t}");
    assert!((t_motor - t * (0.1 * 1.5 + 0.05 * 1.0_f64).exp()).abs() < 1e-7 * t);
    assert!((tap - t * (0.05_f64).exp()).abs() < 1e-7 * t, "{tap}");
    // paying out (the drum turning back) the friction reverses
    net.output(&[alpha, -0.3], &u, &mut y);
    assert!((y[names.len() - 1] - t * (-0.05_f64).exp()).abs() < 1e-7 * t);
    // the drum's load is its capstan radius times the drum-side tension
    assert!((y[names.len() - 2 - 1] - 0.02 * y[3]).abs() < 1e-12 * t);
}

/// The winch's cable tension (output 2) of `net` at state `x`, input `u`.
fn tension(net: &Network, x: &[f64], u: &[f64]) -> f64 {
    let mut y = vec![0.0; net.n_outputs()];
    net.output(x, u, &mut y);
    y[2]
}

/// A creeping cable's reference is its law at the run's first input: held there, the tension
/// stays; stretched further by `Δe` it relaxes by `κ·ΔF`; the whole form relaxes from the start.
#[test]
fn creep_relaxes_from_the_first_stretch() {
    let base =
        Network::new(&NetworkSpec::from_json(&winch("position").to_string()).unwrap()).unwrap();
    let (alpha, end) = (2.0, 1e-3);
    // inputs: the drum's [q, q̇], the end's [q, q̇] (no joint loads)
    let u0 = [alpha, 0.0, end, 0.0];
    let plain = tension(&base, &base.rest_at(&u0), &u0);
    let (kappa, scale) = (0.3, 0.8 / (0.8 - 0.02 * alpha));
    let (len, de) = (1000, 2e-4);
    let held = [alpha, 0.0, end + de, 0.0];
    for whole in [false, true] {
        let mut net = base.clone();
        net.set_creep(
            0,
            TensionCreep {
                fraction: kappa,
                time_constant: 0.1,
                whole,
                stretch: false,
            },
        );
        assert_eq!(net.n_states(), base.n_states() + 2);
        let x0 = net.rest_at(&u0);
        assert!((tension(&net, &x0, &u0) - plain).abs() < 1e-12 * plain);
        // one sample at the start, then the end stretched by Δe and held for 10 τ
        let u: Vec<f64> = u0.into_iter().chain((1..len).flat_map(|_| held)).collect();
        let out = simulate(
            &net,
            &u,
            &x0,
            &SimOptions::new(1e-3, 4, InputHold::Zoh).unwrap(),
        )
        .unwrap();
        let t_end = out.outputs[(len - 1) * net.n_outputs() + 2];
        let stretched = tension(&base, &base.rest_at(&u0), &held);
        let expect = if whole {
            stretched * (1.0 - kappa)
        } else {
            stretched - kappa * 2.5e4 * de * scale
        };
        assert!(
            (t_end - expect).abs() < 1e-3 * plain,
            "{whole}: {t_end} vs {expect}"
        );
    }
}

/// The stretch form relaxes as the tension form does while the free length stays (a linear law:
/// `w = k·f·δ`), and keeps its crept length when the drum winds: right after a wind at the same
/// elongation its loss has scaled with the free length's factor `f`, the tension form's has not.
#[test]
fn creep_of_the_stretch_keeps_its_length_as_the_drum_winds() {
    let base =
        Network::new(&NetworkSpec::from_json(&winch("position").to_string()).unwrap()).unwrap();
    let (alpha, end, kappa, de) = (2.0, 1e-3, 0.3, 2e-4);
    let u0 = [alpha, 0.0, end, 0.0];
    let held = [alpha, 0.0, end + de, 0.0];
    let len = 1000;
    let u: Vec<f64> = u0.into_iter().chain((1..len).flat_map(|_| held)).collect();
    let scale = |a: f64| 0.8 / (0.8 - 0.02 * a);
    // wound 10 cm further in at the same elongation (the end moves with it)
    let alpha2 = alpha + 5.0;
    let wound = [alpha2, 0.0, end + de - 0.02 * (alpha2 - alpha), 0.0];
    let mut loss = Vec::new();
    for stretch in [false, true] {
        let mut net = base.clone();
        net.set_creep(
            0,
            TensionCreep {
                fraction: kappa,
                time_constant: 0.1,
                whole: false,
                stretch,
            },
        );
        let names = net.state_names();
        let want = if stretch { "crept:c" } else { "creep:c" };
        assert_eq!(names[names.len() - 2], want);
        let x0 = net.rest_at(&u0);
        assert!((tension(&net, &x0, &u0) - tension(&base, &base.rest_at(&u0), &u0)).abs() < 1e-9);
        let out = simulate(
            &net,
            &u,
            &x0,
            &SimOptions::new(1e-3, 4, InputHold::Zoh).unwrap(),
        )
        .unwrap();
        let x_end = &out.states[(len - 1) * net.n_states()..len * net.n_states()];
        let relaxed = tension(&base, &base.rest_at(&u0), &held) - tension(&net, x_end, &held);
        assert!(
            (relaxed - kappa * 2.5e4 * de * scale(alpha)).abs() < 1e-3 * relaxed,
            "{stretch}: relaxed {relaxed}"
        );
        loss.push(tension(&base, &base.rest_at(&u0), &wound) - tension(&net, x_end, &wound));
    }
    let ratio = loss[1] / loss[0];
    let want = scale(alpha2) / scale(alpha);
    assert!((ratio - want).abs() < 1e-6, "{ratio} vs {want}");
}

/// A stiffness scaled about the reference keeps the tension at the run's first input and scales
/// only the change from there; where the rest leaves the cable at its pretension it is the plain
/// scaled law.
#[test]
fn a_stiffness_scale_pivots_about_the_first_stretch() {
    let base =
        Network::new(&NetworkSpec::from_json(&winch("position").to_string()).unwrap()).unwrap();
    let s = 0.4;
    let mut net = base.clone();
    net.set_stiffness_scale(0, s);
    assert_eq!(net.n_states(), base.n_states() + 1);
    assert_eq!(
        net.state_names().last().map(String::as_str),
        Some("stiffness_ref:c")
    );
    let (alpha, end) = (2.0, 1e-3);
    let u0 = [alpha, 0.0, end, 0.0];
    let (x0, xb) = (net.rest_at(&u0), base.rest_at(&u0));
    assert!(x0[x0.len() - 1] > 0.0, "the end's stretch is the reference");
    let plain = tension(&base, &xb, &u0);
    assert!((tension(&net, &x0, &u0) - plain).abs() < 1e-12 * plain);
    for de in [2e-4, -1e-4] {
        let held = [alpha, 0.0, end + de, 0.0];
        let change = tension(&base, &xb, &held) - plain;
        let got = tension(&net, &x0, &held) - plain;
        assert!(
            (got - s * change).abs() < 1e-9 * plain,
            "{got} vs {}",
            s * change
        );
    }
    // at a first input that leaves the cable at its pretension: the law scaled about zero
    let u1 = [0.0, 0.0, 0.0, 0.0];
    let x1 = net.rest_at(&u1);
    assert!(x1[x1.len() - 1].abs() < f64::MIN_POSITIVE);
    let mut scaled = base.clone();
    scaled.cable_run_mut(0).law = base.cable_run(0).law.scaled(s);
    let held = [0.0, 0.0, 3e-4, 0.0];
    let want = tension(&scaled, &scaled.rest_at(&u1), &held);
    assert!((tension(&net, &x1, &held) - want).abs() < 1e-12 * want);
}

#[test]
fn a_cables_end_motor_and_taps_are_checked() {
    let bad = |edit: &dyn Fn(&mut serde_json::Value)| {
        let mut doc = winch("torque");
        edit(&mut doc);
        match NetworkSpec::from_json(&doc.to_string()).and_then(|s| Network::new(&s)) {
            Err(CableError::Network { element, reason }) => format!("{element}: {reason}"),
            Err(e) => e.to_string(),
            Ok(_) => panic!("accepted {doc}"),
        }
    };
    let e = bad(&|d| {
        d["motors"][1]["drive"] = "torque".into();
        d["motors"][1]["inertia"] = 1e-4.into();
    });
    assert!(
        e.contains("end_motor") && e.contains("position-driven"),
        "{e}"
    );
    let e = bad(&|d| d["cables"][0]["end_motor"] = "drum".into());
    assert!(e.contains("already hauls"), "{e}");
    let e = bad(&|d| d["cables"][0]["end_motor"] = "nowhere".into());
    assert!(e.contains("nowhere"), "{e}");
    let e = bad(&|d| d["sensors"][1]["at"] = "v".into());
    assert!(e.contains("sensor \"cell\"") && e.contains("\"v\""), "{e}");
    let e = bad(&|d| d["cables"][0]["free_length"] = (-0.5).into());
    assert!(e.contains("free_length"), "{e}");
    let e = bad(&|d| d["cables"][0]["end_sense"] = 2.0.into());
    assert!(e.contains("end_sense"), "{e}");
    let e = bad(&|d| d["cables"] = serde_json::json!([]));
    assert!(e.contains("at least one cable"), "{e}");
}

/// The winch with a parallel robot's path between its last pulley and the platform: seed
/// 002's additive law with the exit wrap a measured signal, and the drum position-driven.
fn winch_with_path(law: serde_json::Value) -> Network {
    let mut doc = winch("position");
    doc["signals"] = serde_json::json!(["wrap"]);
    let mut path = serde_json::json!({
        "coefficient": 0.03, "viscous": 5.0, "guide_wrap": std::f64::consts::PI, "exit_wrap": "wrap"
    });
    for (k, v) in law.as_object().unwrap() {
        path[k] = v.clone();
    }
    doc["cables"][0]["path"] = path;
    Network::new(&NetworkSpec::from_json(&doc.to_string()).unwrap()).unwrap()
}

#[test]
fn a_path_adds_seed_002s_pulley_friction_between_the_end_and_the_routing() {
    let net = winch_with_path(serde_json::json!({"law": "coulomb", "smoothing": 1e-3}));
    // inputs: the drum's and the end's [q, q̇], then the signal
    assert_eq!(net.n_inputs(), 5);
    assert_eq!(net.input_names()[4], "signal:wrap");
    assert_eq!(net.n_states(), 0);
    let names = net.output_names();
    let (alpha, end, wrap) = (2.0, 1e-3, 1.2);
    // the platform draws the cable in (its end's rate negative): v = +0.05 m/s towards the winch
    let u = [alpha, 0.0, end, -0.05, wrap];
    let mut y = vec![0.0; net.n_outputs()];
    net.output(&[], &u, &mut y);
    let e = 0.02 * alpha + end;
    let t = (20.0 + 2.5e4 * e) * 0.8 / (0.8 - 0.02 * alpha);
    let normal = 2.0 + 2.0 * (0.5 * wrap).sin();
    let s = crate::friction::smooth_sign(0.05, 1e-3);
    let t_path = t + 0.03 * normal * t * s + 5.0 * 0.05;
    let tap = y[names.len() - 1];
    assert!(
        (y[2] - t).abs() < 1e-9 * t,
        "the elastic piece keeps its tension"
    );
    assert!((tap - t_path).abs() < 1e-9 * t, "{tap} vs {t_path}");
    // the routing's capstan acts on the path's motor side (drum at rest: its sign is 0)
    assert!((y[3] - t_path).abs() < 1e-9 * t);
    // the exit wrap moves the friction with the pose
    let u2 = [alpha, 0.0, end, -0.05, 0.0];
    net.output(&[], &u2, &mut y);
    assert!((y[names.len() - 1] - (t + 0.03 * 2.0 * t * s + 0.25)).abs() < 1e-9 * t);
}

#[test]
fn a_dahl_path_slides_to_its_level_over_its_presliding_length() {
    let x_c = 2e-3;
    let net = winch_with_path(serde_json::json!({"law": "dahl", "presliding": x_c}));
    assert_eq!(net.n_states(), 1);
    assert_eq!(net.state_names()[0], "z_path:c");
    // the platform draws the cable in at 10 mm/s from rest: z = 1 − exp(−s/x_c), s = v·t
    let (dt, steps, v, wrap) = (1e-3, 400, 0.01, 1.0);
    let mut u = Vec::new();
    for k in 0..steps {
        let end = 1e-3 - v * dt * k as f64;
        u.extend_from_slice(&[0.5, 0.0, end, -v, wrap]);
    }
    let opts = SimOptions::new(dt, 4, InputHold::Foh).unwrap();
    let traj = simulate(&net, &u, &[0.0], &opts).unwrap();
    let p = net.n_outputs();
    for k in [50, 200, 399] {
        let z = 1.0 - (-(v * dt * k as f64) / x_c).exp();
        assert!(
            (traj.states[k] - z).abs() < 1e-6,
            "z({k}) {} vs {z}",
            traj.states[k]
        );
        let y = &traj.outputs[k * p..(k + 1) * p];
        let normal = 2.0 + 2.0 * (0.5 * wrap).sin();
        let want = y[2] + 0.03 * normal * y[2] * z + 5.0 * v;
        assert!(
            (y[p - 1] - want).abs() < 1e-4 * want,
            "{} vs {want}",
            y[p - 1]
        );
    }
}

#[test]
fn a_bad_path_or_signal_is_a_typed_error_naming_it() {
    let err = |edit: &dyn Fn(&mut serde_json::Value)| {
        let mut doc = winch("position");
        doc["signals"] = serde_json::json!(["wrap"]);
        doc["cables"][0]["path"] = serde_json::json!({"coefficient": 0.03, "exit_wrap": "wrap"});
        edit(&mut doc);
        match NetworkSpec::from_json(&doc.to_string()).and_then(|s| Network::new(&s)) {
            Err(e) => e.to_string(),
            Ok(_) => panic!("accepted"),
        }
    };
    let e = err(&|d| d["cables"][0]["path"]["exit_wrap"] = "pose".into());
    assert!(e.contains("path") && e.contains("pose"), "{e}");
    let e = err(&|d| d["cables"][0]["path"]["exit_wrap"] = 7.0.into());
    assert!(e.contains("exit_wrap"), "{e}");
    let e = err(&|d| d["cables"][0]["path"]["coefficient"] = (-0.1).into());
    assert!(e.contains("coefficient"), "{e}");
    let e = err(&|d| d["cables"][0]["path"]["law"] = "lugre".into());
    assert!(e.contains("law"), "{e}");
    let e = err(&|d| d["cables"][0]["path"]["friction"] = 1.0.into());
    assert!(e.contains("unknown") && e.contains("friction"), "{e}");
    let e = err(&|d| d["signals"] = serde_json::json!(["wrap", "wrap"]));
    assert!(e.contains("signal") && e.contains("twice"), "{e}");
    let e = err(&|d| d["signals"] = serde_json::json!("wrap"));
    assert!(e.contains("signals"), "{e}");
    // a path on a tendon that turns a joint is refused
    let mut spec = finger();
    spec.cables[0].path = Some(PathSpec {
        coefficient: 0.01,
        viscous: 0.0,
        guide_wrap: 0.0,
        exit_wrap: ExitWrap::Fixed(1.0),
        law: crate::cdpr::PathLaw::Coulomb { smoothing: 1e-3 },
    });
    let (el, reason) = network_error(&spec);
    assert!(el.contains("t1") && el.contains("path"), "{el}");
    assert!(reason.contains("turns no joint"), "{reason}");
}

#[test]
fn the_rest_state_balances_the_joints_under_unequal_pretension_and_a_held_load() {
    // the test joint's cables: 10 N at 12 kN/m and 8 N at 9 kN/m on one pulley — at the
    // kinematic angle (both cables at their pretension) the joint feels 2 N · r
    let j = joint();
    let net = Network::new(&NetworkSpec::from_joint(&j).unwrap()).unwrap();
    let mut dx = vec![0.0; net.n_states()];
    for (x_m, tau_ext) in [(0.0, 0.0), (3e-4, 0.0), (-2e-4, 4e-3)] {
        let u0 = [x_m, 0.0, tau_ext];
        let x = net.rest_at(&u0);
        net.derivative(&x, &u0, &mut dx);
        // at rest: no speed, no acceleration
        assert!(x[1].abs() < f64::MIN_POSITIVE);
        assert!(dx[1].abs() * 1e-5 < 1e-10, "{}", dx[1]); // N·m (8e-3 at the kinematic angle)
                                                          // the joint sits where the two cables' tensions differ by the held load alone,
                                                          // r·(T1 − T2) = −τ_ext (closed form for the linear cables)
        let (k1, k2, t1, t2) = (12_000.0, 9_000.0, 10.0, 8.0);
        let r = j.radius;
        // stretch s = x_m − r·θ on cable 1, −s on cable 2: T1 − T2 = t1 − t2 + (k1 + k2)·s
        let s = (-tau_ext / r - (t1 - t2)) / (k1 + k2);
        let theta = (x_m - s) / r;
        assert!(
            (x[0] - theta).abs() < 1e-9 * (1.0 + theta.abs()),
            "{} vs {theta}",
            x[0]
        );
        // the kinematic angle, where the old rest started, is not at rest
        assert!((x[0] - x_m / r).abs() > 1e-3);
    }
    // a balanced pair keeps its kinematic angle exactly
    let mut even = j;
    even.ret = even.drive;
    let net = Network::new(&NetworkSpec::from_joint(&even).unwrap()).unwrap();
    let x = net.rest_at(&[3e-4, 0.0, 0.0]);
    assert!((x[0] - 3e-4 / even.radius).abs() < 1e-14);
}
