//! Fixed-step explicit integration: classical RK4 with sub-stepping, input hold, divergence
//! detection, and step-size advice from the model's stiffest mode.
//!
//! One RK4 step of size `h` from `x` with inputs `u(τ)` over the step:
//!
//! ```text
//! k₁ = f(x,            u(0))
//! k₂ = f(x + h/2·k₁,   u(h/2))
//! k₃ = f(x + h/2·k₂,   u(h/2))
//! k₄ = f(x + h·k₃,     u(h))
//! x⁺ = x + h/6·(k₁ + 2k₂ + 2k₃ + k₄)
//! ```
//!
//! Inputs are sampled at the same instants as states (`u[k]` at `t_k = k·dt`). Between samples
//! they are held constant (**zero-order hold**, `u(τ) = u[k]`, what a digital controller applies)
//! or interpolated linearly (**first-order hold**, `u(τ) = u[k] + τ/dt·(u[k+1] − u[k])`, right for
//! sampled positions). A sample interval `dt` is split into `substeps` RK4 steps of `dt/substeps`.
//!
//! Trajectories follow the logging convention: `states[0] = x0`,
//! `states[k+1] = Φ(states[k], u over [t_k, t_{k+1}])`, `outputs[k] = h(states[k], u[k])`.

mod stability;

pub use crate::error::MAX_SUBSTEPS;

pub use stability::{jacobian, jacobian_rows, propose_step, rk4_stability_radius, StepAdvice};

use crate::dynamics::Model;
use crate::error::{check, CableError, Result};
use crate::lanes::{madd, LaneBuf, LANES};

/// How inputs behave between samples.
#[derive(Debug, Clone, Copy, PartialEq, Eq, Default)]
pub enum InputHold {
    /// Zero-order hold: `u[k]` over the whole interval.
    #[default]
    Zoh,
    /// First-order hold: linear from `u[k]` to `u[k+1]` (the last sample is held).
    Foh,
}

impl InputHold {
    /// Parse `"zoh"` / `"foh"`.
    pub fn from_name(name: &str) -> Result<Self> {
        match name {
            "zoh" => Ok(InputHold::Zoh),
            "foh" => Ok(InputHold::Foh),
            other => Err(CableError::InvalidOption {
                name: "hold".into(),
                value: other.into(),
                allowed: "\"zoh\", \"foh\"".into(),
            }),
        }
    }
}

/// Scratch space for RK4 so that stepping allocates nothing.
#[derive(Debug, Clone)]
pub struct Rk4 {
    k1: Vec<f64>,
    k2: Vec<f64>,
    k3: Vec<f64>,
    k4: Vec<f64>,
    tmp: Vec<f64>,
    u_mid: Vec<f64>,
    u_end: Vec<f64>,
    u_start: Vec<f64>,
    /// The state of [`rk4_interval_into`] while it integrates.
    tmp_out: Vec<f64>,
}

impl Rk4 {
    /// Workspace for a model with `n` states and `m` inputs.
    pub fn new(n: usize, m: usize) -> Self {
        Self {
            k1: vec![0.0; n],
            k2: vec![0.0; n],
            k3: vec![0.0; n],
            k4: vec![0.0; n],
            tmp: vec![0.0; n],
            u_mid: vec![0.0; m],
            u_end: vec![0.0; m],
            u_start: vec![0.0; m],
            tmp_out: Vec::with_capacity(n),
        }
    }

    /// Workspace sized for `model`.
    pub fn for_model<M: Model + ?Sized>(model: &M) -> Self {
        Self::new(model.n_states(), model.n_inputs())
    }

    /// One RK4 step of size `h` with inputs `u0` at the start, `um` at the midpoint and `u1` at
    /// the end of the step. Updates `x` in place. No validation (hot path).
    #[inline]
    pub fn step_with<M: Model + ?Sized>(
        &mut self,
        model: &M,
        x: &mut [f64],
        u0: &[f64],
        um: &[f64],
        u1: &[f64],
        h: f64,
    ) {
        let n = x.len();
        model.derivative(x, u0, &mut self.k1);
        for i in 0..n {
            self.tmp[i] = x[i] + 0.5 * h * self.k1[i];
        }
        model.derivative(&self.tmp, um, &mut self.k2);
        for i in 0..n {
            self.tmp[i] = x[i] + 0.5 * h * self.k2[i];
        }
        model.derivative(&self.tmp, um, &mut self.k3);
        for i in 0..n {
            self.tmp[i] = x[i] + h * self.k3[i];
        }
        model.derivative(&self.tmp, u1, &mut self.k4);
        for i in 0..n {
            x[i] += h / 6.0 * (self.k1[i] + 2.0 * self.k2[i] + 2.0 * self.k3[i] + self.k4[i]);
        }
    }

