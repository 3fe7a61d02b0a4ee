//! Process and measurement models of the filter: any cable-core [`Model`] integrated by RK4
//! with sub-steps, a discrete linear system, and linear-selection or model-output measurements.

use crate::dynamics::Model;
use crate::error::{check, CableError, Result};
use crate::integrate::{InputHold, Rk4, Rk4Lanes, SimOptions};
use crate::lanes::{cpu_has_avx2_fma, transpose4, LaneBuf, Lanes, LANES, WIDE};

/// A discrete-time process `x_k = F(x_{k−1}, u_{k−1})` (additive noise is the filter's).
pub trait Process {
    /// State dimension `n`.
    fn n_states(&self) -> usize;
    /// Input dimension.
    fn n_inputs(&self) -> usize;
    /// Propagates `x` over one filter period in place with input `u` (held over the period).
    fn propagate(&mut self, x: &mut [f64], u: &[f64]);
    /// Propagates the consecutive states of `xs` (length a multiple of `n`, e.g. all sigma
    /// points), each exactly as [`Process::propagate`] would. The default calls it per state;
    /// [`ModelProcess`] runs four states at a time in SIMD lanes.
    fn propagate_many(&mut self, xs: &mut [f64], u: &[f64]) {
        let n = self.n_states();
        for x in xs.chunks_exact_mut(n) {
            self.propagate(x, u);
        }
    }
    /// Projects a mean onto the admissible set (bounded parameters); identity by default.
    fn project(&self, _x: &mut [f64]) {}
    /// Whether a propagation since the step began could not be computed (a front end's
    /// callback raised): the filter then undoes the step and reports it. Never by default.
    fn failed(&self) -> bool {
        false
    }
}

/// A measurement `y = H(x, u)`.
pub trait Observe {
    /// Measurement dimension `p`.
    fn n_outputs(&self) -> usize;
    /// Writes `H(x, u)` into `y`.
    fn observe(&mut self, x: &[f64], u: &[f64], y: &mut [f64]);
    /// Measures the consecutive states of `xs` (length a multiple of `n`, e.g. all sigma
    /// points) into the consecutive `p`-long rows of `ys`, each exactly as
    /// [`Observe::observe`] would. The default calls it per state; a model that is cheaper
    /// measured all at once (a user's vectorised callback) overrides it.
    fn observe_many(&mut self, xs: &[f64], u: &[f64], ys: &mut [f64]) {
        let p = self.n_outputs();
        if p == 0 {
            return;
        }
        let k = ys.len() / p;
        let n = xs.len().checked_div(k).unwrap_or(0);
        for (x, y) in xs.chunks_exact(n.max(1)).zip(ys.chunks_exact_mut(p)) {
            self.observe(x, u, y);
        }
    }
    /// `Some` when `H(x, u) = H·x` is linear (and ignores `u`). Sigma points through a
    /// linear map reproduce `H·x̂`, `H·P·Hᵀ` and `P·Hᵀ` exactly, so the filter then forms
    /// the measurement update's sums (eqs 3.17–3.21) in closed form from `S`: the same
    /// update, without the `2n + 1` measured points. `None` (the default) runs the
    /// sigma-point update.
    fn linear(&self) -> Option<LinearRows<'_>> {
        None
    }
    /// Whether a measurement since the step began could not be computed (see
    /// [`Process::failed`]). Never by default.
    fn failed(&self) -> bool {
        false
    }
}

/// The matrix of a linear measurement ([`Observe::linear`]).
#[derive(Debug, Clone, Copy)]
pub struct LinearRows<'a> {
    /// `H`, `p × n` row-major.
    pub h: &'a [f64],
    /// `Some(idx)` when row `i` of `H` is the unit row `e_idx[i]ᵀ` (a selection).
    pub pick: Option<&'a [usize]>,
}

impl LinearRows<'_> {
    /// Row `k` of `H` times `v` (`n` long).
    #[inline(always)]
    pub fn row_times(&self, k: usize, v: &[f64]) -> f64 {
        match self.pick {
            Some(pick) => v[pick[k]],
            None => {
                let n = v.len();
                self.h[k * n..(k + 1) * n]
                    .iter()
                    .zip(v)
                    .map(|(h, v)| h * v)
                    .sum()
            }
        }
    }
}

