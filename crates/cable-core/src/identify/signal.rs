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

/// An integrating (averaging) converter held between conversions, as an HX711 or a
/// sigma-delta ADC with a sinc filter: at each instant `phase + j·period` it reports the **mean
/// of the input over the conversion window just ended** (one period) and holds it. Samples
/// before the first instant show `x_0`. Against [`sample_hold`] of the instantaneous value the
/// report lags by about half a period and smooths everything faster than the window.
pub fn sample_hold_mean(x: &[f64], period: f64, phase: f64, dt: f64, y: &mut [f64]) {
    if x.is_empty() {
        return;
    }
    // prefix sums: the mean of x[a..=b] in O(1)
    let mut pre = Vec::with_capacity(x.len() + 1);
    pre.push(0.0);
    for &v in x {
        pre.push(pre.last().copied().unwrap_or(0.0) + v);
    }
    let width = ((period / dt).round() as usize).max(1);
    let mut held = x[0];
    let mut j = 0.0;
    for k in 0..y.len() {
        let t = k as f64 * dt;
        while phase + j * period <= t + 1e-9 * dt {
            let i = (((phase + j * period) / dt).round() as usize).min(x.len() - 1);
            let a = (i + 1).saturating_sub(width);
            held = (pre[i + 1] - pre[a]) / (i + 1 - a) as f64;
            j += 1.0;
        }
        y[k] = held;
    }
}

/// Second-order sensor with its own natural frequency `ω_n = 1/τ` and damping ratio `ζ`
/// (a load cell's mechanical resonance, an amplifier's two-pole filter):
/// `ÿ + 2ζω_n·ẏ + ω_n²·y = ω_n²·x`, from rest at `y_0 = x_0`, the input linear between samples,
/// integrated by RK4 with at least 8 substeps per `τ` (at most 256 per sample: every loop is
/// bounded). `ζ < 1` rings (underdamped), `ζ = 1` is the critically damped two-pole lag. A
/// sensor whose fastest pole needs more than 256 substeps is far above the sample rate: it is
/// replaced by its low-frequency equivalent, a one-pole lag of `2ζτ`.
pub fn second_order_sensor(x: &[f64], tau: f64, zeta: f64, dt: f64, y: &mut [f64]) {
    if x.is_empty() {
        return;
    }
    if tau <= 0.0 {
        y.copy_from_slice(x);
        return;
    }
    let wn = 1.0 / tau;
    let fastest = (wn * (zeta.abs() + (zeta * zeta + 1.0).sqrt())).max(wn);
    let need = (dt * fastest * 8.0).ceil();
    if need.is_nan() || need > 256.0 {
        first_order_lag(x, 2.0 * zeta * tau, dt, y);
        return;
    }
    let sub = (need as usize).max(1);
    let h = dt / sub as f64;
    let f = |u: f64, p: f64, v: f64| -> (f64, f64) { (v, wn * wn * (u - p) - 2.0 * zeta * wn * v) };
    let (mut p, mut v) = (x[0], 0.0);
    y[0] = x[0];
    for k in 1..x.len() {
        let (x0, x1) = (x[k - 1], x[k]);
        for i in 0..sub {
            let u = |s: f64| x0 + (x1 - x0) * ((i as f64 + s) / sub as f64);
            let (k1p, k1v) = f(u(0.0), p, v);
            let (k2p, k2v) = f(u(0.5), p + 0.5 * h * k1p, v + 0.5 * h * k1v);
            let (k3p, k3v) = f(u(0.5), p + 0.5 * h * k2p, v + 0.5 * h * k2v);
            let (k4p, k4v) = f(u(1.0), p + h * k3p, v + h * k3v);
            p += h / 6.0 * (k1p + 2.0 * k2p + 2.0 * k3p + k4p);
            v += h / 6.0 * (k1v + 2.0 * k2v + 2.0 * k3v + k4v);
        }
        y[k] = p;
    }
}