    /// One RK4 step of size `h` with a constant input (zero-order hold).
    #[inline]
    pub fn step<M: Model + ?Sized>(&mut self, model: &M, x: &mut [f64], u: &[f64], h: f64) {
        self.step_with(model, x, u, u, u, h);
    }

    /// Advance one sample interval `dt` in `substeps` RK4 steps, with inputs going linearly
    /// from `u_a` to `u_b` over the interval (pass `u_b = u_a` for zero-order hold).
    pub fn advance<M: Model + ?Sized>(
        &mut self,
        model: &M,
        x: &mut [f64],
        u_a: &[f64],
        u_b: &[f64],
        dt: f64,
        substeps: usize,
    ) {
        let h = dt / substeps as f64;
        if u_a == u_b {
            // constant over the interval (always under zero-order hold): the interpolation
            // below would reproduce `u_a` exactly
            for _ in 0..substeps {
                self.step(model, x, u_a, h);
            }
            return;
        }
        let mut u_start = std::mem::take(&mut self.u_start);
        let mut u_mid = std::mem::take(&mut self.u_mid);
        let mut u_end = std::mem::take(&mut self.u_end);
        for j in 0..substeps {
            let (a, b) = (
                j as f64 / substeps as f64,
                (j as f64 + 1.0) / substeps as f64,
            );
            let m = 0.5 * (a + b);
            for i in 0..u_a.len() {
                let du = u_b[i] - u_a[i];
                u_start[i] = u_a[i] + a * du;
                u_mid[i] = u_a[i] + m * du;
                u_end[i] = u_a[i] + b * du;
            }
            self.step_with(model, x, &u_start, &u_mid, &u_end, h);
        }
        self.u_start = u_start;
        self.u_mid = u_mid;
        self.u_end = u_end;
    }
}

/// RK4 over `W` independent states at once ([`LANES`], or [`WIDE`](crate::lanes::WIDE) for
/// two lane groups whose arithmetic interleaves; structure of arrays, see
/// [`Model::derivative_lanes`]): the same operations as [`Rk4::step`] per lane, so the same
/// bits, with the arithmetic in SIMD lanes. Scratch is sized at construction.
#[derive(Debug, Clone)]
pub struct Rk4Lanes<const W: usize = LANES> {
    k1: LaneBuf<W>,
    k2: LaneBuf<W>,
    k3: LaneBuf<W>,
    k4: LaneBuf<W>,
    tmp: LaneBuf<W>,
}

impl<const W: usize> Rk4Lanes<W> {
    /// Workspace for `n` states.
    pub fn new(n: usize) -> Self {
        Self {
            k1: LaneBuf::new(n),
            k2: LaneBuf::new(n),
            k3: LaneBuf::new(n),
            k4: LaneBuf::new(n),
            tmp: LaneBuf::new(n),
        }
    }

    /// One RK4 step of size `h` of every lane with the input `u` held (zero-order hold).
    #[inline(always)]
    pub fn step<M: Model>(&mut self, model: &M, x: &mut [[f64; W]], u: &[f64], h: f64) {
        self.advance::<M, false>(model, x, u, h);
    }

    /// [`Rk4Lanes::step`] with fused multiply-adds, in the stages and in the model
    /// ([`Model::derivative_lanes_fused`]): for code compiled for CPUs with FMA. The results
    /// differ from [`Rk4::step`] in the last bits.
    #[inline(always)]
    pub fn step_fused<M: Model>(&mut self, model: &M, x: &mut [[f64; W]], u: &[f64], h: f64) {
        self.advance::<M, true>(model, x, u, h);
    }

