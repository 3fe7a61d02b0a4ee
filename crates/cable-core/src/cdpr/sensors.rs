//! Cable tension sensors of seed 003 §4: the load-cell pulley (eqs 31–32), the linear
//! calibration from loading and unloading runs (eq. 33), and the signal chain between the cable
//! and the controller (the HX711's conversion, a sample-and-hold, the link's latency).
//!
//! ```text
//! load-cell pulley (eq. 31):  F_push = T·(sin α₁ + sin α₂)
//! tension range of a cell rated F_FS:  T_max = F_FS/(sin α₁ + sin α₂)   (eq. 32, see below)
//! calibration (eq. 33):       R = α·T + t₀,   T = (R − t₀)/α
//! signal chain:               reading_k = mean of T over the k-th conversion window
//!                             (t₀ + k·t_c, t₀ + (k+1)·t_c], available from its end plus the
//!                             latency, held until the next one
//! ```
//!
//! Eq. 32 as printed, `F_F.S = τ_max/(sin α₁ + sin α₂)` "for a maximum cable tension τ_max",
//! contradicts eq. 31, which gives the push at `τ_max` as `τ_max·(sin α₁ + sin α₂)`. Read with
//! eq. 31, it is the largest tension a cell rated `F_F.S` can measure (solved for `T`), which is
//! what [`LoadCellPulley::tension_range`] returns; [`LoadCellPulley::push`] is eq. 31.

use crate::error::{check, CableError, Result};

/// A load cell pushed by a small pulley that deflects the cable by the exit angles `α₁`, `α₂`.
#[derive(Debug, Clone, Copy, PartialEq)]
pub struct LoadCellPulley {
    /// Exit angle on one side `α₁` (rad), in `(0, π/2]`.
    pub angle_1: f64,
    /// Exit angle on the other side `α₂` (rad), in `(0, π/2]`.
    pub angle_2: f64,
}

impl LoadCellPulley {
    /// Validated constructor.
    pub fn new(angle_1: f64, angle_2: f64) -> Result<Self> {
        for (name, a) in [("angle_1", angle_1), ("angle_2", angle_2)] {
            if !(a.is_finite() && a > 0.0 && a <= std::f64::consts::FRAC_PI_2) {
                return Err(CableError::InvalidParameter {
                    name: name.into(),
                    value: a,
                    requirement: "in (0, pi/2] rad",
                });
            }
        }
        Ok(Self { angle_1, angle_2 })
    }

    /// `sin α₁ + sin α₂`: the push per newton of tension.
    pub fn ratio(&self) -> f64 {
        self.angle_1.sin() + self.angle_2.sin()
    }

    /// The push on the cell at cable tension `tension` (N), eq. 31.
    pub fn push(&self, tension: f64) -> Result<f64> {
        check::finite("tension", tension)?;
        finite_result("push", tension * self.ratio())
    }

    /// The largest tension a cell rated `rating` (N) measures (eq. 32 read with eq. 31).
    pub fn tension_range(&self, rating: f64) -> Result<f64> {
        check::finite("rating", rating)?;
        finite_result("tension range", rating / self.ratio())
    }
}

/// `value`, or an error naming `what` when finite input overflowed.
fn finite_result(what: &str, value: f64) -> Result<f64> {
    if value.is_finite() {
        Ok(value)
    } else {
        Err(CableError::NonFiniteResult {
            what: what.into(),
            index: 0,
            value,
            location: String::new(),
            hint: "the input is too large for the pulley's ratio",
        })
    }
}

/// A linear calibration `R = α·T + t₀` (eq. 33).
#[derive(Debug, Clone, Copy, PartialEq)]
pub struct Calibration {
    /// Reading per newton `α` (reading units/N), non-zero.
    pub gain: f64,
    /// Reading at zero tension `t₀`.
    pub offset: f64,
}

/// A calibration fitted to loading and unloading runs, and how well the line holds.
#[derive(Debug, Clone, PartialEq)]
pub struct CalibrationFit {
    /// The least-squares line through every point.
    pub calibration: Calibration,
    /// Pearson correlation of readings and loads (the seed reports > 0.9994).
    pub correlation: f64,
    /// RMS of the tension residuals `T − (R − t₀)/α` (N).
    pub residual_rms: f64,
    /// Largest residual (N).
    pub residual_max: f64,
    /// Largest difference, at a load met both ways, between the unloading and the loading
    /// readings, in newtons (`(R_down − R_up)/α`: positive when unloading reads high); 0 without
    /// a load met both ways.
    pub hysteresis: f64,
    /// `hysteresis` as a fraction of the calibrated span (largest minus smallest load).
    pub hysteresis_fraction: f64,
}

