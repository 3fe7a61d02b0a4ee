"""O'Neill et al. (RA-L 2018), experiments 1–2, the way their MATLAB code runs them, and the strict
folds of the same folder beside it (issue #37 §1).

Their protocol (``RAL-2018/`` in the data's upstream repository: ``compileDataRPY.m``,
``segmentData.m``, ``neuralNetDriver.m``, ``trainNeuralNet.m``, ``validateNetwork.m``):

* every column low-passed with a 3rd-order Butterworth filter, 3 dB at 50 Hz, applied forwards
  and backwards (``filtfilt``: zero phase, non-causal); the spindle's velocity is the
  11-point Holoborodko smooth differentiator of the filtered angle;
* each run trimmed by 1 s at both ends and cut to its **closing portions**: the samples whose
  filtered spindle velocity is at most −0.25 rad/s (left jaw);
* all runs' remaining samples concatenated and split **at random, sample by sample**, 70 % train,
  15 % validation, 15 % test (``dividerand``); a 30-neuron ``logsig`` network trained with
  Bayesian regularisation (``trainbr``) on the training samples; the score is the RMSE on the
  test samples against the **filtered** jaw torque.

A random split of samples puts a test sample between training samples a millisecond away: the
protocol measures interpolation inside runs the model has seen. The strict folds beside it leave
a whole frequency or a whole load level out.

Here the zero-phase filter is applied in the frequency domain (the filtfilt magnitude
``|H|²`` of the bilinear-transform Butterworth, odd-reflection padding); it differs from MATLAB's
``filtfilt`` only in the end transients, which the 1 s trim removes.
"""

from __future__ import annotations

import math
from collections.abc import Callable, Sequence
from dataclasses import dataclass, field

import numpy as np
from numpy.typing import NDArray

from cablekit._args import Epochs, Seed, checked, count, instance, real, signal
from cablekit.errors import CablekitError, DataError, ParameterError
from cablekit.forceps.davinci import PUBLISHED_RMSE, BenchRun, Estimator, Physics, _skip, score

__all__ = [
    "CLOSING_SPEED",
    "PaperRow",
    "closing_mask",
    "holoborodko",
    "lowpass_zero_phase",
    "paper_protocol",
    "paper_split",
    "strict_folds",
]

F64 = NDArray[np.float64]

#: the filter of ``compileDataRPY.m``: order and 3 dB frequency (Hz)
FILTER_ORDER = 3
FILTER_HZ = 50.0
#: ``segmentData.m``: closing portions (rad/s of spindle velocity, left jaw) and the trim (s)
CLOSING_SPEED = 0.25
TRIM_S = 1.0
#: ``trainNeuralNet.m``: dividerand's shares
SPLIT = (0.70, 0.15, 0.15)
#: training rows given to the network (every k-th of the training samples; theirs trained on
#: all for hours)
NET_ROWS = 20_000


@checked
def lowpass_zero_phase(x: F64, dt: float, hz: float = FILTER_HZ, order: int = FILTER_ORDER) -> F64:
    """``x`` (1-D or ``(T, k)`` columns) through a Butterworth low-pass of ``order`` and 3 dB
    frequency ``hz``, forwards and backwards: the gain ``1 / (1 + (tan(ω/2) / tan(ω_c/2))^{2N})``
    at every frequency, no phase."""
    x = signal(x, "x")
    # a cut-off below 1e-9 of the sample rate is no filter (its period exceeds any run)
    dt, hz = real(dt, "dt", lo=1e-9, hi=1e3), real(hz, "hz", lo=1e-9 / dt)
    if x.ndim not in (1, 2) or x.shape[0] < 2:
        raise DataError(f"lowpass_zero_phase needs a 1-D or 2-D array of at least 2 rows, got {x.shape}")
    if not np.isfinite(x).all():
        raise DataError("lowpass_zero_phase: the signal has NaN or inf")
    if not (math.isfinite(dt) and dt > 0 and math.isfinite(hz) and 0 < hz < 0.5 / dt):
        raise ParameterError(f"need dt > 0 and 0 < hz < the Nyquist frequency, got dt={dt}, hz={hz}")
    if not (isinstance(order, int) and 1 <= order <= 12):
        raise ParameterError(f"order must be an integer in 1..12, got {order!r}")
    n = x.shape[0]
    pad = min(n - 1, max(1, round(1.0 / (hz * dt)) * 20))
    head = 2 * x[:1] - x[pad:0:-1]
    tail = 2 * x[-1:] - x[-2 : -pad - 2 : -1]
    ext = np.concatenate([head, x, tail], axis=0)
    w = np.pi * np.fft.rfftfreq(ext.shape[0])  # ω/2 in [0, π/2]
    ratio = np.tan(np.minimum(w, np.pi / 2 - 1e-12)) / math.tan(math.pi * hz * dt)
    gain = 1.0 / (1.0 + ratio ** (2 * order))
    spec = np.fft.rfft(ext, axis=0)
    out = np.fft.irfft(spec * (gain if x.ndim == 1 else gain[:, None]), n=ext.shape[0], axis=0)
    return np.ascontiguousarray(out[pad : pad + n])