    #[inline(always)]
    fn advance<M: Model, const FUSED: bool>(
        &mut self,
        model: &M,
        x: &mut [[f64; W]],
        u: &[f64],
        h: f64,
    ) {
        let f = |x: &[[f64; W]], dx: &mut [[f64; W]]| {
            if FUSED {
                model.derivative_lanes_fused(x, u, dx)
            } else {
                model.derivative_lanes(x, u, dx)
            }
        };
        let stage = |tmp: &mut [[f64; W]], x: &[[f64; W]], k: &[[f64; W]], c: f64| {
            let ch = c * h;
            for ((t, x), k) in tmp.iter_mut().zip(x).zip(k) {
                for l in 0..W {
                    t[l] = madd::<FUSED>(ch, k[l], x[l]);
                }
            }
        };
        // the workspaces cut to the states' length: a caller whose length is a constant
        // (`ModelProcess` for 12 states) unrolls the stage loops whole
        let n = x.len();
        let (k1, k2, k3, k4, tmp) = (
            &mut self.k1.blocks_mut()[..n],
            &mut self.k2.blocks_mut()[..n],
            &mut self.k3.blocks_mut()[..n],
            &mut self.k4.blocks_mut()[..n],
            &mut self.tmp.blocks_mut()[..n],
        );
        f(x, k1);
        stage(tmp, x, k1, 0.5);
        f(tmp, k2);
        stage(tmp, x, k2, 0.5);
        f(tmp, k3);
        stage(tmp, x, k3, 1.0);
        f(tmp, k4);
        let h6 = h / 6.0;
        for (i, x) in x.iter_mut().enumerate() {
            let (k1, k2, k3, k4) = (k1[i], k2[i], k3[i], k4[i]);
            for l in 0..W {
                let s = madd::<FUSED>(2.0, k3[l], madd::<FUSED>(2.0, k2[l], k1[l])) + k4[l];
                x[l] = madd::<FUSED>(h6, s, x[l]);
            }
        }
    }
}

/// Options of a trajectory simulation.
#[derive(Debug, Clone, Copy, PartialEq)]
pub struct SimOptions {
    /// Sample interval `dt` (s), > 0.
    pub dt: f64,
    /// RK4 steps per sample interval, ≥ 1.
    pub substeps: usize,
    /// Input behaviour between samples.
    pub hold: InputHold,
}

impl SimOptions {
    /// Validated options.
    pub fn new(dt: f64, substeps: usize, hold: InputHold) -> Result<Self> {
        check::positive("dt", dt)?;
        check::substeps("substeps", substeps)?;
        Ok(Self { dt, substeps, hold })
    }
}

/// A simulated trajectory: row-major `(T, n)` states and `(T, p)` outputs.
#[derive(Debug, Clone, PartialEq)]
pub struct Trajectory {
    /// Number of samples `T`.
    pub len: usize,
    /// States, row-major `(T, n)`.
    pub states: Vec<f64>,
    /// Outputs, row-major `(T, p)`.
    pub outputs: Vec<f64>,
}

impl Trajectory {
    /// Zero-filled storage for `len` samples of `model`.
    pub fn zeros<M: Model + ?Sized>(model: &M, len: usize) -> Self {
        Self {
            len,
            states: vec![0.0; len * model.n_states()],
            outputs: vec![0.0; len * model.n_outputs()],
        }
    }

    /// Borrow the buffers for the `*_into` simulators.
    pub fn as_mut(&mut self) -> TrajectoryMut<'_> {
        TrajectoryMut {
            states: &mut self.states,
            outputs: &mut self.outputs,
        }
    }
}

/// Caller-owned trajectory storage, row-major `(T, n)` states and `(T, p)` outputs.
///
/// The `*_into` simulators write here instead of allocating, so a caller (the Python bindings,
/// a controller re-running a horizon) can reuse memory it already owns: on the machines we
/// measured, first-touch page faults of freshly allocated output buffers cost as much as a
/// third of a 100k-step run.
#[derive(Debug)]
pub struct TrajectoryMut<'a> {
    /// States, row-major `(T, n)`.
    pub states: &'a mut [f64],
    /// Outputs, row-major `(T, p)`.
    pub outputs: &'a mut [f64],
}