/// Period and phase `(period, phase)` (s) of a held channel from its **update instants read off
/// single-sample jumps**, with noise after the hold (so no value repeats exactly) and with
/// updates that change nothing (the input at rest). A hold changes by a period's worth of
/// motion at each update and by noise in between: a difference `Δ_k = x_k − x_{k−1}` more than
/// 5 robust standard deviations (the differences' MAD, dominated by the noise) from zero and
/// more than 3× both neighbours is an update. The intervals between updates are whole
/// multiples of the period (updates at rest are not seen): with the median interval as a first
/// period, each instant gets its update count, and `t_j = phase + n_j·period` is fitted by least
/// squares, twice (the second time without instants more than a sample off the line). `None`
/// when fewer than 8 updates are found, when they are not isolated single samples (a continuous
/// signal moving fast), when fewer than 80 % of the intervals are whole multiples of the period,
/// or when the period is below 2 samples.
pub fn hold_from_jumps(x: &[f64], dt: f64) -> Option<(f64, f64)> {
    let n = x.len();
    if n < 32 || dt.is_nan() || dt <= 0.0 {
        return None;
    }
    let d: Vec<f64> = x.windows(2).map(|w| w[1] - w[0]).collect();
    let mut abs: Vec<f64> = d.iter().map(|v| v.abs()).collect();
    abs.sort_by(f64::total_cmp);
    let s = 1.4826 * abs[abs.len() / 2];
    if !(s > 0.0 && s.is_finite()) {
        return None;
    }
    let m = d.len();
    let events: Vec<f64> = (0..m)
        .filter(|&k| {
            let a = d[k].abs();
            let left = if k > 0 { d[k - 1].abs() } else { 0.0 };
            let right = if k + 1 < m { d[k + 1].abs() } else { 0.0 };
            a > 5.0 * s && a > 3.0 * left && a > 3.0 * right
        })
        .map(|k| (k + 1) as f64) // the jump into sample k + 1
        .collect();
    if events.len() < 8 {
        return None;
    }
    let mut gaps: Vec<f64> = events.windows(2).map(|w| w[1] - w[0]).collect();
    gaps.sort_by(f64::total_cmp);
    let p0 = gaps[gaps.len() / 2];
    if p0 < 2.0 {
        return None;
    }
    let whole = events
        .windows(2)
        .filter(|w| {
            let g = w[1] - w[0];
            (g - (g / p0).round().max(1.0) * p0).abs() <= 1.0_f64.max(0.02 * g)
        })
        .count();
    if (whole as f64) < 0.8 * (events.len() - 1) as f64 {
        return None;
    }
    // update counts from the local intervals, then a line through (n_j, t_j); the counts are
    // taken again with the fitted period (a median interval of 14 samples for a 13.5-sample
    // hold counts a 175-sample interval as 13 updates instead of 13), twice
    let counts_for = |p: f64| -> Vec<f64> {
        let mut counts = vec![0.0; events.len()];
        for j in 1..events.len() {
            counts[j] = counts[j - 1] + ((events[j] - events[j - 1]) / p).round().max(1.0);
        }
        counts
    };
    let line = |counts: &[f64], keep: &dyn Fn(usize) -> bool| -> Option<(f64, f64)> {
        let idx: Vec<usize> = (0..events.len()).filter(|&j| keep(j)).collect();
        let k = idx.len() as f64;
        let (sn, st) = idx
            .iter()
            .fold((0.0, 0.0), |(a, b), &j| (a + counts[j], b + events[j]));
        let (snn, snt) = idx.iter().fold((0.0, 0.0), |(a, b), &j| {
            (a + counts[j] * counts[j], b + counts[j] * events[j])
        });
        let den = k * snn - sn * sn;
        (den > 0.0).then(|| {
            let period = (k * snt - sn * st) / den;
            (period, (st - period * sn) / k)
        })
    };
    // a first period from the short intervals alone (at most 4 updates: a median of 14 samples
    // for a 13.5-sample hold counts a 1,134-sample interval as 81 updates instead of 84)
    let (sum_g, sum_n) = events.windows(2).fold((0.0, 0.0), |(g, n), w| {
        let gap = w[1] - w[0];
        let k = (gap / p0).round().max(1.0);
        if k <= 4.0 {
            (g + gap, n + k)
        } else {
            (g, n)
        }
    });
    let mut period = if sum_n > 0.0 { sum_g / sum_n } else { p0 };
    let mut first = events[0];
    for _ in 0..3 {
        let counts = counts_for(period);
        let (p1, f1) = line(&counts, &|_| true)?;
        let (p2, f2) = line(&counts, &|j| (events[j] - f1 - p1 * counts[j]).abs() <= 1.0)?;
        if !p2.is_finite() || p2 < 2.0 {
            return None;
        }
        (period, first) = (p2, f2);
    }
    // samples → seconds; the update seen at sample k was taken in (t_{k−1}, t_k]
    let (period, first) = (period * dt, first * dt);
    Some((period, (first - 0.5 * dt).rem_euclid(period)))
}