/// A cable-core model integrated over the filter period `dt` by `substeps` RK4 steps with the
/// input held (zero-order hold, as a servo applies it).
#[derive(Debug, Clone)]
pub struct ModelProcess<M: Model> {
    /// The continuous-time model.
    pub model: M,
    dt: f64,
    substeps: usize,
    rk4: Rk4,
    /// Four states side by side.
    narrow: LaneWork<LANES>,
    /// Eight states (two lane groups).
    wide: LaneWork<WIDE>,
    /// The CPU has AVX2 and FMA: `propagate_many` runs the fused AVX2 build.
    avx2_fma: bool,
}

impl<M: Model> ModelProcess<M> {
    /// `dt > 0` s per filter step, `substeps ≥ 1`.
    pub fn new(model: M, dt: f64, substeps: usize) -> Result<Self> {
        SimOptions::new(dt, substeps, InputHold::Zoh)?;
        let rk4 = Rk4::for_model(&model);
        let n = model.n_states();
        Ok(Self {
            model,
            dt,
            substeps,
            rk4,
            narrow: LaneWork::new(n),
            wide: LaneWork::new(n),
            avx2_fma: cpu_has_avx2_fma(),
        })
    }

    /// Filter period (s).
    pub fn dt(&self) -> f64 {
        self.dt
    }

    /// RK4 steps per period.
    pub fn substeps(&self) -> usize {
        self.substeps
    }
}

impl<M: Model> Process for ModelProcess<M> {
    fn n_states(&self) -> usize {
        self.model.n_states()
    }
    fn n_inputs(&self) -> usize {
        self.model.n_inputs()
    }
    #[inline]
    fn propagate(&mut self, x: &mut [f64], u: &[f64]) {
        let h = self.dt / self.substeps as f64;
        for _ in 0..self.substeps {
            self.rk4.step(&self.model, x, u, h);
        }
    }

    fn propagate_many(&mut self, xs: &mut [f64], u: &[f64]) {
        #[cfg(target_arch = "x86_64")]
        if self.avx2_fma {
            // SAFETY: `avx2_fma` is set only when `cpu_has_avx2_fma()`
            // (`is_x86_feature_detected!`) reported AVX2 and FMA on this CPU, which is all
            // `propagate_many_avx2` requires.
            #[allow(unsafe_code)]
            unsafe {
                return propagate_many_avx2(self, xs, u);
            }
        }
        self.propagate_lanes::<false, false>(xs, u);
    }
}

impl<M: Model> ModelProcess<M> {
    /// States go through RK4 eight at a time while more than four are left (two lane groups
    /// whose arithmetic interleaves), then four at a time (the last group padded with copies
    /// of its last state); every lane runs the same operations, so the results are those of
    /// [`Process::propagate`], bit for bit, unless `FUSED` (the AVX2 + FMA build: fused
    /// multiply-adds, the last bits differ). `AVX` moves the states in and out of lanes with
    /// AVX shuffles: only for code compiled with AVX.
    #[inline(always)]
    fn propagate_lanes<const FUSED: bool, const AVX: bool>(&mut self, xs: &mut [f64], u: &[f64]) {
        // the 3-link transmission's 12 states as a constant: the RK4 stages' loops over the
        // states unroll whole (13 % fewer instructions, 3-4 % less time per propagation)
        match self.model.n_states() {
            12 => self.propagate_lanes_n::<FUSED, AVX, 12>(xs, u),
            _ => self.propagate_lanes_n::<FUSED, AVX, 0>(xs, u),
        }
    }

    /// [`Self::propagate_lanes`] for `NS` states (any count when `NS` is 0).
    #[inline(always)]
    fn propagate_lanes_n<const FUSED: bool, const AVX: bool, const NS: usize>(
        &mut self,
        xs: &mut [f64],
        u: &[f64],
    ) {
        let count = xs.len() / self.model.n_states();
        let (model, h, k) = (&self.model, self.dt / self.substeps as f64, self.substeps);
        let mut first = 0;
        while first < count {
            let left = count - first;
            first += if left > LANES {
                self.wide
                    .run::<M, FUSED, AVX, NS>(model, xs, u, h, k, first, left.min(WIDE))
            } else {
                self.narrow
                    .run::<M, FUSED, AVX, NS>(model, xs, u, h, k, first, left)
            };
        }
    }
}

/// RK4 workspace and states in `W` lanes.
#[derive(Debug, Clone)]
struct LaneWork<const W: usize> {
    rk4: Rk4Lanes<W>,
    soa: LaneBuf<W>,
}

