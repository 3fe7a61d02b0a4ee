//! Clamping force of a two-forceps cable-driven end-effector (seed 000 §2.3): the joint torque
//! disturbance observer (JTDO) and the clamping-force estimator.
//!
//! Each forceps `A`, `B` is a yaw joint pulled by a drive cable (`1`) and a return cable (`2`)
//! over an effective radius `r₂`; motor-side sensors measure the four tensions
//! `F_M = [F_A¹, F_A², F_B¹, F_B²]` (seed 000 eq. 1). A free-motion model (a network trained on
//! runs without contact, or a physics model) predicts the tensions `F̂_E` the same motor motion
//! would need with nothing in the jaws. Then, per sample:
//!
//! ```text
//! F̂_D   = F_M − F̂_E                                   (eq. 8)
//! τ̂_aD  = r₂·(F̂_AD¹ − F̂_AD²),  τ̂_bD = r₂·(F̂_BD¹ − F̂_BD²)  (eq. 15)
//! F̂_ext = [τ̂_aD / l_eA, τ̂_bD / l_eB] − bias            (eq. 16, bias: a calibration group's
//!                                                        mean errors, seed 000 §3.3)
//! F̂_CF  = ½·(|F̂_ext^A| + |F̂_ext^B|)                    (eq. 17)
//! ```
//!
//! and a forceps is in contact when `|F̂_ext|` exceeds the collision threshold (seed 000: 0.11 N).

pub mod drive;
pub mod physics;
pub mod twin;

use crate::error::{check, CableError, Result};

/// The collision threshold of seed 000 §3.3 (N): the detection resolution it measured.
pub const SEED_THRESHOLD: f64 = 0.11;

/// Lever geometry of the two forceps (m).
#[derive(Debug, Clone, Copy, PartialEq)]
pub struct Geometry {
    /// Effective drive radius `r₂` of both yaw joints (m).
    pub r2: f64,
    /// Arm `l_eA` of the external force on forceps A (m).
    pub arm_a: f64,
    /// Arm `l_eB` of the external force on forceps B (m).
    pub arm_b: f64,
}

/// One sample of the observer.
#[derive(Debug, Clone, Copy, PartialEq)]
pub struct Clamp {
    /// Cable tension disturbances `F̂_D` (N), eq. 8.
    pub disturbance: [f64; 4],
    /// Joint torque disturbances `[τ̂_aD, τ̂_bD]` (N·m), eq. 15.
    pub torque: [f64; 2],
    /// External forces `[F̂_ext^A, F̂_ext^B]` (N), eq. 16, bias removed.
    pub external: [f64; 2],
    /// Clamping force `F̂_CF` (N), eq. 17.
    pub clamping: f64,
    /// `|F̂_ext|` above the collision threshold, per forceps.
    pub contact: [bool; 2],
}

/// Outputs of [`Jtdo::estimate_batch`], row-major, one row per sample.
#[derive(Debug)]
pub struct ClampMut<'a> {
    /// `(T, 4)` tension disturbances.
    pub disturbance: &'a mut [f64],
    /// `(T, 2)` joint torque disturbances.
    pub torque: &'a mut [f64],
    /// `(T, 2)` external forces.
    pub external: &'a mut [f64],
    /// `(T,)` clamping forces.
    pub clamping: &'a mut [f64],
    /// `(T, 2)` contact flags.
    pub contact: &'a mut [bool],
}

/// [`Jtdo::estimate_log`]'s owned outputs, row-major like [`ClampMut`]'s.
#[derive(Debug, Clone, PartialEq)]
pub struct ClampLog {
    /// Samples `T`.
    pub len: usize,
    /// `(T, 4)` tension disturbances (N).
    pub disturbance: Vec<f64>,
    /// `(T, 2)` joint torque disturbances (N·m).
    pub torque: Vec<f64>,
    /// `(T, 2)` external forces (N).
    pub external: Vec<f64>,
    /// `(T,)` clamping forces (N).
    pub clamping: Vec<f64>,
    /// `(T, 2)` contact flags.
    pub contact: Vec<bool>,
}

