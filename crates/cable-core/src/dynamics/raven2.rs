//! The Raven-II parameter set for the first three axes (shoulder, elbow, insertion).
//!
//! Sources (the dissertation text of seed 001 lost most digits): Raven-II's public control code
//! (`include/raven/defines.h`, `fwd_cable_coupling.h`, `inv_cable_coupling.cpp`, `motor.h`,
//! `params/r2params.yaml`) and the public Raven-II dynamic simulator that uses the dissertation's
//! exact parameter set (`Li_DYN/`), as collected in the project's `raven2-parameters.md`.
//!
//! | quantity | link 1 | link 2 | link 3 | units |
//! |---|---|---|---|---|
//! | gear ratio N | 12.25 | 12.25 | 12.25 | – |
//! | capstan radius r_m | 5.675 | 5.675 | 5.675 | mm |
//! | joint radius r_l | 63.095 | 56.297 (two-stage, effective) | 1 (prismatic) | mm, mm, m/m |
//! | motor inertia I_m | 2.847e-4 | 2.847e-4 | 2.847e-4 | kg·m² (lumped fit) |
//! | motor Coulomb τ_cm | 8.11e-2 | 4.11e-2 | 5.11e-2 | N·m |
//! | motor viscous τ_vm | 1.9e-4 | 1.8e-4 | 7.1e-4 | N·m·s/rad |
//! | cable k_e (exponential law, ℓ = 1 m) | 720e3 | 88e3 | 9.25e3 | N/m |
//! | cable b_e | 4000 | 1380 | 400 | N·s/m |
//! | link Coulomb F_cl | 0.505 | 0.49 | 0.53 | N·m, N·m, N |
//! | link viscous F_vl | 0.00505 | 0.0049 | 0.0053 | N·m·s/rad, …, N·s/m |
//! | coupling | C01 = 0.14545 rad/rad, C02 = 0.0077973826 m/rad, C12 = 0.008077387 m/rad |||
//!
//! **Torque convention.** The simulator feeds the gearbox-output torque that Raven's control
//! software commands into the motor-shaft equation (2.3), so `I_m`, `τ_cm`, `τ_vm` are lumped fits
//! in that convention, not RE40 datasheet rotor values. Inputs to this model are therefore Raven
//! "gearbox-output" torques (current limit ≈ 0.68/0.68/0.54 N·m).
//!
//! **Choices made here, not in the sources** (documented so users can replace them):
//! * Link inertias are constants (the model's link dynamics are decoupled): the diagonal of the
//!   simulator's configuration-dependent mass matrix at mid-range (elbow 90°, insertion 0.40 m):
//!   0.2164 kg·m², 0.1004 kg·m², and the insertion mass 0.407 kg.
//! * Gravity is off: Raven-II is a spherical remote-centre mechanism whose gravity loads depend
//!   on all three joints and on the mounting; set `Gravity` for your mounting if needed.
//! * Pretension (not given for links 1–2): 40 N per side on links 1–2, so loops stay taut for net
//!   tensions up to 80 N; 11 N on link 3, the middle of the "Mid" category (8–14 N) of seed 001
//!   ch. 5. While both sides are taut the loop law is exactly eq. (2.6).
//! * Smoothing velocities of the Coulomb terms: 0.1 rad/s at the motors, 1e-3 rad/s at the
//!   revolute joints, 1e-4 m/s at the insertion axis.

use super::transmission::{CableTransmission, Gravity, JointKind, TransmissionLink};
use crate::cable::{CableLaw, CableLoop, CableRun};
use crate::error::{CableError, Result};
use crate::friction::StaticFriction;

/// Coupling matrix of eq. (2.8) for Raven-II (row-major 3×3; cable i, joint j).
pub const RAVEN2_COUPLING: [f64; 9] = [
    0.0,
    0.0,
    0.0,
    0.14545,
    0.0,
    0.0,
    0.007_797_382_6,
    0.008_077_387,
    0.0,
];