impl TrajectoryMut<'_> {
    /// Check that the buffers hold `len` samples of `model`.
    pub fn check<M: Model + ?Sized>(&self, model: &M, len: usize) -> Result<()> {
        for (what, buf, width) in [
            ("states buffer", &*self.states, model.n_states()),
            ("outputs buffer", &*self.outputs, model.n_outputs()),
        ] {
            if buf.len() != len * width {
                return Err(CableError::Shape {
                    what: what.into(),
                    expected: format!("({len}, {width})"),
                    got: format!("{} values", buf.len()),
                });
            }
        }
        Ok(())
    }
}

/// Validate shapes and values of a simulation request; returns `T`.
pub fn validate_request<M: Model + ?Sized>(model: &M, inputs: &[f64], x0: &[f64]) -> Result<usize> {
    let (n, m) = (model.n_states(), model.n_inputs());
    if m == 0 || !inputs.len().is_multiple_of(m) || inputs.is_empty() {
        return Err(CableError::Shape {
            what: "inputs".into(),
            expected: format!("(T, {m}) with T >= 1"),
            got: format!("{} values", inputs.len()),
        });
    }
    check::len("x0", x0, n)?;
    check::all_finite("inputs", inputs, m)?;
    check::all_finite("x0", x0, 1)?;
    Ok(inputs.len() / m)
}

/// Store sample `k` (state `x`, output `h(x, u)`) into row-major buffers, or report divergence
/// when either is non-finite.
pub(crate) fn record<M: Model + ?Sized>(
    model: &M,
    k: usize,
    x: &[f64],
    u: &[f64],
    dt: f64,
    out: &mut TrajectoryMut<'_>,
) -> Result<()> {
    let (n, p) = (model.n_states(), model.n_outputs());
    let y = &mut out.outputs[k * p..(k + 1) * p];
    model.output(x, u, y);
    if !x.iter().chain(y.iter()).all(|v| v.is_finite()) {
        return Err(CableError::Diverged {
            step: k,
            time_s: k as f64 * dt,
        });
    }
    out.states[k * n..(k + 1) * n].copy_from_slice(x);
    Ok(())
}

/// One checked sample interval of RK4 from `x`: inputs going linearly from `u_a` to `u_b`,
/// `substeps` steps (1 ..= [`MAX_SUBSTEPS`]). Lengths and finiteness are checked, and a
/// non-finite new state is [`CableError::Diverged`] at step 1. For callers outside the hot loops
/// (the bindings); a controller loop uses [`rk4_interval_into`] or [`Rk4::advance`] on its own
/// workspace.
pub fn rk4_interval<M: Model + ?Sized>(
    model: &M,
    x: &[f64],
    u_a: &[f64],
    u_b: &[f64],
    dt: f64,
    substeps: usize,
) -> Result<Vec<f64>> {
    let mut out = vec![0.0; x.len()];
    rk4_interval_into(
        model,
        x,
        u_a,
        u_b,
        dt,
        substeps,
        &mut out,
        &mut Rk4::for_model(model),
    )?;
    Ok(out)
}

/// [`rk4_interval`] into `out` (length `n`) with the caller's workspace `work` (sized for the
/// model by [`Rk4::for_model`]; a workspace of another size is resized): no allocation, for a
/// controller's loop. `x` and `out` may hold the same values (the step integrates a copy in the
/// workspace). On an error `out` is left as it was.
#[allow(clippy::too_many_arguments)]
pub fn rk4_interval_into<M: Model + ?Sized>(
    model: &M,
    x: &[f64],
    u_a: &[f64],
    u_b: &[f64],
    dt: f64,
    substeps: usize,
    out: &mut [f64],
    work: &mut Rk4,
) -> Result<()> {
    SimOptions::new(dt, substeps, InputHold::Foh)?;
    for (name, data, n) in [
        ("x", x, model.n_states()),
        ("u", u_a, model.n_inputs()),
        ("u_next", u_b, model.n_inputs()),
    ] {
        check::len(name, data, n)?;
        check::all_finite(name, data, 1)?;
    }
    check::len("out", out, model.n_states())?;
    if work.k1.len() != model.n_states() || work.u_mid.len() != model.n_inputs() {
        *work = Rk4::for_model(model);
    }
    // integrate in the workspace's scratch so that a diverged step leaves `out` untouched
    let mut y = std::mem::take(&mut work.tmp_out);
    y.clear();
    y.extend_from_slice(x);
    work.advance(model, &mut y, u_a, u_b, dt, substeps);
    let ok = y.iter().all(|v| v.is_finite());
    if ok {
        out.copy_from_slice(&y);
    }
    work.tmp_out = y;
    if ok {
        Ok(())
    } else {
        Err(CableError::Diverged {
            step: 1,
            time_s: dt,
        })
    }
}