/// The joint torque disturbance observer with the clamping-force estimator (eqs 8, 15–17).
#[derive(Debug, Clone, Copy, PartialEq)]
pub struct Jtdo {
    geometry: Geometry,
    threshold: f64,
    bias: [f64; 2],
}

impl Jtdo {
    /// An observer for `geometry` (every length finite and > 0) that flags contact above
    /// `threshold` (N, finite and ≥ 0) and subtracts `bias` (N, the mean errors of
    /// `[F̂_ext^A, F̂_ext^B]` on a calibration group; zeros for none).
    pub fn new(geometry: Geometry, threshold: f64, bias: [f64; 2]) -> Result<Self> {
        check::positive("r2", geometry.r2)?;
        check::positive("arm_a", geometry.arm_a)?;
        check::positive("arm_b", geometry.arm_b)?;
        check::non_negative("threshold", threshold)?;
        check::finite("bias[0]", bias[0])?;
        check::finite("bias[1]", bias[1])?;
        Ok(Self {
            geometry,
            threshold,
            bias,
        })
    }

    /// The geometry.
    pub fn geometry(&self) -> Geometry {
        self.geometry
    }

    /// The collision threshold (N).
    pub fn threshold(&self) -> f64 {
        self.threshold
    }

    /// The bias removed from the external forces (N).
    pub fn bias(&self) -> [f64; 2] {
        self.bias
    }

    /// The same observer with another bias (a calibration's mean errors).
    pub fn with_bias(&self, bias: [f64; 2]) -> Result<Self> {
        Self::new(self.geometry, self.threshold, bias)
    }

    /// The same observer with the bias of a calibration group (seed 000 §3.3): the mean errors
    /// `mean(F̂_ext − F_ext)` of this observer without bias over rows of `measured`, `free`
    /// (`(T, 4)`) against the known external forces `external` (`(T, 2)`, N), `T ≥ 1`.
    pub fn calibrated(&self, measured: &[f64], free: &[f64], external: &[f64]) -> Result<Self> {
        let t = measured.len() / 4;
        if t == 0 || external.len() != 2 * t {
            return Err(CableError::Shape {
                what: "calibration forces".into(),
                expected: format!("({t}, 2) with at least one sample"),
                got: format!("{} values", external.len()),
            });
        }
        check::all_finite("calibration forces", external, 2)?;
        let plain = Self::new(self.geometry, self.threshold, [0.0; 2])?;
        let e = plain.estimate_log(measured, free)?.external;
        let mut bias = [0.0; 2];
        for (row, truth) in e.as_chunks::<2>().0.iter().zip(external.as_chunks::<2>().0) {
            bias[0] += row[0] - truth[0];
            bias[1] += row[1] - truth[1];
        }
        self.with_bias(bias.map(|b| b / t as f64))
    }

    /// One sample from the measured tensions `F_M` and the free-motion tensions `F̂_E` (N, in
    /// the order `[A drive, A return, B drive, B return]`). No allocation; a non-finite input
    /// is an error naming it, and so is a result that overflows.
    pub fn estimate(&self, measured: &[f64; 4], free: &[f64; 4]) -> Result<Clamp> {
        check::all_finite("measured tensions", measured, 1)?;
        check::all_finite("free-motion tensions", free, 1)?;
        let c = self.kernel(measured, free);
        check::result_finite(
            "clamping force",
            &[
                c.torque[0],
                c.torque[1],
                c.external[0],
                c.external[1],
                c.clamping,
            ],
            1,
            "the tensions are too large for the forceps' geometry",
        )?;
        Ok(c)
    }

    /// eqs 8, 15–17 of finite inputs.
    #[inline]
    fn kernel(&self, measured: &[f64; 4], free: &[f64; 4]) -> Clamp {
        let d: [f64; 4] = std::array::from_fn(|i| measured[i] - free[i]);
        let Geometry { r2, arm_a, arm_b } = self.geometry;
        let torque = [r2 * (d[0] - d[1]), r2 * (d[2] - d[3])];
        let external = [
            torque[0] / arm_a - self.bias[0],
            torque[1] / arm_b - self.bias[1],
        ];
        Clamp {
            disturbance: d,
            torque,
            external,
            clamping: 0.5 * (external[0].abs() + external[1].abs()),
            contact: [
                external[0].abs() > self.threshold,
                external[1].abs() > self.threshold,
            ],
        }
    }