impl<const W: usize> LaneWork<W> {
    fn new(n: usize) -> Self {
        Self {
            rk4: Rk4Lanes::new(n),
            soa: LaneBuf::new(n),
        }
    }

    /// States `first..first + used` of `xs` (`used ≤ W`) through `substeps` RK4 steps of
    /// size `h` in `W` lanes; returns `used`. `NS` is the state count when known at compile
    /// time (0: `model.n_states()`).
    #[inline(always)]
    #[allow(clippy::too_many_arguments)] // one group of the propagation: its loop state
    fn run<M: Model, const FUSED: bool, const AVX: bool, const NS: usize>(
        &mut self,
        model: &M,
        xs: &mut [f64],
        u: &[f64],
        h: f64,
        substeps: usize,
        first: usize,
        used: usize,
    ) -> usize {
        let n = if NS == 0 { model.n_states() } else { NS };
        let soa = &mut self.soa.blocks_mut()[..n];
        gather::<AVX, W>(xs, n, first, used, soa);
        for _ in 0..substeps {
            if FUSED {
                self.rk4.step_fused(model, soa, u, h);
            } else {
                self.rk4.step(model, soa, u, h);
            }
        }
        scatter::<AVX, W>(soa, n, first, used, xs);
        used
    }
}

/// States `first..first + used` of `xs` (`n` values each) into the `W` lanes of `soa`, the
/// unused lanes filled with copies of the last state: whole blocks of four states of four
/// points by [`transpose4`] (shuffles when `AVX`), the rest value by value.
#[inline(always)]
fn gather<const AVX: bool, const W: usize>(
    xs: &[f64],
    n: usize,
    first: usize,
    used: usize,
    soa: &mut [[f64; W]],
) {
    let points: [&[f64]; W] = std::array::from_fn(|l| &xs[(first + l.min(used - 1)) * n..][..n]);
    let whole = n - n % LANES;
    for b in (0..whole).step_by(LANES) {
        for g in (0..W).step_by(LANES) {
            let rows: [Lanes; LANES] =
                std::array::from_fn(|l| points[g + l][b..b + LANES].try_into().expect("LANES"));
            for (s, lanes) in transpose4::<AVX>(&rows).iter().enumerate() {
                soa[b + s][g..g + LANES].copy_from_slice(lanes);
            }
        }
    }
    for s in whole..n {
        soa[s] = std::array::from_fn(|l| points[l][s]);
    }
}

/// The first `used` lanes of `soa` back to states `first..` of `xs` ([`gather`] reversed).
#[inline(always)]
fn scatter<const AVX: bool, const W: usize>(
    soa: &[[f64; W]],
    n: usize,
    first: usize,
    used: usize,
    xs: &mut [f64],
) {
    let whole = n - n % LANES;
    let xs = &mut xs[first * n..(first + used) * n];
    for b in (0..whole).step_by(LANES) {
        for g in (0..W).step_by(LANES) {
            let block: [Lanes; LANES] =
                std::array::from_fn(|s| soa[b + s][g..g + LANES].try_into().expect("LANES"));
            let states = transpose4::<AVX>(&block);
            for (x, s) in xs.chunks_exact_mut(n).skip(g).zip(&states) {
                x[b..b + LANES].copy_from_slice(s);
            }
        }
    }
    for (l, x) in xs.chunks_exact_mut(n).enumerate() {
        for (v, lanes) in x[whole..].iter_mut().zip(&soa[whole..n]) {
            *v = lanes[l];
        }
    }
}

#[cfg(target_arch = "x86_64")]
#[target_feature(enable = "avx2,fma")]
fn propagate_many_avx2<M: Model>(p: &mut ModelProcess<M>, xs: &mut [f64], u: &[f64]) {
    p.propagate_lanes::<true, true>(xs, u);
}

/// `x_k = A·x_{k−1} + B·u_{k−1}` (matrices row-major).
#[derive(Debug, Clone, PartialEq)]
pub struct LinearProcess {
    n: usize,
    m: usize,
    a: Vec<f64>,
    b: Vec<f64>,
    tmp: Vec<f64>,
}