impl Calibration {
    /// Validated constructor.
    pub fn new(gain: f64, offset: f64) -> Result<Self> {
        check::finite("gain", gain)?;
        check::finite("offset", offset)?;
        if gain.abs() < f64::MIN_POSITIVE {
            return Err(CableError::InvalidParameter {
                name: "gain".into(),
                value: gain,
                requirement: "non-zero",
            });
        }
        Ok(Self { gain, offset })
    }

    /// The tension (N) of a reading (eq. 33).
    pub fn tension(&self, reading: f64) -> f64 {
        (reading - self.offset) / self.gain
    }

    /// The tensions (N) of finite `readings`; an error where one overflows.
    pub fn tensions(&self, readings: &[f64]) -> Result<Vec<f64>> {
        check::all_finite("readings", readings, readings.len())?;
        let out: Vec<f64> = readings.iter().map(|&r| self.tension(r)).collect();
        if let Some((index, &value)) = out.iter().enumerate().find(|(_, v)| !v.is_finite()) {
            return Err(CableError::NonFiniteResult {
                what: "tension".into(),
                index,
                value,
                location: String::new(),
                hint: "the reading is too far from the offset for this gain",
            });
        }
        Ok(out)
    }

    /// The reading of a tension.
    pub fn reading(&self, tension: f64) -> f64 {
        self.gain * tension + self.offset
    }

    /// Fits the line to a loading run and an unloading run, `(loads N, readings)` each (either
    /// may be empty, together at least two distinct loads); loads met in both runs (equal to
    /// 1e-9 of the span) give the hysteresis.
    pub fn fit(loading: (&[f64], &[f64]), unloading: (&[f64], &[f64])) -> Result<CalibrationFit> {
        for (what, (t, r)) in [("loading", loading), ("unloading", unloading)] {
            check::len(&format!("{what} readings"), r, t.len())?;
            check::all_finite(&format!("{what} loads"), t, t.len())?;
            check::all_finite(&format!("{what} readings"), r, r.len())?;
        }
        let loads: Vec<f64> = loading.0.iter().chain(unloading.0).copied().collect();
        let reads: Vec<f64> = loading.1.iter().chain(unloading.1).copied().collect();
        let n = loads.len() as f64;
        // centred sums, scaled by the largest magnitudes so that squares cannot overflow
        let scale_t = loads
            .iter()
            .fold(0.0_f64, |m, v| m.max(v.abs()))
            .max(f64::MIN_POSITIVE);
        let scale_r = reads
            .iter()
            .fold(0.0_f64, |m, v| m.max(v.abs()))
            .max(f64::MIN_POSITIVE);
        let mt = loads.iter().map(|v| v / scale_t).sum::<f64>() / n;
        let mr = reads.iter().map(|v| v / scale_r).sum::<f64>() / n;
        let (mut stt, mut srr, mut str_) = (0.0, 0.0, 0.0);
        for (t, r) in loads.iter().zip(&reads) {
            let (dt, dr) = (t / scale_t - mt, r / scale_r - mr);
            stt += dt * dt;
            srr += dr * dr;
            str_ += dt * dr;
        }
        let span = loads.iter().fold(f64::NEG_INFINITY, |m, &v| m.max(v))
            - loads.iter().fold(f64::INFINITY, |m, &v| m.min(v));
        // (finite by the checks above)
        if loads.len() < 2 || span <= 0.0 || srr <= 0.0 {
            return Err(CableError::InvalidParameter {
                name: "calibration loads".into(),
                value: loads.len() as f64,
                requirement: "at least two distinct loads and readings that vary",
            });
        }
        let gain = str_ / stt * scale_r / scale_t;
        let offset = (mr - str_ / stt * mt) * scale_r;
        let calibration = Calibration::new(gain, offset)?;
        let res: Vec<f64> = loads
            .iter()
            .zip(&reads)
            .map(|(t, r)| t - calibration.tension(*r))
            .collect();
        let residual_rms = (res.iter().map(|v| v * v).sum::<f64>() / n).sqrt();
        let residual_max = res.iter().fold(0.0_f64, |m, v| m.max(v.abs()));
        let mut hysteresis: f64 = 0.0;
        for (tu, ru) in loading.0.iter().zip(loading.1) {
            for (td, rd) in unloading.0.iter().zip(unloading.1) {
                if (tu - td).abs() <= 1e-9 * span {
                    let h = (rd - ru) / gain;
                    if h.abs() > hysteresis.abs() {
                        hysteresis = h;
                    }
                }
            }
        }
        let fit = CalibrationFit {
            calibration,
            correlation: str_ / (stt * srr).sqrt(),
            residual_rms,
            residual_max,
            hysteresis,
            hysteresis_fraction: hysteresis / span,
        };
        check::all_finite(
            "calibration fit",
            &[fit.correlation, residual_rms, residual_max, hysteresis],
            4,
        )
        .map_err(|_| CableError::NonFiniteResult {
            what: "calibration fit".into(),
            index: 0,
            value: f64::NAN,
            location: String::new(),
            hint: "the loads or readings span too many orders of magnitude",
        })?;
        Ok(fit)
    }
}