    /// [`Jtdo::estimate_batch`] into buffers it allocates.
    pub fn estimate_log(&self, measured: &[f64], free: &[f64]) -> Result<ClampLog> {
        let t = measured.len() / 4;
        let mut log = ClampLog {
            len: t,
            disturbance: vec![0.0; 4 * t],
            torque: vec![0.0; 2 * t],
            external: vec![0.0; 2 * t],
            clamping: vec![0.0; t],
            contact: vec![false; 2 * t],
        };
        let out = ClampMut {
            disturbance: &mut log.disturbance,
            torque: &mut log.torque,
            external: &mut log.external,
            clamping: &mut log.clamping,
            contact: &mut log.contact,
        };
        self.estimate_batch(measured, free, out)?;
        Ok(log)
    }

    /// [`Jtdo::estimate`] for every row of `measured` and `free` (`(T, 4)` each, row-major)
    /// into `out`. Shapes and finiteness are checked first (errors name the row and column, and
    /// leave `out` untouched).
    pub fn estimate_batch(&self, measured: &[f64], free: &[f64], out: ClampMut<'_>) -> Result<()> {
        if !measured.len().is_multiple_of(4) {
            return Err(CableError::Shape {
                what: "measured tensions".into(),
                expected: "(T, 4)".into(),
                got: format!("{} values", measured.len()),
            });
        }
        let t = measured.len() / 4;
        for (what, len, want) in [
            ("free-motion tensions", free.len(), 4 * t),
            ("disturbance buffer", out.disturbance.len(), 4 * t),
            ("torque buffer", out.torque.len(), 2 * t),
            ("external buffer", out.external.len(), 2 * t),
            ("clamping buffer", out.clamping.len(), t),
            ("contact buffer", out.contact.len(), 2 * t),
        ] {
            if len != want {
                return Err(CableError::Shape {
                    what: what.into(),
                    expected: format!("{want} values ({t} samples)"),
                    got: format!("{len}"),
                });
            }
        }
        check::all_finite("measured tensions", measured, 4)?;
        check::all_finite("free-motion tensions", free, 4)?;
        for (k, (m, f)) in measured
            .as_chunks::<4>()
            .0
            .iter()
            .zip(free.as_chunks::<4>().0)
            .enumerate()
        {
            let c = self.kernel(m, f);
            out.disturbance[4 * k..4 * k + 4].copy_from_slice(&c.disturbance);
            out.torque[2 * k..2 * k + 2].copy_from_slice(&c.torque);
            out.external[2 * k..2 * k + 2].copy_from_slice(&c.external);
            out.clamping[k] = c.clamping;
            out.contact[2 * k..2 * k + 2].copy_from_slice(&c.contact);
        }
        check::result_finite(
            "external forces",
            out.external,
            2,
            "the tensions are too large for the forceps' geometry",
        )?;
        check::result_finite(
            "clamping forces",
            out.clamping,
            1,
            "the tensions are too large for the forceps' geometry",
        )
    }
}

#[cfg(test)]
mod tests {
    use super::*;

    fn observer() -> Jtdo {
        let g = Geometry {
            r2: 4e-3,
            arm_a: 12e-3,
            arm_b: 14e-3,
        };
        Jtdo::new(g, 0.11, [0.0, 0.0]).unwrap()
    }

