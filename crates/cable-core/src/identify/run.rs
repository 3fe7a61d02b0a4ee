//! Recorded runs and measured channels of a diagnosis problem.

/// One measured channel.
#[derive(Debug, Clone, Copy, PartialEq)]
pub struct Channel {
    /// Index into the outputs `[T_m,1, T_m,2, T_j,1, T_j,2, θ, F_c, T_m,1 − T_m,2]`.
    pub output: usize,
    /// Residual weight (1 / noise standard deviation), > 0.
    pub weight: f64,
    /// Whether sensor-stage effects (lag, sampling, gain/bias) apply: force sensors yes,
    /// encoders no.
    pub sensor: bool,
    /// Width (odd, ≥ 1) of a centred moving average applied to the channel's residual
    /// `prediction − measurement` before weighting (1: none). For a channel whose noise is blue
    /// — a load derived as `τ − J·q̈` from an encoder — the weight is then 1 / the noise of the
    /// *averaged* residual; the window is clamped at the ends of the scored samples.
    pub window: usize,
    /// The column of the run's `commands` that this channel's measurement holds as recorded (a
    /// load derived as `τ − J·q̈` of a motor replayed from its measured angle), or `None`. An
    /// input-stage delay `d` then acts on that part of the measurement — the prediction gains
    /// `τ(t) − τ(t − d)` — and not on the motor's measured angle, which is the plant's input.
    pub command: Option<usize>,
}

impl Channel {
    /// A channel scored sample by sample (`window = 1`).
    pub fn new(output: usize, weight: f64, sensor: bool) -> Self {
        Self {
            output,
            weight,
            sensor,
            window: 1,
            command: None,
        }
    }

    /// The same channel with its residual averaged over `window` samples.
    pub fn with_window(self, window: usize) -> Self {
        Self { window, ..self }
    }

    /// The same channel holding the run's command column `command` (see [`Channel::command`]).
    pub fn with_command(self, command: usize) -> Self {
        Self {
            command: Some(command),
            ..self
        }
    }
}

/// One recorded run.
#[derive(Debug, Clone, PartialEq)]
pub struct JointRun {
    /// Sample interval (s).
    pub dt: f64,
    /// Recorded input, row-major `(T, width)`: joint `x_m` (m); transmission motor torques.
    pub input: Vec<f64>,
    /// Columns of `input` (joint 1, transmission `n`).
    pub width: usize,
    /// Initial state (the plant's layout), or empty for the default.
    pub x0: Vec<f64>,
    /// Coupled-axis signal, length `T`, or empty.
    pub coupled: Vec<f64>,
    /// External joint torque(s), row-major `(T, width)` (N·m, or N on a prismatic link), or
    /// empty (none).
    pub external: Vec<f64>,
    /// Measured channels, row-major `(T, q)`.
    pub measured: Vec<f64>,
    /// Recorded commands that are not the plant's input, row-major `(T, c)`, or empty: the torque
    /// of a motor replayed from its measured angle, held in a derived load channel
    /// ([`Channel::command`]).
    pub commands: Vec<f64>,
    /// First sample that counts in the residual.
    pub start: usize,
}

impl JointRun {
    /// Number of samples `T`.
    pub fn len(&self) -> usize {
        self.input.len() / self.width.max(1)
    }

    /// Whether the run has no samples.
    pub fn is_empty(&self) -> bool {
        self.input.is_empty()
    }

    /// Number of command columns (0 without commands).
    pub fn n_commands(&self) -> usize {
        match self.len() {
            0 => 0,
            t => self.commands.len() / t,
        }
    }

    /// Column `j` of the commands (`j < n_commands`).
    pub(crate) fn command_column(&self, j: usize) -> Vec<f64> {
        let c = self.n_commands().max(1);
        self.commands.iter().skip(j).step_by(c).copied().collect()
    }

    /// Column `c` of the input.
    pub(crate) fn input_column(&self, c: usize) -> Vec<f64> {
        self.input
            .iter()
            .skip(c)
            .step_by(self.width.max(1))
            .copied()
            .collect()
    }
}
