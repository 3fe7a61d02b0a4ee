//! Operators on uniformly sampled signals: the input-side and sensor-side effects of the
//! diagnosis (backlash, delay, sensor lag, sample-and-hold, gain and bias), and the velocity of a
//! sampled position.
//!
//! All operate on one channel `x[k]`, `k = 0..T`, sample interval `dt`, and write `y` of the same
//! length. They are causal except [`velocity`] (central differences).

/// Backlash (play operator) of half-width `δ ≥ 0`: the output follows the input only once the
/// input has crossed the dead band, `y_k = clamp(y_{k−1}, x_k − δ, x_k + δ)`, starting centred
/// (`y_0 = x_0`). A motor-side play in the cable drive shifts the transmitted position by `∓δ`
/// after each reversal.
pub fn play(x: &[f64], half_width: f64, y: &mut [f64]) {
    let mut prev = x.first().copied().unwrap_or(0.0);
    for (yk, &xk) in y.iter_mut().zip(x) {
        prev = prev.clamp(xk - half_width, xk + half_width);
        *yk = prev;
    }
}

/// Pure delay by `d ≥ 0` seconds: `y(t) = x(t − d)`, interpolated between samples by the cubic
/// Catmull–Rom spline (exact for quadratics; linear interpolation's `h²/8·ẍ` error is at the
/// noise level of a geared motor's encoder), samples outside the record clamped to its ends.
pub fn delay(x: &[f64], d: f64, dt: f64, y: &mut [f64]) {
    if x.is_empty() {
        return;
    }
    let shift = d / dt;
    let whole = shift.floor();
    let frac = shift - whole;
    let whole = whole as isize;
    let last = x.len() as isize - 1;
    let at = |i: isize| x[i.clamp(0, last) as usize];
    for (k, yk) in y.iter_mut().enumerate() {
        let i = k as isize - whole;
        if frac == 0.0 {
            *yk = at(i);
            continue;
        }
        // between samples j = i − 1 and j + 1 = i, at u = 1 − frac from j
        let j = i - 1;
        let (p0, p1, p2, p3) = (at(j - 1), at(j), at(j + 1), at(j + 2));
        let u = 1.0 - frac;
        *yk = p1
            + 0.5
                * u
                * ((p2 - p0)
                    + u * ((2.0 * p0 - 5.0 * p1 + 4.0 * p2 - p3)
                        + u * (3.0 * (p1 - p2) + p3 - p0)));
    }
}

/// First-order sensor lag with time constant `τ ≥ 0` s, discretised exactly for an input that
/// is linear between samples: `τ·ẏ + y = x`, `y_0 = x_0`. `τ = 0` copies.
pub fn first_order_lag(x: &[f64], tau: f64, dt: f64, y: &mut [f64]) {
    if x.is_empty() {
        return;
    }
    if tau <= 0.0 {
        y.copy_from_slice(x);
        return;
    }
    let a = (-dt / tau).exp();
    // exact response to a ramp over [t_{k-1}, t_k]: y_k = a·y_{k−1} + b0·x_k + b1·x_{k−1}
    let c = tau / dt * (1.0 - a);
    let (b0, b1) = (1.0 - c, c - a);
    y[0] = x[0];
    for k in 1..x.len() {
        y[k] = a * y[k - 1] + b0 * x[k] + b1 * x[k - 1];
    }
}

/// Sample-and-hold: the sensor reports a new value every `period` s, first at `phase` s
/// (`0 ≤ phase < period`), and holds it (a load-cell amplifier such as an HX711 at ~10 Hz).
/// Sample `k` (time `k·dt`) shows the input at the last sampling instant `≤ k·dt`, taken at the
/// nearest sample; before the first instant it shows `x_0`.
pub fn sample_hold(x: &[f64], period: f64, phase: f64, dt: f64, y: &mut [f64]) {
    let mut held = x.first().copied().unwrap_or(0.0);
    // instants phase + j·period computed directly, not accumulated (no drift over long runs)
    let mut j = 0.0;
    for k in 0..y.len() {
        let t = k as f64 * dt;
        while phase + j * period <= t + 1e-9 * dt {
            let i = (((phase + j * period) / dt).round() as usize).min(x.len() - 1);
            held = x[i];
            j += 1.0;
        }
        y[k] = held;
    }
}