@checked
def holoborodko(x: F64, dt: float) -> F64:
    """Derivative of ``x`` by the 11-point smooth noise-robust differentiator (Holoborodko), ends
    mirrored about the first and last sample as ``filteredDerivative.m`` does."""
    x = signal(x, "x")
    dt = real(dt, "dt", lo=1e-9, hi=1e3)
    s = 5
    if x.ndim != 1 or x.size < s + 2:
        raise DataError(f"holoborodko needs a 1-D array of at least {s + 2} samples, got {x.shape}")
    if not (math.isfinite(dt) and dt > 0):
        raise ParameterError(f"dt must be > 0, got {dt}")
    f = np.concatenate([2 * x[0] - x[s:0:-1], x, 2 * x[-1] - x[-2 : -s - 2 : -1]])
    c = {1: 322.0, 2: 256.0, 3: 39.0, 4: -32.0, 5: -11.0}
    n = x.size
    d = np.zeros(n)
    for k, ck in c.items():
        d += ck * (f[s + k : s + k + n] - f[s - k : s - k + n])
    return d / (1536.0 * dt)


@dataclass(frozen=True)
class _Filtered:
    run: BenchRun
    angle: F64
    velocity: F64
    torque: F64
    jaw: F64
    closing: NDArray[np.bool_]


def _filtered(run: BenchRun) -> _Filtered:
    cols = lowpass_zero_phase(np.column_stack([run.signals[:, 0], run.signals[:, 1], run.jaw_torque]), run.dt)
    v = holoborodko(cols[:, 0], run.dt)
    return _Filtered(run, cols[:, 0], v, cols[:, 1], cols[:, 2], closing_mask(run, v))


@checked
def closing_mask(run: BenchRun, velocity: F64 | None = None) -> NDArray[np.bool_]:
    """The samples ``segmentData.m`` keeps: 1 s in from both ends, filtered spindle velocity at
    most −0.25 rad/s."""
    v = holoborodko(lowpass_zero_phase(run.signals[:, 0], run.dt), run.dt) if velocity is None else velocity
    t = np.arange(v.size) * run.dt
    return (t >= TRIM_S) & (t <= t[-1] - TRIM_S) & (v <= -CLOSING_SPEED)


@checked
def paper_split(masks: Sequence[NDArray[np.bool_]], seed: Seed = 0) -> list[NDArray[np.int8]]:
    """dividerand over the concatenated kept samples: per run, ``0`` not kept, ``1`` train,
    ``2`` validation, ``3`` test."""
    instance(masks, "masks", list | tuple)
    masks = [instance(m, f"masks[{k}]", np.ndarray) for k, m in enumerate(masks)]
    if any(m.dtype != np.bool_ or m.ndim != 1 for m in masks):
        raise DataError("masks must be 1-D boolean arrays, one per run")
    seed = count(seed, "seed", hi=2**63 - 1)
    sizes = [int(m.sum()) for m in masks]
    total = sum(sizes)
    if total < 20:
        raise DataError(f"the closing portions hold {total} samples; the split needs at least 20")
    perm = np.random.default_rng(seed).permutation(total)
    labels = np.empty(total, dtype=np.int8)
    n_train, n_val = round(SPLIT[0] * total), round(SPLIT[1] * total)
    labels[perm[:n_train]] = 1
    labels[perm[n_train : n_train + n_val]] = 2
    labels[perm[n_train + n_val :]] = 3
    out, off = [], 0
    for m, k in zip(masks, sizes, strict=True):
        lab = np.zeros(m.size, dtype=np.int8)
        lab[m] = labels[off : off + k]
        out.append(lab)
        off += k
    return out


@dataclass(frozen=True)
class PaperRow:
    """One estimator in one protocol of the folder: pooled RMSE and the worst run's (mN·m) over
    the scored samples, and what it was trained and scored on."""

    protocol: str
    estimator: str
    rmse_mnm: float
    worst_run_mnm: float
    scored: str
    notes: list[str] = field(default_factory=list)

    @property
    def meets_anchor(self) -> bool:
        return self.worst_run_mnm <= PUBLISHED_RMSE


def _pooled(errors: list[F64]) -> tuple[float, float]:
    e = np.concatenate(errors) * 1e3
    worst = max(float(np.sqrt(np.mean(x**2))) * 1e3 for x in errors if x.size)
    return float(np.sqrt(np.mean(e**2))), worst


def _their_inputs(f: _Filtered) -> F64:
    """inputArray{4} of ``train_torque.m``: filtered spindle angle, its filtered velocity and the
    filtered spindle torque."""
    return np.column_stack([f.angle, f.velocity, f.torque])