impl LinearProcess {
    /// `a` is `n × n`, `b` is `n × m` (`m` may be 0), both row-major and finite.
    pub fn new(n: usize, m: usize, a: Vec<f64>, b: Vec<f64>) -> Result<Self> {
        check::len("A", &a, n * n)?;
        check::len("B", &b, n * m)?;
        check::all_finite("A", &a, n)?;
        check::all_finite("B", &b, m.max(1))?;
        Ok(Self {
            n,
            m,
            a,
            b,
            tmp: vec![0.0; n],
        })
    }
}

impl Process for LinearProcess {
    fn n_states(&self) -> usize {
        self.n
    }
    fn n_inputs(&self) -> usize {
        self.m
    }
    fn propagate(&mut self, x: &mut [f64], u: &[f64]) {
        let (n, m) = (self.n, self.m);
        for i in 0..n {
            let row = &self.a[i * n..(i + 1) * n];
            let mut s: f64 = row.iter().zip(x.iter()).map(|(a, x)| a * x).sum();
            for j in 0..m {
                s += self.b[i * m + j] * u[j];
            }
            self.tmp[i] = s;
        }
        x.copy_from_slice(&self.tmp);
    }
}

/// `y = H·x` (row-major `p × n`).
#[derive(Debug, Clone, PartialEq)]
pub struct LinearObserve {
    p: usize,
    n: usize,
    h: Vec<f64>,
    /// `Some(idx)` when every row of `H` is a unit row `e_idx[i]ᵀ`: the product is a gather
    /// (the same values for finite states, without the multiplications by zero).
    pick: Option<Vec<usize>>,
}

impl LinearObserve {
    /// `h` is `p × n` row-major and finite.
    pub fn new(p: usize, n: usize, h: Vec<f64>) -> Result<Self> {
        check::len("H", &h, p * n)?;
        check::all_finite("H", &h, n)?;
        #[allow(clippy::float_cmp)] // exact unit rows only
        let pick = h
            .chunks_exact(n.max(1))
            .map(|row| {
                let ones: Vec<usize> = (0..n).filter(|&j| row[j] != 0.0).collect();
                (ones.len() == 1 && row[ones[0]] == 1.0).then(|| ones[0])
            })
            .collect::<Option<Vec<usize>>>()
            .filter(|_| n > 0);
        Ok(Self { p, n, h, pick })
    }

    /// Measures the listed states directly (`y_i = x[idx_i]`).
    pub fn select(n: usize, idx: &[usize]) -> Result<Self> {
        let mut h = vec![0.0; idx.len() * n];
        for (i, &k) in idx.iter().enumerate() {
            if k >= n {
                return Err(CableError::InvalidParameter {
                    name: format!("measured state index [{i}]"),
                    value: k as f64,
                    requirement: "below the number of states",
                });
            }
            h[i * n + k] = 1.0;
        }
        Self::new(idx.len(), n, h)
    }

    /// State dimension.
    pub fn n_states(&self) -> usize {
        self.n
    }
}

impl Observe for LinearObserve {
    fn n_outputs(&self) -> usize {
        self.p
    }
    fn linear(&self) -> Option<LinearRows<'_>> {
        Some(LinearRows {
            h: &self.h,
            pick: self.pick.as_deref(),
        })
    }
    #[inline]
    fn observe(&mut self, x: &[f64], _u: &[f64], y: &mut [f64]) {
        if let Some(pick) = &self.pick {
            for (yi, &k) in y.iter_mut().zip(pick) {
                *yi = x[k];
            }
            return;
        }
        let n = self.n;
        for (i, yi) in y.iter_mut().enumerate().take(self.p) {
            *yi = self.h[i * n..(i + 1) * n]
                .iter()
                .zip(x)
                .map(|(h, x)| h * x)
                .sum();
        }
    }
}

/// Selected outputs of a model's (nonlinear) output map, e.g. cable tensions.
#[derive(Debug, Clone)]
pub struct ModelOutputs<M: Model> {
    /// The model whose `output` is measured.
    pub model: M,
    idx: Vec<usize>,
    buf: Vec<f64>,
}

impl<M: Model> ModelOutputs<M> {
    /// Measures outputs `idx` of `model.output`.
    pub fn new(model: M, idx: Vec<usize>) -> Result<Self> {
        let p = model.n_outputs();
        if let Some((i, &k)) = idx.iter().enumerate().find(|(_, &k)| k >= p) {
            return Err(CableError::InvalidParameter {
                name: format!("measured output index [{i}]"),
                value: k as f64,
                requirement: "below the model's number of outputs",
            });
        }
        Ok(Self {
            buf: vec![0.0; p],
            model,
            idx,
        })
    }
}

