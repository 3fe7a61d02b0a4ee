"""Type stub of the compiled core (checked against the built module by mypy.stubtest in .ci/run)."""

import os
from collections.abc import Callable, Sequence
from typing import Any, ClassVar, final

import numpy as np
from numpy.typing import ArrayLike, NDArray
from typing_extensions import disjoint_base

__all__ = [
    "AntagonisticJoint",
    "CableNetwork",
    "CableTransmission",
    "Calibration",
    "CalibrationFit",
    "Capacity",
    "CdprPlant",
    "ClampRun",
    "ClampStep",
    "DahlElement",
    "DriveModel",
    "DualRun",
    "DualSrUkf",
    "FilterHealth",
    "FilterRun",
    "FitReport",
    "JawEstimate",
    "JawObserver",
    "JawSample",
    "JointProblem",
    "JointRun",
    "Jtdo",
    "Kinematics",
    "LoadCellPulley",
    "LoopRun",
    "Mlp",
    "Model",
    "ParamSpec",
    "PathRun",
    "PhysicsCalibration",
    "PhysicsObserver",
    "PulleyFriction",
    "Robot",
    "SignalChain",
    "SrUkf",
    "Step",
    "TensionController",
    "Tensions",
    "Twin",
    "TwinRun",
    "Winch",
    "WinchDrive",
    "__version__",
    "cable_tension",
    "capstan_ratio",
    "coulomb_friction",
    "dahl_rate",
    "effect_catalogue",
    "propose_step_raw",
    "simulate_arrays",
    "simulate_servo_arrays",
    "stribeck_friction",
]

__version__: str

_F = NDArray[np.float64]

@disjoint_base
class Model:
    @property
    def n_states(self) -> int: ...
    @property
    def n_inputs(self) -> int: ...
    @property
    def n_outputs(self) -> int: ...
    @property
    def state_names(self) -> list[str]: ...
    @property
    def input_names(self) -> list[str]: ...
    @property
    def output_names(self) -> list[str]: ...
    def rest_state(self) -> _F: ...
    def derivative(self, x: _F, u: _F) -> _F: ...
    def output(self, x: _F, u: _F, out: _F | None = None) -> _F: ...
    def rk4_step(
        self, x: _F, u: _F, dt: float, substeps: int = 1, u_next: _F | None = None, out: _F | None = None
    ) -> _F: ...
    def jacobian(self, x: _F, u: _F) -> _F: ...

@final
class CableTransmission(Model):
    def __new__(
        cls,
        *,
        motor_inertia: float | list[float],
        gear_ratio: float | list[float],
        capstan_radius: float | list[float],
        joint_radius: float | list[float],
        link_inertia: float | list[float],
        cable_stiffness: float | list[float],
        cable_damping: float | list[float] | None = None,
        pretension: float | list[float] | None = None,
        cable_law: str = "linear",
        length_scale: float = 1.0,
        joint_kind: list[str] | None = None,
        motor_coulomb: float | list[float] | None = None,
        motor_viscous: float | list[float] | None = None,
        motor_smoothing: float | list[float] | None = None,
        link_coulomb: float | list[float] | None = None,
        link_viscous: float | list[float] | None = None,
        link_smoothing: float | list[float] | None = None,
        gravity_amplitude: float | list[float] | None = None,
        gravity_offset: float | list[float] | None = None,
        coupling: list[list[float]] | None = None,
    ) -> CableTransmission: ...
    @staticmethod
    def raven2(links: int = 3) -> CableTransmission: ...
    @property
    def n_links(self) -> int: ...
    @property
    def transmission_matrix(self) -> _F: ...
    def params(self) -> dict[str, Any]: ...
    def parameter_values(self, names: list[str]) -> _F: ...
    def with_parameter_values(self, names: list[str], values: _F) -> CableTransmission: ...
    def joint_to_motor(self, q_l: _F) -> _F: ...
    def motor_to_joint(self, q_m: _F) -> _F: ...
    def energy(self, x: _F) -> float: ...