/// Period and phase `(period, phase)` (s) of a sample-and-hold in a measured channel, read
/// off the **energy of its sample-to-sample jumps**, so that noise added after the hold (the
/// amplifier, the ADC) does not hide it: `None` when no periodic jump pattern stands out.
///
/// A held signal changes by a whole period's worth of motion at each update and by noise
/// only in between, so the jump energy `e_k = (x_k − x_{k−1})²`, less its running median over
/// five samples (the motion's slowly varying share), is a pulse train. Its periodogram
/// `|Σ e_k·exp(−2πi·f·k)|²` (FFT) has lines at the update rate and its harmonics; the rate is
/// the lowest frequency whose harmonic sum over its first five harmonics is within 70 % of the
/// best, whose line stands 20× above the median power and at least three of whose harmonics
/// do (the motion's envelope has isolated lines, sub-multiples of the rate lack harmonics);
/// it is refined to a fraction of a sample in period by golden section on the periodogram,
/// and kept only if the folded jump samples carry far more energy than their neighbours.
/// The update instant lies in the sample interval before the jump: phase `(ψ − ½)·dt` for the
/// jumps' mean fold position `ψ` (samples). Periods from 4 samples to `max_period`.
pub fn hold_period(x: &[f64], dt: f64, max_period: f64) -> Option<(f64, f64)> {
    let n = x.len();
    if n < 32 || dt.is_nan() || dt <= 0.0 {
        return None;
    }
    let raw: Vec<f64> = x
        .windows(2)
        .map(|w| (w[1] - w[0]) * (w[1] - w[0]))
        .collect();
    let m = raw.len();
    let mut e = vec![0.0; m];
    for k in 0..m {
        let (a, b) = (k.saturating_sub(2), (k + 3).min(m));
        let mut w: Vec<f64> = raw[a..b].to_vec();
        w.sort_by(f64::total_cmp);
        e[k] = raw[k] - w[w.len() / 2];
    }
    let mean = e.iter().sum::<f64>() / m as f64;
    e.iter_mut().for_each(|v| *v -= mean);
    // S(f) = Σ_j e_j·exp(2πi·f·(j + 1)): e_j is the jump into sample k = j + 1
    let spectrum = |f: f64| -> (f64, f64) {
        let (s, c) = (std::f64::consts::TAU * f).sin_cos();
        let (mut re, mut im) = (0.0, 0.0);
        let (mut cr, mut ci) = (c, s);
        for &v in &e {
            re += v * cr;
            im += v * ci;
            let t = cr * c - ci * s;
            ci = cr * s + ci * c;
            cr = t;
        }
        (re * re + im * im, im.atan2(re))
    };
    let p_max = (max_period / dt).min(m as f64 / 4.0);
    if p_max < 3.0 {
        return None;
    }
    // power spectrum on a 2×-oversampled grid (zero padding), bins b ↔ f = b/len
    let len = (2 * m).next_power_of_two();
    let (mut re, mut im) = (vec![0.0; len], vec![0.0; len]);
    re[1..=m].copy_from_slice(&e); // e_j belongs to sample j + 1
    fft(&mut re, &mut im);
    let power: Vec<f64> = (0..=len / 2)
        .map(|b| re[b] * re[b] + im[b] * im[b])
        .collect();
    let (b_lo, b_hi) = (((len as f64) / p_max).ceil() as usize, len / 4);
    if b_hi <= b_lo + 2 {
        return None;
    }
    let mut sorted = power[b_lo..=b_hi].to_vec();
    sorted.sort_by(f64::total_cmp);
    let floor = sorted[sorted.len() / 2].max(f64::MIN_POSITIVE);
    // harmonic sum: a pulse train has lines at f, 2f, 3f, ...; the motion's slowly varying
    // envelope (lines near zero frequency) and the rate's sub-multiples have few of them
    let line = |x: f64| -> f64 {
        let c = x.round() as usize;
        (c.saturating_sub(1)..=(c + 1).min(len / 2))
            .map(|b| power[b])
            .fold(0.0, f64::max)
    };
    let harmonic: Vec<f64> = (b_lo..=b_hi)
        .map(|b| {
            let terms: Vec<f64> = (1..=5)
                .map(|h| (h * b) as f64)
                .filter(|&x| x <= (len / 2) as f64)
                .map(line)
                .collect();
            // a pulse train of single-sample jumps has its harmonics too: the fundamental and
            // at least three of the first five (all, when fewer fit below Nyquist) stand out
            // of the noise — the motion's envelope has one or two isolated lines
            let clear = terms.iter().filter(|&&p| p >= 20.0 * floor).count();
            if line(b as f64) < 20.0 * floor || clear < terms.len().clamp(2, 3) {
                0.0
            } else {
                terms.iter().sum::<f64>() / terms.len() as f64
            }
        })
        .collect();
    let best = harmonic.iter().copied().fold(0.0, f64::max);
    if best.is_nan() || best <= 0.0 {
        return None;
    }
    // candidates in rising frequency: local peaks of the harmonic sum within 70 % of the best;
    // the first whose folded jumps check out is the rate
    let bin = 1.0 / len as f64;
    let sd = (e.iter().map(|v| v * v).sum::<f64>() / m as f64).sqrt();
    let g = 0.5 * (5f64.sqrt() - 1.0);
    let peaks = (0..harmonic.len()).filter(|&i| {
        harmonic[i] >= 0.7 * best
            && (i == 0 || harmonic[i - 1] <= harmonic[i])
            && (i + 1 == harmonic.len() || harmonic[i + 1] < harmonic[i])
    });
    for i in peaks.take(8) {
        // the line's peak within two bins either side (inside the main lobe, ±1/m)
        let f0 = (b_lo + i) as f64 * bin;
        let (mut lo, mut hi) = (f0 - 2.0 * bin, f0 + 2.0 * bin);
        for _ in 0..50 {
            let (a, b) = (hi - g * (hi - lo), lo + g * (hi - lo));
            if spectrum(a).0 > spectrum(b).0 {
                hi = b;
            } else {
                lo = a;
            }
        }
        let p = 2.0 / (lo + hi);
        let (_, angle) = spectrum(1.0 / p);
        // jumps sit at samples k ≡ ψ (mod P) with 2π·ψ/P = angle
        let psi = (angle / std::f64::consts::TAU * p).rem_euclid(p);
        // a hold's jumps are single samples: at the folded jump sample the excess jump energy
        // is large, at the samples either side it is not (a slowly varying envelope fails)
        let (mut at, mut side, mut count) = (0.0, 0.0, 0usize);
        let mut c = psi;
        while c.round() as usize + 1 < m {
            let k = c.round() as usize; // the jump into sample k is e[k − 1]
            if k >= 2 {
                at += e[k - 1];
                side += 0.5 * (e[k - 2] + e[k]);
                count += 1;
            }
            c += p;
        }
        let n_jumps = count.max(1) as f64;
        if at / n_jumps > 3.0 * (side / n_jumps).abs() + 4.0 * sd / n_jumps.sqrt() {
            let phase = ((psi - 0.5) * dt).rem_euclid(p * dt);
            return Some((p * dt, phase));
        }
    }
    None
}

