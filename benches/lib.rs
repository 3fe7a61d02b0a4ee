//! Shared fixtures for the criterion benches (`dynamics.rs`, `srukf.rs`, `nn.rs`).
#![allow(missing_docs)]

use cable_core::dynamics::{raven2, CableTransmission, Model};

/// The Raven-II 3-link model at a taut, moving state with a torque input.
pub fn raven_fixture() -> (CableTransmission, Vec<f64>, Vec<f64>) {
    let model = raven2(3).expect("shipped parameter set is valid");
    let q_l = [0.7, 1.5, 0.4];
    let mut q_m = [0.0; 3];
    model.joint_to_motor(&q_l, &mut q_m);
    let mut x = vec![0.0; model.n_states()];
    for i in 0..3 {
        x[4 * i] = q_m[i] + 0.01;
        x[4 * i + 1] = 5.0;
        x[4 * i + 2] = q_l[i];
        x[4 * i + 3] = 0.03;
    }
    let u = vec![0.1, -0.05, 0.2, 0.0, 0.0, 0.0];
    (model, x, u)
}

/// A `sizes` network (tansig hidden layers, linear output) with fixed pseudo-random weights,
/// as the PSO-BPNN paper's 4-10-4 (seed 000, Table 1).
pub fn mlp_fixture(sizes: &[usize]) -> cable_core::nn::Mlp {
    use cable_core::nn::{Activation, Layer, MapMinMax, Mlp, MlpInfo};
    let mut s: u64 = 0x9E37_79B9_7F4A_7C15;
    let mut next = move || {
        s = s
            .wrapping_mul(6_364_136_223_846_793_005)
            .wrapping_add(1_442_695_040_888_963_407);
        ((s >> 11) as f64 / (1u64 << 53) as f64) * 2.0 - 1.0
    };
    let last = sizes.len() - 2;
    let layers = (0..sizes.len() - 1)
        .map(|l| Layer {
            weight: (0..sizes[l] * sizes[l + 1]).map(|_| next()).collect(),
            bias: (0..sizes[l + 1]).map(|_| next()).collect(),
            n_in: sizes[l],
            n_out: sizes[l + 1],
            activation: if l == last {
                Activation::Purelin
            } else {
                Activation::Tansig
            },
        })
        .collect();
    let (n0, nl) = (sizes[0], sizes[sizes.len() - 1]);
    Mlp::new(
        layers,
        MapMinMax::new(vec![-1.0; n0], vec![1.0; n0]),
        MapMinMax::new(vec![0.0; nl], vec![20.0; nl]),
        MlpInfo::default(),
    )
    .expect("fixture network is valid")
}

/// The IPAnema-like 8-cable robot of `python/cablekit/cdpr/robots/ipanema_like.toml` (the same
/// numbers; `tests/test_cdpr.py` loads the file), and `count` poses spread over the central
/// 70 % of its frame with rotations up to 0.1 rad.
pub fn ipanema_fixture(count: usize) -> (cable_core::cdpr::Robot, Vec<f64>) {
    use cable_core::cdpr::{Cable, Motion, Platform, Robot};
    let corners = [(-1.0, -1.0), (1.0, -1.0), (1.0, 1.0), (-1.0, 1.0)];
    let mut cables = Vec::new();
    for (z, pz) in [(0.0, 0.15), (3.0, -0.15)] {
        for &(sx, sy) in &corners {
            cables.push(Cable {
                anchor: [2.0 * sx, 1.5 * sy, z],
                attachment: [0.15 * sx, 0.2 * sy, pz],
                f_min: 10.0,
                f_max: 3000.0,
                ea: 30e9 * 2.827e-5,
                pulley: None,
            });
        }
    }
    let platform = Platform {
        mass: 10.0,
        com: [0.0; 3],
        inertia: [0.2083, 0.0, 0.0, 0.0, 0.15, 0.0, 0.0, 0.0, 0.2083],
    };
    let robot = Robot::new(
        "ipanema-like",
        Motion::Spatial,
        cables,
        platform,
        [0.0, 0.0, -9.80665],
    )
    .expect("the fixture is valid");
    let mut s: u64 = 0x2545_F491_4F6C_DD1D;
    let mut next = move || {
        s ^= s << 13;
        s ^= s >> 7;
        s ^= s << 17;
        (s >> 11) as f64 / (1u64 << 53) as f64 * 2.0 - 1.0
    };
    let poses = (0..count)
        .flat_map(|_| {
            [
                1.4 * next(),
                1.05 * next(),
                1.5 + 1.05 * next(),
                0.1 * next(),
                0.1 * next(),
                0.1 * next(),
            ]
        })
        .collect();
    (robot, poses)
}