@final
class AntagonisticJoint(Model):
    def __new__(
        cls,
        *,
        radius: float,
        stiffness: float,
        inertia: float,
        damping: float = 0.0,
        pretension: float = 0.0,
        stiffness_return: float | None = None,
        damping_return: float | None = None,
        pretension_return: float | None = None,
        cable_law: str = "linear",
        length_scale: float = 1.0,
        viscous: float = 0.0,
        coulomb: float = 0.0,
        smoothing: float = 0.05,
        static_friction: float | None = None,
        stribeck_velocity: float = 1.0,
        stribeck_exponent: float = 2.0,
        capstan_mu: float = 0.0,
        capstan_wrap: float = 0.0,
        capstan_smoothing: float = 1e-3,
        contact_angle: float | None = None,
        contact_stiffness: float | None = None,
        contact_damping: float = 0.0,
        contact_lever_arm: float | None = None,
        dahl_coulomb: float | None = None,
        dahl_sigma0: float | None = None,
        dahl_exponent: float = 1.0,
        creep_fraction: float | None = None,
        creep_time_constant: float | None = None,
    ) -> AntagonisticJoint: ...
    @staticmethod
    def forceps_example() -> AntagonisticJoint: ...
    def params(self) -> dict[str, Any]: ...

@final
class CableNetwork(Model):
    @staticmethod
    def from_json(text: str) -> CableNetwork: ...
    @staticmethod
    def from_joint(joint: AntagonisticJoint) -> CableNetwork: ...
    @staticmethod
    def from_transmission(transmission: CableTransmission) -> CableNetwork: ...
    @property
    def joint_names(self) -> list[str]: ...
    @property
    def cable_names(self) -> list[str]: ...
    @property
    def motor_names(self) -> list[str]: ...
    @property
    def signal_names(self) -> list[str]: ...
    @property
    def sensors(self) -> list[tuple[str, int]]: ...
    @property
    def moment_arms(self) -> NDArray[np.float64]: ...
    def length_change(self, q: ArrayLike) -> NDArray[np.float64]: ...
    def joint_torques(self, tensions: ArrayLike) -> NDArray[np.float64]: ...
    def energy(self, x: ArrayLike, u: ArrayLike) -> float: ...
    def tension_closure(self) -> tuple[float, NDArray[np.float64]]: ...

@final
class DahlElement(Model):
    def __new__(cls, *, sigma0: float, coulomb: float, exponent: float = 1.0) -> DahlElement: ...

def simulate_arrays(
    model: Model, inputs: _F, dt: float, x0: _F | None = None, substeps: int = 1, hold: str = "zoh"
) -> tuple[_F, _F]: ...
def simulate_servo_arrays(
    model: CableTransmission,
    references: _F,
    dt: float,
    *,
    kp: list[float],
    kd: list[float],
    torque_limit: list[float],
    external: _F | None = None,
    x0: _F | None = None,
    substeps: int = 1,
) -> tuple[_F, _F, _F]: ...
def propose_step_raw(
    model: Model, dt: float, x: _F | None = None, u: _F | None = None, safety: float = 0.9
) -> tuple[float, tuple[float, float], int]: ...
def coulomb_friction(v: _F, *, coulomb: float, smoothing: float) -> _F: ...
def stribeck_friction(
    v: _F,
    *,
    coulomb: float,
    static_level: float,
    stribeck_velocity: float,
    exponent: float = 2.0,
    viscous: float = 0.0,
    smoothing: float,
) -> _F: ...
def capstan_ratio(v: _F, *, mu: float, wrap: float, smoothing: float) -> _F: ...
def dahl_rate(force: _F, v: _F, *, sigma0: float, coulomb: float, exponent: float = 1.0) -> _F: ...
def cable_tension(
    stretch: _F,
    stretch_rate: _F,
    *,
    stiffness: float,
    damping: float = 0.0,
    pretension: float = 0.0,
    law: str = "linear",
    length_scale: float = 1.0,
) -> _F: ...
def effect_catalogue() -> list[dict[str, Any]]: ...