/// The path from the strain gauge to the controller: an integrating converter (the HX711 at 10
/// samples/s converts over 100 ms), a sample-and-hold until the next conversion, and a latency
/// (a BLE notification: 30 ms or more).
#[derive(Debug, Clone, Copy, PartialEq)]
pub struct SignalChain {
    /// Conversion time `t_c` (s), > 0: one reading per `t_c`, the mean over its window.
    pub conversion_time: f64,
    /// Delay from the end of a conversion to the controller (s), ≥ 0.
    pub latency: f64,
}

/// At most this many conversions per call (a bound on the work).
pub const MAX_CONVERSIONS: usize = 10_000_000;

impl SignalChain {
    /// Validated constructor.
    pub fn new(conversion_time: f64, latency: f64) -> Result<Self> {
        Ok(Self {
            conversion_time: check::positive("conversion_time", conversion_time)?,
            latency: check::non_negative("latency", latency)?,
        })
    }

    /// The HX711 at 10 samples/s (100 ms) behind a BLE link (30 ms), seed 003 §4.2.
    pub fn hx711_ble() -> Self {
        Self {
            conversion_time: 0.1,
            latency: 0.03,
        }
    }

    /// What the controller sees at the times `t` (strictly increasing, s) of a signal sampled
    /// there: each conversion's window mean (of the samples in it; the window's last sample
    /// when none falls inside), held from its end plus the latency. Before the first reading
    /// arrives the controller sees `signal[0]` (the sensor settled before the run).
    pub fn apply(&self, t: &[f64], signal: &[f64]) -> Result<Vec<f64>> {
        check::len("signal", signal, t.len())?;
        check::all_finite("t", t, t.len())?;
        check::all_finite("signal", signal, signal.len())?;
        if let Some(k) = t.windows(2).position(|w| w[1] <= w[0]) {
            return Err(CableError::InvalidParameter {
                name: format!("t[{}]", k + 1),
                value: t[k + 1],
                requirement: "strictly increasing",
            });
        }
        let Some((&t0, &t_end)) = t.first().zip(t.last()) else {
            return Ok(Vec::new());
        };
        let windows = ((t_end - t0) / self.conversion_time).ceil();
        // (an overflowing span gives inf, never NaN: the times are finite)
        if windows > MAX_CONVERSIONS as f64 {
            return Err(CableError::InvalidParameter {
                name: "conversion_time".into(),
                value: self.conversion_time,
                requirement: "at most 1e7 conversions over the run",
            });
        }
        // window means, in order: window k is (t0 + k·t_c, t0 + (k+1)·t_c]; boundaries to within
        // 1e-9 of t_c, so that samples on a multiple of t_c fall where they were meant to
        let tol = 1e-9 * self.conversion_time;
        let mut means = Vec::with_capacity(windows as usize + 1);
        let (mut i, mut k) = (1usize, 0usize);
        let mut last = signal[0];
        while i < t.len() {
            let end = t0 + (k + 1) as f64 * self.conversion_time;
            // (a running mean: a sum of finite samples can overflow, their mean cannot)
            let (mut mean, mut count) = (0.0, 0usize);
            while i < t.len() && t[i] <= end + tol {
                count += 1;
                mean += (signal[i] - mean) / count as f64;
                last = signal[i];
                i += 1;
            }
            means.push(if count > 0 { mean } else { last });
            k += 1;
        }
        // hold: at time τ the newest window whose end plus the latency is ≤ τ
        let mut out = Vec::with_capacity(t.len());
        let mut seen = signal[0];
        let mut next = 0usize;
        for &tau in t {
            while next < means.len()
                && t0 + (next + 1) as f64 * self.conversion_time + self.latency <= tau + tol
            {
                seen = means[next];
                next += 1;
            }
            out.push(seen);
        }
        Ok(out)
    }
}

#[cfg(test)]
mod tests {
    use super::*;