/// In-place radix-2 complex FFT (`re.len()` a power of two), `X_b = Σ_k x_k·exp(−2πi·b·k/n)`.
fn fft(re: &mut [f64], im: &mut [f64]) {
    let n = re.len();
    let mut j = 0;
    for i in 1..n {
        let mut bit = n >> 1;
        while j & bit != 0 {
            j ^= bit;
            bit >>= 1;
        }
        j |= bit;
        if i < j {
            re.swap(i, j);
            im.swap(i, j);
        }
    }
    let mut size = 2;
    while size <= n {
        let (s, c) = (-std::f64::consts::TAU / size as f64).sin_cos();
        for start in (0..n).step_by(size) {
            let (mut wr, mut wi) = (1.0, 0.0);
            for k in 0..size / 2 {
                let (a, b) = (start + k, start + k + size / 2);
                let (tr, ti) = (re[b] * wr - im[b] * wi, re[b] * wi + im[b] * wr);
                re[b] = re[a] - tr;
                im[b] = im[a] - ti;
                re[a] += tr;
                im[a] += ti;
                let t = wr * c - wi * s;
                wi = wr * s + wi * c;
                wr = t;
            }
        }
        size <<= 1;
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
    fn hold_period_is_found_to_a_fraction_of_a_sample_under_noise_after_the_hold() {
        // a 12.37-sample (80.8 Hz) hold of a smooth signal, white noise added after the hold
        // at a tenth of the typical jump; a cheap deterministic noise (LCG, Irwin–Hall)
        // (the instant is known to half a sample: it lies in the interval before the jump)
        let dt = 1e-3;
        let n = 20_000;
        let x: Vec<f64> = (0..n)
            .map(|k| {
                let t = k as f64 * dt;
                (2.0 * std::f64::consts::PI * 0.7 * t).sin()
                    + 0.3 * (2.0 * std::f64::consts::PI * 3.1 * t).sin()
            })
            .collect();
        let (period, phase) = (12.37e-3, 4.2e-3);
        let mut y = vec![0.0; n];
        sample_hold(&x, period, phase, dt, &mut y);
        let mut state = 12345u64;
        let mut noise = || {
            let mut s = 0.0;
            for _ in 0..12 {
                state = state
                    .wrapping_mul(6364136223846793005)
                    .wrapping_add(1442695040888963407);
                s += (state >> 11) as f64 / (1u64 << 53) as f64;
            }
            s - 6.0
        };
        for v in &mut y {
            *v += 0.004 * noise();
        }
        let (p, ph) = hold_period(&y, dt, 1.0).expect("hold found");
        assert!((p - period).abs() < 0.02 * dt, "period {p} vs {period}");
        // the instant is known to within the sample interval it falls in
        let d = (ph - phase).rem_euclid(period);
        assert!(d.min(period - d) <= 0.6 * dt, "phase {ph} vs {phase}");
        // a continuous signal with the same noise has no hold
        let mut z = x.clone();
        for v in &mut z {
            *v += 0.004 * noise();
        }
        let got = hold_period(&z, dt, 1.0);
        assert!(got.is_none(), "{got:?}");
        // a slow 10 Hz hold (100 samples) is not mistaken for a multiple or divisor
        sample_hold(&x, 0.1003, 0.05, dt, &mut y);
        for v in &mut y {
            *v += 0.004 * noise();
        }
        let (p, _) = hold_period(&y, dt, 1.0).expect("hold found");
        assert!((p - 0.1003).abs() < 0.05 * dt, "period {p}");
    }

    /// A smooth signal with dwells, held every `period` s from `phase`, noise after the hold.
    fn held_with_noise_after(period: f64, phase: f64, averaging: bool) -> (Vec<f64>, f64) {
        let dt = 1e-3;
        let n = 20_000;
        let x: Vec<f64> = (0..n)
            .map(|k| {
                let t = k as f64 * dt;
                // point-to-point sweeps with dwells: the held value often does not change
                20.0 + 8.0 * (0.4 * t).sin().powi(3) + 1.5 * (2.3 * t).sin()
            })
            .collect();
        let mut y = vec![0.0; n];
        if averaging {
            sample_hold_mean(&x, period, phase, dt, &mut y);
        } else {
            sample_hold(&x, period, phase, dt, &mut y);
        }
        let mut seed = 12345u64;
        for v in y.iter_mut() {
            // a small LCG-driven sum of uniforms: roughly Gaussian noise of sd 0.02
            let mut u = 0.0;
            for _ in 0..4 {
                seed = seed
                    .wrapping_mul(6364136223846793005)
                    .wrapping_add(1442695040888963407);
                u += (seed >> 11) as f64 / (1u64 << 53) as f64 - 0.5;
            }
            *v += 0.02 * u * 3.0_f64.sqrt();
        }
        (y, dt)
    }

    #[test]
    fn hold_from_jumps_finds_long_holds_under_noise_after_the_hold() {
        for (period, phase, averaging) in [
            (0.1, 0.0, false),
            (0.0823, 0.031, false),
            (0.25, 0.1, true),
            (0.03, 0.011, true),
        ] {
            let (y, dt) = held_with_noise_after(period, phase, averaging);
            let (p, ph) = hold_from_jumps(&y, dt).unwrap_or_else(|| panic!("{period}: no hold"));
            // over 20 s the period must be known to a small fraction of a sample's drift
            assert!(
                (p - period).abs() * 20.0 / period < 0.5 * dt,
                "{period}: {p}"
            );
            let err = (ph - phase + 0.5 * period).rem_euclid(period) - 0.5 * period;
            assert!(
                err.abs() <= 0.5 * dt + 1e-9,
                "{period}: phase {ph} vs {phase}"
            );
        }
        // a continuous signal moving smoothly has no isolated jumps: not a hold
        let dt = 1e-3;
        let smooth: Vec<f64> = (0..20_000)
            .map(|k| 20.0 + 8.0 * (0.4 * k as f64 * dt).sin().powi(3))
            .collect();
        assert_eq!(hold_from_jumps(&smooth, dt), None);
    }

    #[test]
    fn averaging_hold_reports_the_window_mean() {
        let dt = 1e-3;
        let x: Vec<f64> = (0..1000).map(|k| k as f64 * dt).collect(); // a ramp
        let mut y = vec![0.0; x.len()];
        sample_hold_mean(&x, 0.1, 0.05, dt, &mut y);
        // the update at t = 0.15 s reports the mean of the ramp over (0.05, 0.15]: 0.1005
        assert!((y[160] - 0.1005).abs() < 1e-12, "{}", y[160]);
        assert_eq!(y[10], x[0]);
        // an instantaneous hold reports 0.15 there: the mean lags by half a period
        let mut z = vec![0.0; x.len()];
        sample_hold(&x, 0.1, 0.05, dt, &mut z);
        assert!((z[160] - y[160] - 0.0495).abs() < 1e-12);
    }

    #[test]
    fn second_order_sensor_rings_at_its_frequency_and_settles_on_a_step() {
        let dt = 1e-3;
        let x: Vec<f64> = (0..2000).map(|k| if k < 10 { 0.0 } else { 1.0 }).collect();
        let mut y = vec![0.0; x.len()];
        let (fnat, zeta) = (25.0, 0.2);
        second_order_sensor(&x, 1.0 / (std::f64::consts::TAU * fnat), zeta, dt, &mut y);
        // overshoot exp(−ζπ/√(1−ζ²)) of the step
        let peak = y.iter().copied().fold(f64::MIN, f64::max);
        let want = (-zeta * std::f64::consts::PI / (1.0 - zeta * zeta).sqrt()).exp();
        assert!(
            (peak - 1.0 - want).abs() < 0.01,
            "overshoot {} vs {want}",
            peak - 1.0
        );
        // the first peak at half the damped period after the step
        let k_peak = y.iter().position(|&v| v == peak).unwrap();
        let td = 1.0 / (fnat * (1.0 - zeta * zeta).sqrt());
        assert!(
            ((k_peak - 10) as f64 * dt - 0.5 * td).abs() < 2.0 * dt,
            "{k_peak}"
        );
        assert!((y[1999] - 1.0).abs() < 1e-6);
        // ζ = 1 with τ equals two cascaded first-order lags of τ
        let ramp: Vec<f64> = (0..500).map(|k| (k as f64 * 0.01).sin()).collect();
        let (mut a, mut b, mut c) = (vec![0.0; 500], vec![0.0; 500], vec![0.0; 500]);
        second_order_sensor(&ramp, 0.02, 1.0, dt, &mut a);
        first_order_lag(&ramp, 0.02, dt, &mut b);
        first_order_lag(&b, 0.02, dt, &mut c);
        let err = a
            .iter()
            .zip(&c)
            .map(|(p, q)| (p - q).abs())
            .fold(0.0, f64::max);
        assert!(err < 1e-4, "{err}"); // the cascade is exact only for piecewise-linear input
    }

    #[test]
    fn velocity_matches_numpy_gradient_rule() {
        let x = [0.0, 1.0, 4.0, 9.0];
        let mut v = [0.0; 4];
        velocity(&x, 0.5, &mut v);
        assert_eq!(v, [2.0, 4.0, 8.0, 10.0]);
    }
}