@final
class JointRun:
    def __new__(
        cls,
        dt: float,
        input: _F,
        measured: _F,
        *,
        coupled: _F | None = None,
        external: _F | None = None,
        x0: _F | None = None,
        start: int = 0,
        commands: _F | None = None,
    ) -> JointRun: ...
    def with_measured(self, measured: _F) -> JointRun: ...
    @property
    def dt(self) -> float: ...
    def __len__(self) -> int: ...

@final
class JointProblem:
    def __new__(
        cls,
        model: Model,
        channels: Sequence[
            tuple[int, float, bool] | tuple[int, float, bool, int] | tuple[int, float, bool, int, int | None]
        ],
        runs: Sequence[JointRun],
        effects: list[str],
        substeps: int = 1,
        servo: tuple[list[float], list[float], list[float]] | None = None,
        kink_refine: int = 8,
    ) -> JointProblem: ...
    def with_effects(self, effects: list[str], substeps: int | None = None) -> JointProblem: ...
    @property
    def effects(self) -> list[str]: ...
    def candidate_library(self) -> list[dict[str, Any]]: ...
    def describe(self, id: str) -> dict[str, Any]: ...
    @property
    def n_residuals(self) -> int: ...
    def param_specs(self) -> list[ParamSpec]: ...
    def reference(self) -> _F: ...
    def predict(self, theta: _F, run: int) -> _F: ...
    def residuals(self, theta: _F) -> _F: ...
    def advised_substeps(self, theta: _F) -> int: ...
    def fit(
        self,
        theta0: _F | None = None,
        *,
        max_iter: int = 60,
        threads: int = 1,
        ftol: float = 1e-8,
        xtol: float = 1e-8,
        atol: float = 0.0,
    ) -> FitReport: ...
    def head(self, seconds: float) -> JointProblem | None: ...
    def hold_from_updates(self) -> tuple[float, float] | None: ...

@final
class SrUkf:
    def __new__(
        cls,
        model: Model,
        x0: _F,
        P0: _F,
        Q: _F,
        R: _F,
        *,
        dt: float,
        substeps: int = 1,
        states: list[int] | None = None,
        outputs: list[int] | None = None,
        H: _F | None = None,
        alpha: float = 1e-3,
        beta: float = 2.0,
        kappa: float = 0.0,
    ) -> SrUkf: ...
    @staticmethod
    def with_parameters(
        model: Model,
        params: list[str],
        x0: _F,
        P0: _F,
        Q: _F,
        R: _F,
        *,
        dt: float,
        substeps: int = 1,
        states: list[int] | None = None,
        H: _F | None = None,
        bounds: list[tuple[float, float]] | None = None,
        alpha: float = 1e-3,
        beta: float = 2.0,
        kappa: float = 0.0,
    ) -> SrUkf: ...
    @staticmethod
    def with_input_states(
        model: Model,
        inputs: list[int],
        x0: _F,
        P0: _F,
        Q: _F,
        R: _F,
        *,
        dt: float,
        substeps: int = 1,
        states: list[int] | None = None,
        H: _F | None = None,
        alpha: float = 1e-3,
        beta: float = 2.0,
        kappa: float = 0.0,
    ) -> SrUkf: ...
    @staticmethod
    def linear(
        F: _F,
        H: _F,
        x0: _F,
        P0: _F,
        Q: _F,
        R: _F,
        *,
        B: _F | None = None,
        alpha: float = 1e-3,
        beta: float = 2.0,
        kappa: float = 0.0,
    ) -> SrUkf: ...
    @staticmethod
    def from_functions(
        fx: Callable[..., ArrayLike],
        hx: Callable[..., ArrayLike],
        x0: _F,
        P0: _F,
        Q: _F,
        R: _F,
        *,
        dt: float,
        n_inputs: int = 0,
        vectorized: bool = False,
        alpha: float = 1e-3,
        beta: float = 2.0,
        kappa: float = 0.0,
    ) -> SrUkf: ...
    @property
    def n_states(self) -> int: ...
    @property
    def n_outputs(self) -> int: ...
    @property
    def n_inputs(self) -> int: ...
    @property
    def x(self) -> _F: ...
    def x_into(self, out: _F) -> _F: ...
    @property
    def S(self) -> _F: ...
    @property
    def P(self) -> _F: ...
    @property
    def weights(self) -> tuple[float, tuple[float, float], tuple[float, float]]: ...
    @property
    def nis_gate(self) -> float | None: ...
    @nis_gate.setter
    def nis_gate(self, value: float | None) -> None: ...
    @property
    def health(self) -> FilterHealth: ...
    def predict(self, u: _F) -> None: ...
    def update(self, u: _F, y: _F, mask: Sequence[bool] | None = None) -> None: ...
    def step(self, u: _F, y: _F, mask: Sequence[bool] | None = None) -> None: ...
    def reset(self, x: _F, P: _F) -> None: ...
    def run(self, U: _F, Y: _F, mask: NDArray[np.bool_] | None = None, smooth: bool = False) -> FilterRun: ...