impl<M: Model> Observe for ModelOutputs<M> {
    fn n_outputs(&self) -> usize {
        self.idx.len()
    }
    fn observe(&mut self, x: &[f64], u: &[f64], y: &mut [f64]) {
        self.model.output(x, u, &mut self.buf);
        for (yi, &k) in y.iter_mut().zip(&self.idx) {
            *yi = self.buf[k];
        }
    }
}

impl<T: Process + ?Sized> Process for Box<T> {
    fn n_states(&self) -> usize {
        (**self).n_states()
    }
    fn n_inputs(&self) -> usize {
        (**self).n_inputs()
    }
    #[inline]
    fn propagate(&mut self, x: &mut [f64], u: &[f64]) {
        (**self).propagate(x, u)
    }
    fn propagate_many(&mut self, xs: &mut [f64], u: &[f64]) {
        (**self).propagate_many(xs, u)
    }
    fn project(&self, x: &mut [f64]) {
        (**self).project(x)
    }
    fn failed(&self) -> bool {
        (**self).failed()
    }
}

impl<T: Observe + ?Sized> Observe for Box<T> {
    fn n_outputs(&self) -> usize {
        (**self).n_outputs()
    }
    #[inline]
    fn observe(&mut self, x: &[f64], u: &[f64], y: &mut [f64]) {
        (**self).observe(x, u, y)
    }
    fn observe_many(&mut self, xs: &[f64], u: &[f64], ys: &mut [f64]) {
        (**self).observe_many(xs, u, ys)
    }
    fn linear(&self) -> Option<LinearRows<'_>> {
        (**self).linear()
    }
    fn failed(&self) -> bool {
        (**self).failed()
    }
}

/// A model whose selected inputs carry extra random-walk states: the state is `[x; w]` and
/// input `inputs[k]` receives `u[inputs[k]] + w[k]` (an unknown external force or torque as a
/// filter state, seed 001 §5.3).
#[derive(Debug, Clone)]
pub struct InputStates<M: Model> {
    /// The model.
    pub model: M,
    inputs: Vec<usize>,
    dt: f64,
    substeps: usize,
    rk4: Rk4,
    u: Vec<f64>,
}

impl<M: Model> InputStates<M> {
    /// `inputs`: the model input indices driven by the extra states (distinct, in range).
    pub fn new(model: M, inputs: Vec<usize>, dt: f64, substeps: usize) -> Result<Self> {
        SimOptions::new(dt, substeps, InputHold::Zoh)?;
        let m = model.n_inputs();
        for (k, &i) in inputs.iter().enumerate() {
            if i >= m || inputs[..k].contains(&i) {
                return Err(CableError::InvalidParameter {
                    name: format!("input_states[{k}]"),
                    value: i as f64,
                    requirement: "a distinct model input index",
                });
            }
        }
        let rk4 = Rk4::for_model(&model);
        Ok(Self {
            u: vec![0.0; m],
            model,
            inputs,
            dt,
            substeps,
            rk4,
        })
    }
}

impl<M: Model> Process for InputStates<M> {
    fn n_states(&self) -> usize {
        self.model.n_states() + self.inputs.len()
    }
    fn n_inputs(&self) -> usize {
        self.model.n_inputs()
    }
    fn propagate(&mut self, x: &mut [f64], u: &[f64]) {
        let n = self.model.n_states();
        self.u.copy_from_slice(u);
        for (k, &i) in self.inputs.iter().enumerate() {
            self.u[i] += x[n + k];
        }
        let h = self.dt / self.substeps as f64;
        for _ in 0..self.substeps {
            self.rk4.step(&self.model, &mut x[..n], &self.u, h);
        }
    }
}

#[cfg(test)]
mod tests {
    use super::*;
    use crate::dynamics::raven2;

    #[test]
    fn gather_and_scatter_move_states_through_lanes_for_any_state_count() {
        round_trips::<LANES>();
        round_trips::<WIDE>();
    }

