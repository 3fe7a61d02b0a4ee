"""The CDPR diagnosis on runs from a simulator written independently of cablekit's plant (issue
#23: "a score on our own generator is not evidence"): SciPy's LSODA integrates four winches, each
hauling a cable onto a sprung load under a PI tension loop on its motor current, with its own
forms for what the diagnosis looks for:

* drum friction ``τ_st·tanh(ω/ε)`` (the diagnosis assumes ``ω/√(ω² + ε²)``);
* a pulley between drum and sensor as a capstan, ``T_drum = T_sensor·exp(μθ·tanh(v/ε))``
  (multiplicative; the candidate is additive Coulomb);
* a sensor lag as a first-order low-pass of 60 ms read through a 20 Hz sample-and-hold (the
  candidate is a pure delay);
* a calibration error.

Nothing here is shared with ``cable_core::cdpr::CdprPlant`` except the winch's parameter values.
"""

from __future__ import annotations

import numpy as np
import pytest
from scipy import integrate as scipy_integrate

from cablekit.cdpr import Winch
from cablekit.cdpr.diagnose import diagnose

W = dict(zip(Winch.NAMES, Winch.seed003().values, strict=True))
M = 4


def _simulate(effect: str | None, cable: int, seed: int) -> tuple[np.ndarray, ...]:
    rng = np.random.default_rng(seed)
    r = W["drum_radius"]
    jl = W["rotor_inertia"] * W["gear_ratio"] ** 2 + W["gearbox_inertia"] + W["drum_inertia"]
    bl = W["rotor_viscous"] * W["gear_ratio"] ** 2 + W["drum_viscous"]
    kt = W["torque_constant"] * W["gear_ratio"]
    k_cable, m_load, k_load, c_load = 2.0e4, 0.8, 300.0, 8.0
    # each cable's tension reference: a mean and two incommensurate sines
    mean = rng.uniform(15.0, 25.0, M)
    amp = rng.uniform(4.0, 8.0, (M, 2))
    freq = rng.uniform(0.15, 0.6, (M, 2))
    phase = rng.uniform(0, 2 * np.pi, (M, 2))

    def reference(t: float) -> np.ndarray:
        return mean + (amp * np.sin(2 * np.pi * freq * t + phase)).sum(axis=1)

    mu_theta = np.zeros(M)
    if effect == "pulley_friction":
        mu_theta[cable] = 0.12
    kp_i, ki_i = 0.02, 0.6  # the current loop on the sensor's tension: A/N, A/(N·s)

    def tensions(y: np.ndarray) -> tuple[np.ndarray, np.ndarray]:
        alpha, omega, x = y[0:M], y[M : 2 * M], y[2 * M : 3 * M]
        t_sensor = np.maximum(k_cable * (r * alpha - x), 0.0)
        t_drum = t_sensor * np.exp(mu_theta * np.tanh(r * omega / 2e-3))
        return t_sensor, t_drum

    def current(t: float, y: np.ndarray) -> np.ndarray:
        t_sensor, _ = tensions(y)
        err = reference(t) - t_sensor
        return np.clip(r * reference(t) / kt + kp_i * err + ki_i * y[4 * M : 5 * M], -10, 10)

    def rhs(t: float, y: np.ndarray) -> np.ndarray:
        omega, x, v = y[M : 2 * M], y[2 * M : 3 * M], y[3 * M : 4 * M]
        t_sensor, t_drum = tensions(y)
        i = current(t, y)
        torque = kt * i - bl * omega - W["static_friction"] * np.tanh(omega / 0.01) - r * t_drum
        return np.concatenate(
            [omega, torque / jl, v, (t_sensor - k_load * x - c_load * v) / m_load, reference(t) - t_sensor]
        )

    # start at rest holding the mean tensions
    x0 = mean / k_load
    y0 = np.concatenate([(mean / k_cable + x0) / r, np.zeros(M), x0, np.zeros(2 * M)])
    t = np.arange(0.0, 20.0, 1e-3)
    sol = scipy_integrate.solve_ivp(rhs, (0.0, t[-1]), y0, t_eval=t, method="LSODA", rtol=1e-8, atol=1e-10)
    assert sol.success
    y = sol.y.T
    sensor = np.array([tensions(row)[0] for row in y])
    cur = np.array([current(tt, row) for tt, row in zip(t, y, strict=True)])
    if effect == "sensor_lag":
        lag, a = np.empty(t.size), 1e-3 / 0.06
        lag[0] = sensor[0, cable]
        for k in range(1, t.size):
            lag[k] = lag[k - 1] + a * (sensor[k, cable] - lag[k - 1])
        held = np.floor(t / 0.05) * 0.05  # 20 Hz sample-and-hold
        sensor[:, cable] = np.interp(held, t, lag)
    elif effect == "sensor_gain":
        sensor[:, cable] = 0.95 * sensor[:, cable] - 0.5
    sensor = sensor + rng.normal(0.0, 0.1, sensor.shape)
    cur = cur + rng.normal(0.0, 0.003, cur.shape)
    return t, y[:, :M], cur, sensor