@final
class FitReport:
    @property
    def params(self) -> _F: ...
    @property
    def cost(self) -> float: ...
    @property
    def initial_cost(self) -> float: ...
    @property
    def iterations(self) -> int: ...
    @property
    def evaluations(self) -> int: ...
    @property
    def converged(self) -> bool: ...
    @property
    def at_bound(self) -> NDArray[np.bool_]: ...
    @property
    def jacobian(self) -> _F: ...
    @property
    def residuals(self) -> _F: ...

@final
class ParamSpec:
    def __new__(
        cls,
        effect: str,
        name: str,
        unit: str,
        reference: float,
        initial: float,
        lower: float,
        upper: float,
        scale: float,
        grid: bool,
        starts: list[float],
    ) -> ParamSpec: ...
    def __getnewargs__(
        self,
    ) -> tuple[str, str, str, float, float, float, float, float, bool, list[float]]: ...
    @property
    def effect(self) -> str: ...
    @property
    def name(self) -> str: ...
    @property
    def unit(self) -> str: ...
    @property
    def reference(self) -> float: ...
    @property
    def initial(self) -> float: ...
    @property
    def lower(self) -> float: ...
    @property
    def upper(self) -> float: ...
    @property
    def scale(self) -> float: ...
    @property
    def grid(self) -> bool: ...
    @property
    def starts(self) -> list[float]: ...

@final
class FilterRun:
    @property
    def x(self) -> _F: ...
    @property
    def S(self) -> NDArray[np.float64]: ...
    @property
    def nis(self) -> _F: ...
    @property
    def condition(self) -> _F: ...
    @property
    def recovered(self) -> NDArray[np.uint32]: ...
    @property
    def measured(self) -> NDArray[np.uint64]: ...
    @property
    def gated(self) -> NDArray[np.bool_]: ...
    @property
    def x_smooth(self) -> _F | None: ...
    @property
    def S_smooth(self) -> NDArray[np.float64] | None: ...

@final
class DualRun:
    @property
    def x(self) -> _F: ...
    @property
    def theta(self) -> _F: ...
    @property
    def theta_std(self) -> _F: ...

@final
class FilterHealth:
    @property
    def nis(self) -> float: ...
    @property
    def measured(self) -> int: ...
    @property
    def condition(self) -> float: ...
    @property
    def recovered(self) -> int: ...
    @property
    def recoveries_total(self) -> int: ...
    @property
    def gated(self) -> bool: ...
    @property
    def rejected_total(self) -> int: ...
    @property
    def steps(self) -> int: ...