    #[allow(clippy::float_cmp)] // values are moved, not computed: exact equality is the claim
    fn round_trips<const W: usize>() {
        let avx = [false, crate::lanes::cpu_has_avx2()];
        for n in [1, 3, 4, 5, 8, 11, 12, 13] {
            for count in 1..=2 * W + 1 {
                let xs: Vec<f64> = (0..n * count).map(|k| k as f64 + 0.5).collect();
                for first in (0..count).step_by(W) {
                    let used = W.min(count - first);
                    for &with_avx in &avx {
                        let mut soa = LaneBuf::<W>::new(n);
                        let soa = soa.blocks_mut();
                        soa.fill([f64::NAN; W]);
                        let mut out = vec![-1.0; n * count];
                        if with_avx {
                            #[cfg(target_arch = "x86_64")]
                            {
                                #[allow(unsafe_code)]
                                // SAFETY: the CPU reported AVX2
                                unsafe {
                                    round_trip_avx(&xs, n, first, used, soa, &mut out)
                                };
                            }
                        } else {
                            gather::<false, W>(&xs, n, first, used, soa);
                            scatter::<false, W>(soa, n, first, used, &mut out);
                        }
                        for s in 0..n {
                            for l in 0..W {
                                // unused lanes hold copies of the last state
                                let k = first + l.min(used - 1);
                                assert_eq!(soa[s][l], xs[k * n + s], "n {n} state {s} lane {l}");
                            }
                        }
                        let range = first * n..(first + used) * n;
                        assert_eq!(out[range.clone()], xs[range.clone()], "n {n} count {count}");
                        // and nothing outside the group is written
                        assert!(out[..range.start].iter().all(|&v| v == -1.0));
                        assert!(out[range.end..].iter().all(|&v| v == -1.0));
                    }
                }
            }
        }
    }

    #[cfg(target_arch = "x86_64")]
    #[target_feature(enable = "avx2")]
    fn round_trip_avx<const W: usize>(
        xs: &[f64],
        n: usize,
        first: usize,
        used: usize,
        soa: &mut [[f64; W]],
        out: &mut [f64],
    ) {
        gather::<true, W>(xs, n, first, used, soa);
        scatter::<true, W>(soa, n, first, used, out);
    }

    #[test]
    fn propagating_many_states_in_lanes_equals_one_at_a_time() {
        let model = raven2(3).unwrap();
        let n = model.n_states();
        let u = [0.1, -0.05, 0.2, 0.01, 0.0, -0.02];
        // one narrow group, one wide group partly used, wide groups then a narrow one
        for (count, substeps) in [(25, 1), (1, 3), (7, 2), (8, 1), (5, 1), (13, 2)] {
            let mut p = ModelProcess::new(model.clone(), 1e-4, substeps).unwrap();
            let mut q_m = [0.0; 3];
            let xs: Vec<f64> = (0..count)
                .flat_map(|k| {
                    let q_l = [0.7 - 0.01 * k as f64, 1.5, 0.4 + 0.001 * k as f64];
                    model.joint_to_motor(&q_l, &mut q_m);
                    let off = 1e-5 * (k as f64 - 3.0).powi(3);
                    let mut x = vec![0.0; n];
                    for i in 0..3 {
                        x[4 * i] = q_m[i] + off;
                        x[4 * i + 1] = 5.0 - k as f64;
                        x[4 * i + 2] = q_l[i];
                        x[4 * i + 3] = 0.03;
                    }
                    x
                })
                .collect();
            let mut one = xs.clone();
            for x in one.chunks_exact_mut(n) {
                p.propagate(x, &u);
            }
            // the portable lanes: the scalar RK4's operations, so its bits
            let mut plain = xs.clone();
            p.propagate_lanes::<false, false>(&mut plain, &u);
            assert_eq!(plain, one, "{count} states, {substeps} substeps");
            assert_ne!(plain, xs);
            // fused multiply-adds (correctly rounded, so `mul_add` here is the CPU's FMA):
            // within rounding of the scalar RK4
            let mut fused = xs.clone();
            p.propagate_lanes::<true, false>(&mut fused, &u);
            for (f, o) in fused.iter().zip(&one) {
                assert!((f - o).abs() <= 1e-14 * o.abs().max(1.0), "{f} vs {o}");
            }
            assert_ne!(fused, one, "the fused build fused nothing");
            // and `propagate_many` is the one this CPU runs
            let mut many = xs.clone();
            p.propagate_many(&mut many, &u);
            let want = if crate::lanes::cpu_has_avx2_fma() {
                &fused
            } else {
                &plain
            };
            assert_eq!(&many, want);
        }
    }
}
