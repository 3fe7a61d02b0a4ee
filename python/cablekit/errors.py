"""The cablekit exception hierarchy.

Every error raised by cablekit, from Rust or Python, is a :class:`CablekitError`. The compiled core
maps each typed Rust error to one of these classes by name, so they also derive from the matching
built-in (``except ValueError`` keeps working).
"""

from __future__ import annotations


class CablekitError(Exception):
    """Base class of every cablekit error."""


class ShapeError(CablekitError, ValueError):
    """An array has the wrong number of dimensions, rows or columns. ``argument`` names it."""


class DTypeError(CablekitError, TypeError):
    """An array is not a ``numpy.ndarray`` of ``float64``."""


class LayoutError(CablekitError, ValueError):
    """An array is not C-contiguous (cablekit never copies behind your back)."""


class NotFiniteError(CablekitError, ValueError):
    """An input holds NaN or inf. ``argument`` and flat ``index`` say where."""


class ParameterError(CablekitError, ValueError):
    """A physical or numerical parameter is out of range (e.g. negative stiffness, dt <= 0)."""


class SimulationDivergedError(CablekitError, ArithmeticError):
    """The integrated state became non-finite. ``step`` and ``time`` (s) say where."""


class NonFiniteResultError(CablekitError, ArithmeticError):
    """A result computed from finite inputs left the float range (overflow to inf, or NaN): an
    input or a parameter is too extreme for the model. ``argument`` names the result and
    ``index`` the first non-finite element."""


class ConvergenceError(CablekitError, ArithmeticError):
    """An iterative computation reached its iteration cap (every loop in cablekit is bounded).
    ``argument`` names it and ``limit`` is the cap."""


class ConcurrentUseError(CablekitError, RuntimeError):
    """An object with state (``SrUkf``, ``DualSrUkf``) was called from a second thread while a
    call was running. Use one object per thread, or serialise the calls with a lock. (``Mlp`` is
    safe to share.)"""


class FilterDivergedError(CablekitError, ArithmeticError):
    """A filter's mean or square-root covariance became non-finite in a step. The filter is left
    as it was before that step; ``step`` is the row of the log in ``run``, else the steps since
    the filter was built or reset."""


class DataError(CablekitError, ValueError):
    """A data file (CSV, TOML) is malformed: missing column, bad time base, unknown unit."""


class NetworkError(DataError):
    """A cable network (a network model file's mechanism) is not a valid mechanism: a cable over
    no pulley, a disconnected body, a negative wrap angle, a singular coupling, an unknown
    pulley or motor. ``element`` names the element at fault (``cable "flexor"``)."""


class WeightsFormatError(CablekitError, ValueError):
    """A weight file is not a valid cablekit network. ``item`` names the tensor or metadata key."""


class WeightsCorruptError(WeightsFormatError):
    """Not a readable safetensors file: truncated, bad header, or a tensor that is not float64."""


class WeightsMetadataError(WeightsFormatError):
    """``__metadata__`` missing, a required key missing or invalid, an unknown activation."""


class WeightsShapeError(WeightsFormatError):
    """A tensor is missing, unexpected, or its shape disagrees with the stored architecture."""


class WeightsValueError(WeightsFormatError):
    """A weight, bias or normalisation bound is NaN/inf, or a normalisation range is reversed."""


class OnnxExportError(CablekitError, ValueError):
    """A network cannot be exported to ONNX as asked: unknown dtype, opset too old, no ``onnx``."""


class InternalError(CablekitError, RuntimeError):
    """A bug inside cablekit (a Rust panic caught at the boundary). Please report it."""


__all__ = [
    "CablekitError",
    "ConcurrentUseError",
    "ConvergenceError",
    "DTypeError",
    "DataError",
    "FilterDivergedError",
    "InternalError",
    "LayoutError",
    "NetworkError",
    "NonFiniteResultError",
    "NotFiniteError",
    "OnnxExportError",
    "ParameterError",
    "ShapeError",
    "SimulationDivergedError",
    "WeightsCorruptError",
    "WeightsFormatError",
    "WeightsMetadataError",
    "WeightsShapeError",
    "WeightsValueError",
]