@final
class DualSrUkf:
    def __new__(
        cls,
        model: Model,
        params: list[str],
        x0: _F,
        P0: _F,
        Q: _F,
        P0_theta: _F,
        Q_theta: _F,
        R: _F,
        *,
        dt: float,
        substeps: int = 1,
        states: list[int],
        bounds: list[tuple[float, float]] | None = None,
        alpha: float = 1e-3,
        beta: float = 2.0,
        kappa: float = 0.0,
    ) -> DualSrUkf: ...
    @staticmethod
    def from_functions(
        fx: Callable[..., ArrayLike],
        hx: Callable[..., ArrayLike],
        x0: _F,
        P0: _F,
        Q: _F,
        theta0: _F,
        P0_theta: _F,
        Q_theta: _F,
        R: _F,
        *,
        dt: float,
        n_inputs: int = 0,
        bounds: list[tuple[float, float]] | None = None,
        alpha: float = 1e-3,
        beta: float = 2.0,
        kappa: float = 0.0,
    ) -> DualSrUkf: ...
    def run(self, U: _F, Y: _F, mask: NDArray[np.bool_] | None = None) -> DualRun: ...

@disjoint_base
class Robot:
    def __new__(
        cls,
        *,
        name: str,
        motion: str,
        anchors: _F,
        attachments: _F,
        f_min: _F,
        f_max: _F,
        ea: _F,
        mass: float,
        com: _F,
        inertia: _F,
        gravity: _F,
        pulleys: Sequence[tuple[int, float, tuple[float, float, float]]] | None = None,
    ) -> Robot: ...
    @property
    def name(self) -> str: ...
    @property
    def motion(self) -> str: ...
    @property
    def dof(self) -> int: ...
    @property
    def n_cables(self) -> int: ...
    @property
    def mass(self) -> float: ...
    @property
    def ea(self) -> _F: ...
    @property
    def bounds(self) -> tuple[_F, _F]: ...
    def inverse_kinematics(self, poses: _F) -> Kinematics: ...
    def distribute(
        self, poses: _F, wrenches: _F | None = None, *, method: str = "auto", gravity: bool = True
    ) -> Tensions: ...
    def path_friction(
        self,
        poses: _F,
        ee: _F,
        dt: float,
        coefficient: _F,
        viscous: _F,
        guide_wrap: _F,
        *,
        law: str | None = None,
        smoothing: float | None = None,
        presliding: float | None = None,
        exponent: float | None = None,
    ) -> PathRun: ...
    def project_tensions(
        self, poses: _F, tensions: _F, wrenches: _F | None = None, *, gravity: bool = True
    ) -> _F: ...
    def forward_kinematics(
        self, lengths: _F, seed: _F, tolerance: float = 1e-10
    ) -> tuple[_F, float, int, bool]: ...
    def gravity_wrench(self, pose: _F) -> _F: ...
    def points(self) -> tuple[_F, _F]: ...
    def capacity(
        self,
        poses: _F,
        wrench: _F | None = None,
        half_width: _F | None = None,
        *,
        gravity: bool = True,
        moment_length: float = 1.0,
        margins: str = "everywhere",
    ) -> Capacity: ...
    def controller(self, method: str = "auto", *, gravity: bool = True) -> TensionController: ...

@final
class Capacity:
    @property
    def margin(self) -> _F: ...
    @property
    def feasible(self) -> NDArray[np.bool_]: ...
    @property
    def degenerate(self) -> NDArray[np.bool_]: ...
    @property
    def weakest(self) -> _F: ...

@final
class Jtdo:
    def __new__(
        cls,
        *,
        r2: float,
        arm_a: float,
        arm_b: float,
        threshold: float = ...,  # 0.11 N, the seed's collision threshold
        bias: tuple[float, float] | None = None,  # None: (0.0, 0.0)
    ) -> Jtdo: ...
    def with_bias(self, bias: tuple[float, float]) -> Jtdo: ...
    def calibrated(self, measured: _F, free: _F, external: _F) -> Jtdo: ...
    @property
    def geometry(self) -> tuple[float, float, float]: ...
    @property
    def threshold(self) -> float: ...
    @property
    def bias(self) -> tuple[float, float]: ...
    def step(self, measured: _F, free: _F) -> ClampStep: ...
    def estimate(self, measured: _F, free: _F) -> ClampRun: ...