/// The last sample time `dt·(T − 1)` must be finite (a time column of `inf` is no answer).
pub fn check_time_base(dt: f64, t_len: usize) -> Result<()> {
    if (dt * t_len.saturating_sub(1) as f64).is_finite() {
        Ok(())
    } else {
        Err(CableError::InvalidParameter {
            name: "dt".into(),
            value: dt,
            requirement: "small enough that dt·(T − 1) is finite",
        })
    }
}

/// Simulate `model` over the sampled inputs (row-major `(T, m)`) from `x0`.
///
/// Errors: shape or non-finite inputs, invalid options, and [`CableError::Diverged`] with the
/// first sample whose state (or output) is non-finite — never NaN-filled arrays.
pub fn simulate<M: Model + ?Sized>(
    model: &M,
    inputs: &[f64],
    x0: &[f64],
    opts: &SimOptions,
) -> Result<Trajectory> {
    let t_len = validate_request(model, inputs, x0)?;
    let mut traj = Trajectory::zeros(model, t_len);
    simulate_into(model, inputs, x0, opts, traj.as_mut())?;
    Ok(traj)
}

/// [`simulate`] into caller-owned buffers of `T` samples; returns `T`.
///
/// On error the buffers hold the samples before the failing one and zeros or stale values
/// after it.
pub fn simulate_into<M: Model + ?Sized>(
    model: &M,
    inputs: &[f64],
    x0: &[f64],
    opts: &SimOptions,
    mut out: TrajectoryMut<'_>,
) -> Result<usize> {
    let t_len = validate_request(model, inputs, x0)?;
    check_time_base(opts.dt, t_len)?;
    out.check(model, t_len)?;
    let m = model.n_inputs();
    let mut ws = Rk4::for_model(model);
    let mut x = x0.to_vec();
    for k in 0..t_len {
        let u_k = &inputs[k * m..(k + 1) * m];
        if k > 0 {
            let u_prev = &inputs[(k - 1) * m..k * m];
            let u_b = match opts.hold {
                InputHold::Zoh => u_prev,
                InputHold::Foh => u_k,
            };
            ws.advance(model, &mut x, u_prev, u_b, opts.dt, opts.substeps);
        }
        record(model, k, &x, u_k, opts.dt, &mut out)?;
    }
    Ok(t_len)
}

#[cfg(test)]
#[allow(clippy::float_cmp)] // exact zeros are the claims under test (slack, no contact)
mod tests {
    use super::*;

    /// ẋ = λx with u ignored, to check the order of accuracy.
    struct Decay(f64);
    impl Model for Decay {
        fn n_states(&self) -> usize {
            1
        }
        fn n_inputs(&self) -> usize {
            1
        }
        fn n_outputs(&self) -> usize {
            1
        }
        fn derivative(&self, x: &[f64], u: &[f64], dx: &mut [f64]) {
            dx[0] = self.0 * x[0] + u[0];
        }
        fn output(&self, x: &[f64], _u: &[f64], y: &mut [f64]) {
            y[0] = x[0];
        }
        fn state_names(&self) -> Vec<String> {
            vec!["x".into()]
        }
        fn input_names(&self) -> Vec<String> {
            vec!["u".into()]
        }
        fn output_names(&self) -> Vec<String> {
            vec!["y".into()]
        }
    }

    #[test]
    fn rk4_is_fourth_order() {
        let model = Decay(-1.0);
        let err = |steps: usize| {
            let u = vec![0.0; steps + 1];
            let opts = SimOptions::new(1.0 / steps as f64, 1, InputHold::Zoh).unwrap();
            let tr = simulate(&model, &u, &[1.0], &opts).unwrap();
            (tr.states[steps] - (-1.0f64).exp()).abs()
        };
        let ratio = err(20) / err(40);
        assert!((ratio - 16.0).abs() < 0.5, "ratio {ratio}");
    }