    #[test]
    fn load_cell_pulley_push_and_range() {
        let s = LoadCellPulley::new(0.1, 0.2).unwrap();
        let ratio = 0.1_f64.sin() + 0.2_f64.sin();
        assert!((s.push(50.0).unwrap() - 50.0 * ratio).abs() < 1e-12);
        assert!((s.tension_range(s.push(50.0).unwrap()).unwrap() - 50.0).abs() < 1e-12);
        let wide = LoadCellPulley::new(1.5, 1.5).unwrap();
        assert!(wide.push(f64::MAX).is_err() && s.push(f64::NAN).is_err());
        assert!(LoadCellPulley::new(1e-3, 1e-3)
            .unwrap()
            .tension_range(f64::MAX)
            .is_err());
        for bad in [0.0, -0.1, 2.0, f64::NAN] {
            assert!(LoadCellPulley::new(bad, 0.2).is_err());
        }
    }

    /// Hand-computed: readings 2·T + 5 plus a loop that reads 0.3 high on the way down.
    #[test]
    fn calibration_recovers_the_line_and_reports_the_loop() {
        let up_t = [1.0, 2.0, 3.0, 4.0];
        let up_r: Vec<f64> = up_t.iter().map(|t| 2.0 * t + 5.0).collect();
        let dn_t = [4.0, 3.0, 2.0, 1.0];
        let dn_r: Vec<f64> = dn_t.iter().map(|t| 2.0 * t + 5.0 + 0.3).collect();
        let fit = Calibration::fit((&up_t, &up_r), (&dn_t, &dn_r)).unwrap();
        // least squares through both: slope 2, intercept 5.15
        assert!((fit.calibration.gain - 2.0).abs() < 1e-12, "{fit:?}");
        assert!((fit.calibration.offset - 5.15).abs() < 1e-12, "{fit:?}");
        // every residual is ±0.15/2 N; the loop 0.3/2 = 0.15 N, 5 % of the 3 N span
        assert!((fit.residual_rms - 0.075).abs() < 1e-12);
        assert!((fit.hysteresis - 0.15).abs() < 1e-12);
        assert!((fit.hysteresis_fraction - 0.05).abs() < 1e-12);
        assert!(fit.correlation > 0.99 && fit.correlation < 1.0);
        let c = fit.calibration;
        assert!((c.tension(c.reading(3.3)) - 3.3).abs() < 1e-12);
        let tiny = Calibration::new(1e-300, 0.0).unwrap();
        assert!(tiny.tensions(&[1.0]).is_ok() && tiny.tensions(&[1e10]).is_err());
        assert!(c.tensions(&[f64::NAN]).is_err());
        // one load only, or flat readings: a typed error
        assert!(Calibration::fit((&[1.0, 1.0], &[2.0, 3.0]), (&[], &[])).is_err());
        assert!(Calibration::fit((&[1.0, 2.0], &[3.0, 3.0]), (&[], &[])).is_err());
        assert!(Calibration::fit((&[1.0, 2.0], &[3.0]), (&[], &[])).is_err());
        assert!(Calibration::fit((&[1.0, f64::NAN], &[3.0, 4.0]), (&[], &[])).is_err());
    }

    /// A step through the HX711 and a BLE link: the first reading after the step is the window
    /// mean (part old, part new), and it arrives at the window's end plus the latency.
    #[test]
    fn signal_chain_averages_holds_and_delays() {
        let chain = SignalChain::hx711_ble();
        let t: Vec<f64> = (0..=1000).map(|k| k as f64 * 1e-3).collect();
        let signal: Vec<f64> = t
            .iter()
            .map(|&s| if s > 0.25 { 10.0 } else { 0.0 })
            .collect();
        let out = chain.apply(&t, &signal).unwrap();
        let at = |s: f64| out[(s * 1e3).round() as usize];
        // window (0.2, 0.3]: 50 samples at 0, 50 at 10 → 5, seen from 0.33 s on
        assert!(at(0.329).abs() < 1e-12);
        assert!((at(0.33) - 5.0).abs() < 1e-12);
        assert!((at(0.429) - 5.0).abs() < 1e-12);
        assert!((at(0.43) - 10.0).abs() < 1e-12);
        // a signal constant from the start reads the same all along
        let flat = chain.apply(&t, &vec![3.0; t.len()]).unwrap();
        assert!(flat.iter().all(|v| (v - 3.0).abs() < 1e-12));
        assert!(chain.apply(&[0.0, 0.0], &[1.0, 2.0]).is_err());
        assert!(SignalChain::new(1e-300, 0.0)
            .unwrap()
            .apply(&[0.0, 1.0], &[1.0, 2.0])
            .is_err());
        assert!(SignalChain::new(0.0, 0.0).is_err());
        assert!(SignalChain::new(0.1, -0.01).is_err());
        assert!(chain.apply(&[], &[]).unwrap().is_empty());
        // the largest finite samples average to themselves (a plain sum would overflow)
        let huge = chain.apply(&t, &vec![1e308; t.len()]).unwrap();
        assert!(huge.iter().all(|v| (v - 1e308).abs() < 1e293));
    }
}