@final
class ClampStep:
    @property
    def disturbance(self) -> tuple[float, float, float, float]: ...
    @property
    def torque(self) -> tuple[float, float]: ...
    @property
    def external(self) -> tuple[float, float]: ...
    @property
    def clamping(self) -> float: ...
    @property
    def contact(self) -> tuple[bool, bool]: ...

@final
class ClampRun:
    @property
    def disturbance(self) -> _F: ...
    @property
    def torque(self) -> _F: ...
    @property
    def external(self) -> _F: ...
    @property
    def clamping(self) -> _F: ...
    @property
    def contact(self) -> NDArray[np.bool_]: ...

_Segment = tuple[str, float] | tuple[str, float, float]

@final
class Twin:
    JAW_NAMES: ClassVar[list[str]]
    SEED_SPEEDS: ClassVar[list[float]]
    def __new__(
        cls,
        a: _F,
        b: _F,
        *,
        tension_noise: float,
        pressure_noise: float,
        seed: int,
        sample_time: float,
        substeps: int,
    ) -> Twin: ...
    @staticmethod
    def seed() -> Twin: ...
    @property
    def a(self) -> _F: ...
    @property
    def b(self) -> _F: ...
    @property
    def bench(self) -> tuple[float, float, int, float, int]: ...
    def free_motion(self, speeds: list[float] = ..., pause: float = 0.2) -> TwinRun: ...
    def clamp(self, speed: float, peak: float, steps: int, dwell: float) -> TwinRun: ...
    def run(
        self,
        start_a: float,
        program_a: list[_Segment],
        start_b: float,
        program_b: list[_Segment],
        block: bool,
    ) -> TwinRun: ...

@final
class TwinRun:
    @property
    def time(self) -> _F: ...
    @property
    def motors(self) -> _F: ...
    @property
    def measured(self) -> _F: ...
    @property
    def tensions(self) -> _F: ...
    @property
    def joint_tensions(self) -> _F: ...
    @property
    def external(self) -> _F: ...
    @property
    def external_true(self) -> _F: ...
    @property
    def angles(self) -> _F: ...

@final
class PhysicsObserver:
    LOSS_NAMES: ClassVar[list[str]]
    def __new__(
        cls,
        *,
        r2: float,
        arm_a: float,
        arm_b: float,
        losses_a: _F | None = None,
        losses_b: _F | None = None,
        threshold: float = ...,  # 0.11 N, the seed's collision threshold
    ) -> PhysicsObserver: ...
    def calibrated(
        self, motors: _F, measured: _F, external: _F
    ) -> tuple[PhysicsObserver, tuple[PhysicsCalibration, PhysicsCalibration]]: ...
    @property
    def losses(self) -> _F: ...
    @property
    def geometry(self) -> tuple[float, float, float]: ...
    @property
    def threshold(self) -> float: ...
    def step(self, motors: _F, measured: _F) -> ClampStep: ...
    def reset(self) -> None: ...
    def estimate(self, motors: _F, measured: _F) -> ClampRun: ...

@final
class PhysicsCalibration:
    @property
    def losses(self) -> list[float]: ...
    @property
    def rmse_start(self) -> float: ...
    @property
    def rmse(self) -> float: ...
    @property
    def iterations(self) -> int: ...
    @property
    def converged(self) -> bool: ...

@final
class DriveModel:
    @staticmethod
    def fit(
        runs: list[_F],
        travels: list[float],
        *,
        dt: float = 1e-3,
        window: int = 20,
        warmup: float = 1.0,
        weights: list[_F] | None = None,
        angle_friction: str | tuple[float, float] | _F | None = None,
        spindle_travels: list[float] | None = None,
    ) -> DriveModel: ...
    def recalibrated(self, run: _F | list[_F], *, dt: float = 1e-3, friction: bool = False) -> DriveModel: ...
    def estimate(self, run: _F, *, dt: float = 1e-3) -> JawEstimate: ...
    def observer(self, *, dt: float = 1e-3) -> JawObserver: ...
    @property
    def coefficients(self) -> list[float]: ...
    @property
    def angle_coefficients(self) -> list[float]: ...
    @property
    def travels(self) -> list[float]: ...
    @property
    def ranges(self) -> list[list[float]]: ...
    @property
    def angle_friction_span(self) -> tuple[float, float] | None: ...
    @property
    def spindle_travels(self) -> list[float]: ...