    #[test]
    fn foh_integrates_a_ramp_input_exactly_enough() {
        // ẋ = u, u ramps 0 → 1 over one sample: x(1) = 1/2 with FOH, 0 with ZOH
        let model = Decay(0.0);
        let u = [0.0, 1.0];
        let foh = simulate(
            &model,
            &u,
            &[0.0],
            &SimOptions::new(1.0, 1, InputHold::Foh).unwrap(),
        )
        .unwrap();
        let zoh = simulate(
            &model,
            &u,
            &[0.0],
            &SimOptions::new(1.0, 1, InputHold::Zoh).unwrap(),
        )
        .unwrap();
        assert!((foh.states[1] - 0.5).abs() < 1e-15);
        assert!(zoh.states[1].abs() < 1e-15);
    }

    #[test]
    fn divergence_is_reported_with_its_step() {
        let model = Decay(-1000.0);
        let u = vec![0.0; 2000];
        let opts = SimOptions::new(0.01, 1, InputHold::Zoh).unwrap();
        match simulate(&model, &u, &[1.0], &opts) {
            Err(CableError::Diverged { step, time_s }) => {
                assert!(step > 10 && step < 2000, "step {step}");
                assert!((time_s - step as f64 * 0.01).abs() < 1e-12);
            }
            other => panic!("expected divergence, got {other:?}"),
        }
        // ten substeps bring |λh| to 1: stable
        let opts = SimOptions::new(0.01, 10, InputHold::Zoh).unwrap();
        assert!(simulate(&model, &u, &[1.0], &opts).is_ok());
    }

    #[test]
    fn bad_requests_are_typed_errors() {
        let model = Decay(-1.0);
        let opts = SimOptions::new(0.1, 1, InputHold::Zoh).unwrap();
        assert!(matches!(
            simulate(&model, &[0.0, f64::NAN], &[1.0], &opts),
            Err(CableError::NotFinite { index: 1, .. })
        ));
        assert!(matches!(
            simulate(&model, &[0.0], &[1.0, 2.0], &opts),
            Err(CableError::Shape { .. })
        ));
        assert!(matches!(
            simulate(&model, &[], &[1.0], &opts),
            Err(CableError::Shape { .. })
        ));
        assert!(SimOptions::new(0.0, 1, InputHold::Zoh).is_err());
        assert!(SimOptions::new(-1.0, 1, InputHold::Zoh).is_err());
        assert!(SimOptions::new(0.1, 0, InputHold::Zoh).is_err());
    }

    #[test]
    fn into_buffers_match_allocating_path_and_are_checked() {
        let model = Decay(-3.0);
        let u: Vec<f64> = (0..50).map(|k| (k as f64 * 0.3).sin()).collect();
        for hold in [InputHold::Zoh, InputHold::Foh] {
            let opts = SimOptions::new(0.02, 3, hold).unwrap();
            let want = simulate(&model, &u, &[0.5], &opts).unwrap();
            let mut got = Trajectory {
                len: 50,
                states: vec![f64::NAN; 50],
                outputs: vec![f64::NAN; 50],
            };
            assert_eq!(
                simulate_into(&model, &u, &[0.5], &opts, got.as_mut()).unwrap(),
                50
            );
            assert_eq!(got, want);
        }
        let opts = SimOptions::new(0.02, 1, InputHold::Zoh).unwrap();
        let (mut s, mut o) = (vec![0.0; 49], vec![0.0; 50]);
        let out = TrajectoryMut {
            states: &mut s,
            outputs: &mut o,
        };
        match simulate_into(&model, &u, &[0.5], &opts, out) {
            Err(CableError::Shape { what, .. }) => assert_eq!(what, "states buffer"),
            other => panic!("expected a shape error, got {other:?}"),
        }
    }

    #[test]
    fn constant_foh_interval_equals_zoh() {
        // the shortcut for equal end inputs must reproduce the interpolating path
        let model = Decay(-2.0);
        let u = [1.0, 1.0, 1.0, -2.0, -2.0];
        let foh = SimOptions::new(0.1, 4, InputHold::Foh).unwrap();
        let zoh = SimOptions::new(0.1, 4, InputHold::Zoh).unwrap();
        let a = simulate(&model, &u, &[0.0], &foh).unwrap();
        let b = simulate(&model, &u, &[0.0], &zoh).unwrap();
        assert_eq!(a.states[..3], b.states[..3]);
        assert_ne!(a.states[3], b.states[3]); // the ramp interval from u[2] to u[3] differs
    }
}