    /// A known jaw force shows up through the tension difference it causes: a force `F` on
    /// forceps A at arm `l` needs `F·l/r₂` more drive than return tension.
    #[test]
    fn a_known_jaw_force_is_recovered_with_its_sign_arm_and_half() {
        let j = observer();
        let free = [12.0, 7.0, 14.0, 6.0];
        let (fa, fb) = (0.8, -0.5);
        let g = j.geometry();
        let measured = [
            free[0] + 0.5 * fa * g.arm_a / g.r2,
            free[1] - 0.5 * fa * g.arm_a / g.r2,
            free[2] + 0.5 * fb * g.arm_b / g.r2,
            free[3] - 0.5 * fb * g.arm_b / g.r2,
        ];
        let c = j.estimate(&measured, &free).unwrap();
        assert!((c.external[0] - fa).abs() < 1e-12);
        assert!((c.external[1] - fb).abs() < 1e-12);
        assert!((c.clamping - 0.5 * (fa.abs() + fb.abs())).abs() < 1e-12);
        assert_eq!(c.contact, [true, true]);
        // a calibration on this sample finds the error a wrong arm leaves
        let wrong = Jtdo::new(
            Geometry {
                arm_a: 1.25 * g.arm_a,
                ..g
            },
            0.11,
            [0.0; 2],
        )
        .unwrap();
        let cal = wrong
            .calibrated(&measured, &free, &[fa, fb])
            .unwrap()
            .bias();
        assert!((cal[0] - (fa / 1.25 - fa)).abs() < 1e-12 && cal[1].abs() < 1e-12);
        // the bias is removed; below the threshold there is no contact
        let b = j.with_bias([fa - 0.05, fb + 0.05]).unwrap();
        let c = b.estimate(&measured, &free).unwrap();
        assert!((c.external[0] - 0.05).abs() < 1e-12);
        assert_eq!(c.contact, [false, false]);
    }

    #[test]
    fn batch_equals_one_sample_at_a_time_and_bad_input_is_named() {
        let j = observer();
        let t = 50;
        let measured: Vec<f64> = (0..4 * t).map(|i| 10.0 + (i as f64 * 0.37).sin()).collect();
        let free: Vec<f64> = (0..4 * t).map(|i| 10.0 + (i as f64 * 0.11).cos()).collect();
        let log = j.estimate_log(&measured, &free).unwrap();
        let (e, cf, ct) = (&log.external, &log.clamping, &log.contact);
        for k in 0..t {
            let m: [f64; 4] = measured[4 * k..4 * k + 4].try_into().unwrap();
            let f: [f64; 4] = free[4 * k..4 * k + 4].try_into().unwrap();
            let c = j.estimate(&m, &f).unwrap();
            assert_eq!(
                c.external.map(f64::to_bits),
                [e[2 * k].to_bits(), e[2 * k + 1].to_bits()]
            );
            assert_eq!(c.clamping.to_bits(), cf[k].to_bits());
            assert_eq!(c.contact, [ct[2 * k], ct[2 * k + 1]]);
        }
        let mut bad = measured.clone();
        bad[4 * 7 + 2] = f64::NAN;
        let err = j.estimate_log(&bad, &free).unwrap_err().to_string();
        assert!(err.contains("row 7, column 2"), "{err}");
        assert!(j.estimate_log(&measured[..8], &free).is_err());
        let (mut short, mut ok) = (vec![0.0; 4], vec![0.0; 2 * t]);
        let out = ClampMut {
            disturbance: &mut short,
            torque: &mut ok.clone(),
            external: &mut ok,
            clamping: &mut vec![0.0; t],
            contact: &mut vec![false; 2 * t],
        };
        assert!(j.estimate_batch(&measured, &free, out).is_err());
        for g in [
            Geometry {
                r2: 0.0,
                arm_a: 1.0,
                arm_b: 1.0,
            },
            Geometry {
                r2: 1.0,
                arm_a: -1.0,
                arm_b: 1.0,
            },
            Geometry {
                r2: 1.0,
                arm_a: 1.0,
                arm_b: f64::INFINITY,
            },
        ] {
            assert!(Jtdo::new(g, 0.1, [0.0; 2]).is_err());
        }
        assert!(Jtdo::new(j.geometry(), -0.1, [0.0; 2]).is_err());
        assert!(Jtdo::new(j.geometry(), 0.1, [f64::NAN, 0.0]).is_err());
        // finite tensions whose disturbance overflows are an error, not an inf
        let huge = [f64::MAX, -f64::MAX, 0.0, 0.0];
        assert!(j.estimate(&huge, &[0.0; 4]).is_err());
    }
}