@final
class JawObserver:
    def step(self, spindle_angle: float, spindle_torque: float, motor_angle: float) -> JawSample: ...
    def reset(self) -> None: ...

@final
class JawSample:
    @property
    def torque(self) -> float: ...
    @property
    def angle(self) -> float: ...
    @property
    def outside(self) -> bool: ...

@final
class JawEstimate:
    @property
    def torque(self) -> _F: ...
    @property
    def angle(self) -> _F: ...
    @property
    def outside_share(self) -> float: ...

@final
class Winch:
    NAMES: ClassVar[list[str]]
    def __new__(cls, values: _F) -> Winch: ...
    @staticmethod
    def seed003() -> Winch: ...
    @property
    def values(self) -> _F: ...
    @property
    def load(self) -> tuple[float, float]: ...
    def open_loop(self, setup: str, lpf: bool) -> tuple[_F, _F]: ...
    def zeros_and_poles(self, setup: str, lpf: bool) -> tuple[_F, _F]: ...
    def root_locus(self, setup: str, lpf: bool, kps: list[float]) -> _F: ...
    def dominant(
        self, setup: str, lpf: bool, kp: float
    ) -> tuple[tuple[float, float], float, float] | None: ...

@final
class PathRun:
    @property
    def pul(self) -> _F: ...
    @property
    def friction(self) -> _F: ...
    @property
    def speed(self) -> _F: ...
    @property
    def wrap(self) -> _F: ...

@final
class LoadCellPulley:
    def __new__(cls, angle_1: float, angle_2: float) -> LoadCellPulley: ...
    @property
    def ratio(self) -> float: ...
    def push(self, tension: float) -> float: ...
    def tension_range(self, rating: float) -> float: ...

@final
class Calibration:
    def __new__(cls, gain: float, offset: float) -> Calibration: ...
    @property
    def gain(self) -> float: ...
    @property
    def offset(self) -> float: ...
    def tension(self, readings: _F) -> _F: ...
    @staticmethod
    def fit(
        loading_loads: _F, loading_readings: _F, unloading_loads: _F, unloading_readings: _F
    ) -> CalibrationFit: ...

@final
class CalibrationFit:
    @property
    def calibration(self) -> Calibration: ...
    @property
    def correlation(self) -> float: ...
    @property
    def residual_rms(self) -> float: ...
    @property
    def residual_max(self) -> float: ...
    @property
    def hysteresis(self) -> float: ...
    @property
    def hysteresis_fraction(self) -> float: ...

@final
class SignalChain:
    def __new__(cls, conversion_time: float, latency: float) -> SignalChain: ...
    @staticmethod
    def hx711_ble() -> SignalChain: ...
    @property
    def conversion_time(self) -> float: ...
    @property
    def latency(self) -> float: ...
    def apply(self, t: _F, signal: _F) -> _F: ...

@final
class WinchDrive(Model):
    def __new__(
        cls,
        winch: Winch | None = None,
        *,
        setup: str | None = None,
        lpf: bool | None = None,
        pretension: float | None = None,
        current_limit: float | None = None,
        friction_smoothing: float | None = None,
        cable_damping: float | None = None,
        control: str | None = None,
    ) -> WinchDrive: ...
    @staticmethod
    def seed003() -> WinchDrive: ...
    @property
    def winch(self) -> Winch: ...
    @property
    def setup(self) -> str: ...
    @property
    def lpf(self) -> bool: ...
    @property
    def control(self) -> str: ...
    @property
    def settings(self) -> tuple[float, float, float, float]: ...

@final
class PulleyFriction:
    def __new__(
        cls,
        coefficient: _F,
        viscous: _F,
        guide_wrap: _F,
        *,
        law: str | None = None,
        smoothing: float | None = None,
        presliding: float | None = None,
        exponent: float | None = None,
    ) -> PulleyFriction: ...