@checked
def paper_protocol(
    runs: Sequence[BenchRun], seed: Seed = 0, networks: bool = True, epochs: Epochs = 200
) -> list[PaperRow]:
    """Their experiment on ``runs`` (one folder): our estimators and a network of theirs, each
    trained on the training samples and scored on the test samples (see the module docs)."""
    if len(runs) < 2:
        raise DataError(f"the paper protocol needs the runs of a folder, got {len(runs)}")
    filt = [_filtered(r) for r in runs]
    labels = paper_split([f.closing for f in filt], seed)
    rows: list[PaperRow] = []
    scored = f"test samples ({SPLIT[2]:.0%}) of the closing portions, filtered jaw torque"

    def errors(pred: Callable[[int, _Filtered], F64]) -> tuple[float, float]:
        errs = [pred(i, f)[labels[i] == 3] - f.jaw[labels[i] == 3] for i, f in enumerate(filt)]
        return _pooled(errs)

    # the drive model on their training samples only, then also on everything outside the
    # closing portions (more of each run's reversals; never a test sample). Their closing samples
    # move the spindle one way only, which cannot identify the spindle-driven friction elements:
    # that row fits the motor-driven ones alone
    for label, weight, spindle in (
        (
            "physics (drive model, motor-driven friction only), their training samples",
            lambda lab: (lab == 1).astype(float),
            False,
        ),
        (
            "physics (drive model), their training samples + non-closing samples",
            lambda lab: ((lab == 1) | (lab == 0)).astype(float),
            True,
        ),
    ):
        try:
            est = Physics.fit(runs, weights=[weight(lab) for lab in labels], spindle=spindle)
            r, w = errors(lambda i, f, est=est: est.predict(f.run)[0])
            rows.append(PaperRow("paper (RA-L 2018)", label, r, w, scored))
        except CablekitError as exc:  # a degenerate design: a row with its reason, not a crash
            rows.append(PaperRow("paper (RA-L 2018)", label, math.nan, math.nan, scored, [str(exc)]))
    # the best linear map of their inputs
    x = np.vstack([_their_inputs(f)[labels[i] == 1] for i, f in enumerate(filt)])
    y = np.concatenate([f.jaw[labels[i] == 1] for i, f in enumerate(filt)])
    design = np.column_stack([np.ones(len(x)), x])
    coef = np.linalg.lstsq(design, y, rcond=None)[0]
    r, w = errors(lambda i, f: np.column_stack([np.ones(f.jaw.size), _their_inputs(f)]) @ coef)
    rows.append(
        PaperRow("paper (RA-L 2018)", "linear map of their inputs (angle, velocity, torque)", r, w, scored)
    )
    if networks:
        from cablekit.nn import to_mlp, train_mlp

        every = max(1, len(x) // NET_ROWS)
        res = train_mlp(
            x[::every],
            y[::every, None] * 1e3,
            method="br",
            hidden=(30,),
            activation="logsig",
            test_fraction=0.0,
            epochs=epochs,
            seed=seed,
            progress=False,
        )
        mlp = to_mlp(res)
        r, w = errors(lambda i, f: mlp.predict(np.ascontiguousarray(_their_inputs(f)))[:, 0] * 1e-3)  # type: ignore[attr-defined]
        note = f"trained on every {every}th training sample ({len(x[::every])} rows), {epochs} epochs"
        rows.append(
            PaperRow(
                "paper (RA-L 2018)",
                "their network: 3-30-1 logsig, Bayesian regularisation",
                r,
                w,
                scored,
                [note],
            )
        )
    return rows


def _digit(run: BenchRun, position: int) -> int | None:
    name = run.name
    return int(name[position]) if name.isdigit() and len(name) >= 2 else None


@checked
def strict_folds(
    runs: Sequence[BenchRun], fitters: dict[str, Callable[[Sequence[BenchRun]], Estimator]]
) -> list[PaperRow]:
    """Leave one frequency out and leave one load level out over the runs ``XY`` of one folder
    (X the frequency, Y the load index, as the bench names them): every estimator trained on the
    other runs, scored on the left-out runs after their warm-up against the raw jaw torque,
    pooled over the folds (and the worst run of all folds)."""
    rows = []
    for protocol, pos in (("leave one frequency out", -2), ("leave one load out", -1)):
        groups: dict[int, list[BenchRun]] = {}
        for r in runs:
            d = _digit(r, pos)
            if d is not None:
                groups.setdefault(d, []).append(r)
        if len(groups) < 2:
            raise DataError(
                f"{protocol} needs runs named XY with at least two values, got {[r.name for r in runs]}"
            )
        for name, fit in fitters.items():
            sq, n, worst = 0.0, 0, 0.0
            for test in groups.values():
                train = [r for r in runs if all(r is not t for t in test)]
                s = score(fit(train), test)
                m = sum(len(r.jaw_torque) - _skip(r) for r in test)
                sq += s.rmse_mnm**2 * m
                n += m
                worst = max(worst, s.worst_run_mnm)
            rows.append(
                PaperRow(
                    protocol,
                    name,
                    math.sqrt(sq / n),
                    worst,
                    f"{len(groups)} folds, whole runs after the warm-up",
                )
            )
    return rows