/// Raven-II transmission with the first `n_links` (1 to 3) axes; see the module docs.
pub fn raven2(n_links: usize) -> Result<CableTransmission> {
    if !(1..=3).contains(&n_links) {
        return Err(CableError::Shape {
            what: "raven2 links".into(),
            expected: "1 to 3 links".into(),
            got: format!("{n_links} links"),
        });
    }
    let joint_radius = [63.095e-3, 56.297e-3, 1.0];
    let kind = [
        JointKind::Revolute,
        JointKind::Revolute,
        JointKind::Prismatic,
    ];
    let tau_cm = [8.11e-2, 4.11e-2, 5.11e-2];
    let tau_vm = [1.9e-4, 1.8e-4, 7.1e-4];
    let k_e = [720e3, 88e3, 9.25e3];
    let b_e = [4000.0, 1380.0, 400.0];
    let f_cl = [0.505, 0.49, 0.53];
    let f_vl = [0.00505, 0.0049, 0.0053];
    let link_inertia = [0.2164, 0.1004, 0.407];
    let pretension = [40.0, 40.0, 11.0];
    let link_smoothing = [1e-3, 1e-3, 1e-4];
    let mut links = Vec::with_capacity(n_links);
    for i in 0..n_links {
        let p = format!("raven2.links[{i}]");
        links.push(TransmissionLink {
            motor_inertia: 2.847e-4,
            gear_ratio: 12.25,
            capstan_radius: 5.675e-3,
            motor_friction: StaticFriction::coulomb_viscous(&p, tau_cm[i], tau_vm[i], 0.1)?,
            cable: CableLoop {
                run: CableRun::new(
                    CableLaw::Exponential {
                        stiffness: k_e[i],
                        length_scale: 1.0,
                    },
                    b_e[i],
                    pretension[i],
                    &p,
                )?,
            },
            kind: kind[i],
            joint_radius: joint_radius[i],
            link_inertia: link_inertia[i],
            link_friction: StaticFriction::coulomb_viscous(
                &p,
                f_cl[i],
                f_vl[i],
                link_smoothing[i],
            )?,
            gravity: Gravity::NONE,
        });
    }
    let coupling: Vec<f64> = (0..n_links * n_links)
        .map(|k| RAVEN2_COUPLING[(k / n_links) * 3 + k % n_links])
        .collect();
    CableTransmission::new(links, &coupling)
}

#[cfg(test)]
#[allow(clippy::float_cmp)] // exact zeros are the claims under test (slack, no contact)
mod tests {
    use super::*;
    use approx::assert_relative_eq;

    #[test]
    fn transmission_matrix_matches_raven_control_code() {
        let m = raven2(3).unwrap().transmission_matrix();
        let expected = [
            136.196, 0.0, 0.0, 17.675, 121.522, 0.0, 16.831, 17.436, 2158.59,
        ];
        for (a, b) in m.iter().zip(expected.iter()) {
            assert!((a - b).abs() <= 1e-3 + 1e-5 * b.abs(), "{a} vs {b}");
        }
    }

    #[test]
    fn kinematics_round_trip() {
        let t = raven2(3).unwrap();
        let q = [0.3, 1.2, 0.4];
        let (mut m, mut back) = ([0.0; 3], [0.0; 3]);
        t.joint_to_motor(&q, &mut m);
        assert_relative_eq!(m[1], 121.522 * (1.2 + 0.14545 * 0.3), max_relative = 1e-5);
        t.motor_to_joint(&m, &mut back);
        for i in 0..3 {
            assert_relative_eq!(back[i], q[i], max_relative = 1e-12);
        }
    }

    #[test]
    fn rejects_more_than_three_links() {
        assert!(raven2(4).is_err());
        assert!(raven2(0).is_err());
        assert_eq!(raven2(2).unwrap().n_links(), 2);
    }
}