@final
class CdprPlant(Model):
    def __new__(
        cls,
        robot: Robot,
        home: _F,
        winch: Winch | None = None,
        *,
        lpf: bool | None = None,
        current_limit: float | None = None,
        friction_smoothing: float | None = None,
        cable_damping: float | None = None,
        drum_side: PulleyFriction | None = None,
        platform_side: PulleyFriction | None = None,
        home_tensions: _F | None = None,
        creep: tuple[_F, _F] | None = None,
        drum_friction: _F | None = None,
    ) -> CdprPlant: ...
    @property
    def home(self) -> _F: ...
    @property
    def home_tensions(self) -> _F: ...
    @property
    def rest_length(self) -> _F: ...
    @property
    def tension_per_ampere(self) -> float: ...
    @property
    def winch(self) -> Winch: ...
    def closed_loop(
        self,
        poses: _F,
        dt: float,
        *,
        substeps: int = 5,
        method: str = "auto",
        gain: float = 0.0,
        feedback: str = "open",
        sensor_delay: int = 0,
        current_feedforward: bool = True,
        sensor_noise: _F | None = None,
        tension_offset: _F | None = None,
        network: Mlp | None = None,
    ) -> LoopRun: ...

@final
class LoopRun:
    @property
    def pose(self) -> _F: ...
    @property
    def desired(self) -> _F: ...
    @property
    def ee(self) -> _F: ...
    @property
    def sensor(self) -> _F: ...
    @property
    def feedback(self) -> _F: ...
    @property
    def current(self) -> _F: ...
    @property
    def alpha(self) -> _F: ...
    @property
    def wrench_desired(self) -> _F: ...
    @property
    def wrench_ee(self) -> _F: ...
    @property
    def wrench_sensor(self) -> _F: ...
    @property
    def wrench_feedback(self) -> _F: ...
    @property
    def infeasible(self) -> int: ...
    @property
    def inputs(self) -> _F: ...
    @property
    def initial_state(self) -> _F: ...

@final
class TensionController:
    def step(self, pose: _F, wrench: _F | None = None, out: _F | None = None) -> Step: ...
    def reset(self) -> None: ...
    @property
    def method(self) -> str: ...

@final
class Step:
    @property
    def f(self) -> _F: ...
    @property
    def method(self) -> str: ...
    @property
    def feasible(self) -> bool: ...
    @property
    def residual(self) -> float: ...
    @property
    def jump(self) -> float: ...

@final
class Kinematics:
    @property
    def length(self) -> _F: ...
    @property
    def structure(self) -> _F: ...

@final
class Tensions:
    @property
    def f(self) -> _F: ...
    @property
    def method(self) -> list[str]: ...
    @property
    def feasible(self) -> NDArray[np.bool_]: ...
    @property
    def residual(self) -> _F: ...

@final
class Mlp:
    @staticmethod
    def load(path: str | os.PathLike[str]) -> Mlp: ...
    @staticmethod
    def from_bytes(data: bytes) -> Mlp: ...
    def to_bytes(self) -> bytes: ...
    def save(self, path: str | os.PathLike[str]) -> None: ...
    def predict(self, x: _F) -> _F: ...
    def predict_into(self, x: _F, out: _F) -> None: ...
    @property
    def sizes(self) -> list[int]: ...
    @property
    def activations(self) -> list[str]: ...
    @property
    def n_inputs(self) -> int: ...
    @property
    def n_outputs(self) -> int: ...
    @property
    def input_names(self) -> list[str]: ...
    @property
    def input_units(self) -> list[str]: ...
    @property
    def output_names(self) -> list[str]: ...
    @property
    def output_units(self) -> list[str]: ...
    @property
    def metadata(self) -> dict[str, str]: ...
    def layers(self) -> list[tuple[_F, _F]]: ...
    def input_range(self) -> tuple[_F, _F]: ...
    def output_range(self) -> tuple[_F, _F]: ...