@pytest.mark.parametrize(
    ("effect", "cable"), [("pulley_friction", 2), ("sensor_lag", 1), ("sensor_gain", 3), (None, 0)]
)
def test_the_diagnosis_locates_effects_in_an_independent_simulator(effect, cable):
    t, alpha, current, sensor = _simulate(effect, cable, seed=7 + cable)
    d = diagnose(Winch.seed003(), t, alpha, current, sensor)
    assert d.length is None
    if effect is None:
        assert d.force.found is None, d.summary()
    else:
        assert d.force.found is not None, d.summary()
        assert (d.force.found.effect, d.force.found.cable) == (effect, cable), d.summary()


# ---- the length channel: a quasi-static planar robot with its own cable laws -----------------
#
# Written from the physics, not from the plant: seed 003's planar robot moves slowly along a
# Lissajous path holding its weight, its internal force swept; each cable's unstretched length
# follows from the geometric length less the stretch of the cable law below, and the drum angle
# from the unstretched length. The laws differ in form from the candidates':
#
# * a softer cable with a toe region: δ = T·L/(0.6·E·A)·(1 + 0.2·e^(−T/5 N)) (the candidate is
#   linear);
# * creep as a Burgers body: a Kelvin–Voigt element (ρ = 0.4, τ = 8 s) plus a Maxwell dashpot's
#   irreversible flow (the candidate has one Kelvin–Voigt element and no flow);
# * a cable whose drum was zeroed 0.3 mm off.


def _lengths_run(effect: str | None, cable: int, seed: int):
    from cablekit.cdpr import shipped
    from cablekit.cdpr.diagnose import Lengths
    from cablekit.cdpr.planar import HOME

    rng = np.random.default_rng(seed)
    robot = shipped("seed003_planar")
    dt, t_end = 1e-3, 40.0
    t = np.arange(0.0, t_end, dt)
    poses = np.tile(HOME, (t.size, 1))
    poses[:, 0] += 0.06 * np.sin(2 * np.pi * t / 13.0)
    poses[:, 1] += 0.04 * np.sin(2 * np.pi * t / 9.0 + 0.7)
    base = robot.distribute(poses).f
    at = robot.inverse_kinematics(poses).structure  # (T, 3, 4)
    null = np.linalg.svd(at)[2][:, -1, :]  # (T, 4): A^T n = 0
    null *= np.sign(null.sum(axis=1, keepdims=True))
    freq = rng.uniform(0.02, 0.2, 3)
    phase = rng.uniform(0, 2 * np.pi, 3)
    sweep = 12.0 + 8.0 * np.sin(2 * np.pi * freq[:, None] * t + phase[:, None]).mean(axis=0)
    tension = base + sweep[:, None] * null / np.abs(null).max(axis=1, keepdims=True)
    assert (tension > 1.0).all()
    ea = robot.ea
    length = robot.inverse_kinematics(poses).length
    stretch = tension * length / ea
    if effect == "cable_elasticity":
        j = cable
        toe = 1 + 0.2 * np.exp(-tension[:, j] / 5.0)
        stretch[:, j] = tension[:, j] * length[:, j] / (0.6 * ea[j]) * toe
    elif effect == "cable_creep":
        j, kv, flow = cable, 0.0, 0.0
        a = np.exp(-dt / 8.0)
        target = 0.4 * stretch[:, j]
        extra = np.empty(t.size)
        kv = target[0]
        for k in range(t.size):
            kv = a * kv + (1 - a) * target[k]
            flow += dt * stretch[k, j] / 400.0  # 0.25 %/s of the elastic stretch
            extra[k] = kv + flow
        stretch[:, j] += extra
    unstretched = length - stretch
    w = dict(zip(Winch.NAMES, Winch.seed003().values, strict=True))
    r = w["drum_radius"]
    rest = unstretched[0].copy()
    if effect == "length_offset":
        rest[cable] += 3e-4
    alpha = (unstretched[0] - unstretched) / r
    rate = np.gradient(alpha, t, axis=0)
    acc = np.gradient(rate, t, axis=0)
    jl, bl = Winch.seed003().load
    kt = w["torque_constant"] * w["gear_ratio"]
    current = (jl * acc + bl * rate + w["static_friction"] * np.tanh(rate / 0.01) + r * tension) / kt
    current += rng.normal(0.0, 0.003, current.shape)
    sensor = tension + rng.normal(0.0, 0.1, tension.shape)
    measured = poses + rng.normal(0.0, [10e-6, 10e-6, 20e-6], poses.shape)
    return t, alpha, current, sensor, Lengths(robot, rest, measured)


@pytest.mark.parametrize(
    ("effect", "cable"),
    [("cable_elasticity", 1), ("cable_creep", 2), ("length_offset", 0), (None, 0)],
)
def test_the_length_channel_locates_cable_effects_written_independently(effect, cable):
    t, alpha, current, sensor, lengths = _lengths_run(effect, cable, seed=11 + cable)
    d = diagnose(Winch.seed003(), t, alpha, current, sensor, lengths=lengths)
    assert d.length is not None
    assert d.force.found is None, d.summary()
    if effect is None:
        assert d.length.found is None, d.summary()
    else:
        assert d.length.found is not None, d.summary()
        assert (d.length.found.effect, d.length.found.cable) == (effect, cable), d.summary()