/// Gain and bias: `y = g·x + b`.
pub fn gain_bias(x: &[f64], gain: f64, bias: f64, y: &mut [f64]) {
    for (yk, &xk) in y.iter_mut().zip(x) {
        *yk = gain * xk + bias;
    }
}

/// Velocity of a sampled position: central differences inside, one-sided at the ends
/// (the same rule as `numpy.gradient`).
pub fn velocity(x: &[f64], dt: f64, v: &mut [f64]) {
    let n = x.len();
    if n < 2 {
        v.iter_mut().for_each(|e| *e = 0.0);
        return;
    }
    v[0] = (x[1] - x[0]) / dt;
    v[n - 1] = (x[n - 1] - x[n - 2]) / dt;
    for k in 1..n - 1 {
        v[k] = (x[k + 1] - x[k - 1]) / (2.0 * dt);
    }
}

#[cfg(test)]
#[allow(clippy::float_cmp)] // exact copies and holds are the claims under test
mod tests {
    use super::*;
    use approx::assert_relative_eq;

    #[test]
    fn play_shifts_by_half_width_after_reversal() {
        let x: Vec<f64> = (0..40)
            .map(|k| if k < 20 { k as f64 } else { 40.0 - k as f64 })
            .collect();
        let mut y = vec![0.0; 40];
        play(&x, 2.0, &mut y);
        assert_eq!(y[10], 8.0); // lags by δ going up
        assert_eq!(y[21], 18.0); // dead band after the reversal: held
        assert_eq!(y[30], 12.0); // leads by δ going down
        play(&x, 0.0, &mut y);
        assert_eq!(y, x);
    }

    #[test]
    fn delay_is_exact_for_whole_samples_and_for_quadratics_between_them() {
        let x: Vec<f64> = (0..10).map(|k| (k * k) as f64).collect();
        let mut y = vec![0.0; 10];
        delay(&x, 0.003, 1e-3, &mut y);
        assert_eq!(&y[3..], &x[..7]);
        assert_eq!(y[0], 0.0);
        delay(&x, 0.0025, 1e-3, &mut y);
        // x(t) = t² sampled: the delayed value at k = 5 is 2.5² exactly (linear would say 6.5)
        assert_relative_eq!(y[5], 6.25, max_relative = 1e-12);
        assert_relative_eq!(y[8], 5.5 * 5.5, max_relative = 1e-12);
    }

    #[test]
    fn lag_tracks_a_ramp_with_delay_tau_and_settles_on_a_step() {
        let dt = 1e-3;
        let tau = 0.05;
        let x: Vec<f64> = (0..2000).map(|k| k as f64 * dt).collect();
        let mut y = vec![0.0; 2000];
        first_order_lag(&x, tau, dt, &mut y);
        // exact ramp response: y(t) = t − τ(1 − e^{−t/τ})
        for k in [10, 100, 1999] {
            let t = k as f64 * dt;
            assert_relative_eq!(y[k], t - tau * (1.0 - (-t / tau).exp()), epsilon = 1e-12);
        }
        let step = vec![1.0; 10];
        first_order_lag(&step, tau, dt, &mut y[..10]);
        assert!(y[..10].iter().all(|&v| (v - 1.0).abs() < 1e-15));
    }

    #[test]
    fn sample_hold_updates_once_per_period() {
        let x: Vec<f64> = (0..1000).map(|k| k as f64).collect();
        let mut y = vec![0.0; 1000];
        sample_hold(&x, 0.1, 0.03, 1e-3, &mut y);
        assert_eq!(y[0], 0.0);
        assert_eq!(y[29], 0.0);
        assert_eq!(y[30], 30.0);
        assert_eq!(y[129], 30.0);
        assert_eq!(y[130], 130.0);
        assert_eq!(y[999], 930.0);
    }

    #[test]
    fn velocity_matches_numpy_gradient_rule() {
        let x = [0.0, 1.0, 4.0, 9.0];
        let mut v = [0.0; 4];
        velocity(&x, 0.5, &mut v);
        assert_eq!(v, [2.0, 4.0, 8.0, 10.0]);
    }
}
