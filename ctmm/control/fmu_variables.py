"""FMU variables as ctmm signals: which variables may be mapped, and how values are converted.

ctmm signals are real numbers (``float64``).  FMU inputs and outputs of these types are accepted:

=========================  ====================================================================
FMI 2 / FMI 3 type          conversion
=========================  ====================================================================
Real / Float64             none
Float32                    input rounded to the nearest float32 (|y| > 3.4e38 is an error)
Integer / Int8 ... UInt64  input rounded to the nearest integer (``numpy.rint``, ties to even);
                           outside the type's range or not finite is an error
Boolean                    input: true when ``y != 0`` (NaN is an error); output 1.0 / 0.0
Enumeration                like Integer
=========================  ====================================================================

Outputs are converted to ``float64`` (exact, except Int64/UInt64 beyond 2**53).  A variable whose unit has
a ``BaseUnit`` with ``factor``/``offset`` is converted from and to SI (:func:`si_scaling`).  String, Binary
and Clock variables, and FMI 3 array variables (``<Dimension>``), cannot be mapped to signals and
are refused at construction.  Parameters and start values are set by name with the type's own
value (float, integral number, bool or str).
"""
from __future__ import annotations

import ctypes
import math
from dataclasses import dataclass
from typing import Any, Mapping, Sequence

import numpy as np

from ..errors import ModelError, SimulationError, UnknownNameError, unknown_name

__all__ = ["VariableType", "variable_type", "mapped_variable", "settable_values", "ValueChannel", "si_scaling"]


@dataclass(frozen=True)
class VariableType:
    """How one FMI type is passed through ctypes and converted from and to float64."""

    name: str  # FMI type name, e.g. "Float32"
    ctype: Any  # ctypes element type
    dtype: np.dtype  # numpy view of the ctypes buffer
    function: str  # suffix of fmiXSet<function> / fmiXGet<function>
    kind: str  # "float", "integer" or "boolean"


def _types(major: int) -> dict[str, VariableType]:
    if major == 2:
        return {
            "Real": VariableType("Real", ctypes.c_double, np.dtype(np.float64), "Real", "float"),
            "Integer": VariableType("Integer", ctypes.c_int, np.dtype(np.intc), "Integer", "integer"),
            "Enumeration": VariableType("Enumeration", ctypes.c_int, np.dtype(np.intc), "Integer", "integer"),
            "Boolean": VariableType("Boolean", ctypes.c_int, np.dtype(np.intc), "Boolean", "boolean"),
        }
    table = {
        "Float64": (ctypes.c_double, np.float64, "float"), "Float32": (ctypes.c_float, np.float32, "float"),
        "Int8": (ctypes.c_int8, np.int8, "integer"), "UInt8": (ctypes.c_uint8, np.uint8, "integer"),
        "Int16": (ctypes.c_int16, np.int16, "integer"), "UInt16": (ctypes.c_uint16, np.uint16, "integer"),
        "Int32": (ctypes.c_int32, np.int32, "integer"), "UInt32": (ctypes.c_uint32, np.uint32, "integer"),
        "Int64": (ctypes.c_int64, np.int64, "integer"), "UInt64": (ctypes.c_uint64, np.uint64, "integer"),
        "Boolean": (ctypes.c_bool, np.bool_, "boolean"),
    }
    result = {name: VariableType(name, ctype, np.dtype(dtype), name, kind) for name, (ctype, dtype, kind) in table.items()}
    result["Enumeration"] = VariableType("Enumeration", ctypes.c_int64, np.dtype(np.int64), "Int64", "integer")
    return result


_TYPES = {2: _types(2), 3: _types(3)}


def variable_type(variable: Any, major: int) -> VariableType | None:
    """The :class:`VariableType` of an fmpy model variable, or None for String/Binary/Clock."""
    return _TYPES[major].get(variable.type)


def _allowed_types(major: int) -> str:
    return ", ".join(_TYPES[major])


def mapped_variable(name: Any, variables: Mapping[str, Any], causality: str, major: int, what: str) -> Any:
    """Look up an input or output variable to be mapped to a ctmm signal.

    Raises
    ------
    ModelError
        Unknown name (the message lists the variables of that causality), wrong causality, a type
        that is not numeric, or an array variable.
    """
    if not isinstance(name, str):
        raise ModelError(f"{what}: FMU variable names must be strings, got {name!r}")
    variable = variables.get(name)
    if variable is None:
        known = [v.name for v in variables.values() if v.causality == causality]
        raise _unknown(what, f"FMU {causality} variable", name, known)
    if variable.causality != causality:
        raise ModelError(f"{what}: FMU variable {name!r} has causality {variable.causality!r}; "
                         f"allowed here: {causality!r}")
    if variable_type(variable, major) is None:
        raise ModelError(f"{what}: FMU variable {name!r} has type {variable.type!r}; allowed for "
                         f"{causality}s mapped to ctmm signals: {_allowed_types(major)}")
    _refuse_array(variable, what)
    return variable


def _unknown(what: str, kind: str, name: str, known: list[str]) -> UnknownNameError:
    """An :class:`UnknownNameError` listing the known names, prefixed with the FMU's name."""
    return UnknownNameError(f"{what}: {unknown_name(kind, name, known)}")


def _refuse_array(variable: Any, what: str) -> None:
    dimensions = getattr(variable, "dimensions", None) or []
    if dimensions:
        shape = ", ".join(_dimension_text(d) for d in dimensions)
        raise ModelError(f"{what}: FMU variable {variable.name!r} is an array (dimensions [{shape}]); "
                         "FMUController maps and sets scalar variables only")


def _dimension_text(dimension: Any) -> str:
    if dimension.start is not None:
        return str(dimension.start)
    size = getattr(dimension, "variable", None)
    return f"size set by {size.name!r}" if size is not None else f"size set by value reference {dimension.valueReference}"


def _settable(variable: Any) -> bool:
    if variable.variability == "constant":
        return False
    if variable.causality == "parameter":
        return variable.variability in ("fixed", "tunable")
    if variable.causality == "input":
        return True
    return variable.causality in ("local", "output") and variable.initial in ("exact", "approx")


def _within_declared_range(variable: Any, value: float, label: str) -> None:
    """Refuse a value outside the variable's declared ``min``/``max`` or enumeration items."""
    declared = getattr(variable, "declaredType", None)
    low = getattr(variable, "min", None)
    high = getattr(variable, "max", None)
    low = getattr(declared, "min", None) if low is None else low
    high = getattr(declared, "max", None) if high is None else high
    if (low is not None and value < float(low)) or (high is not None and value > float(high)):
        raise ModelError(f"{label} = {value!r} is outside the range the FMU declares for it: "
                         f"[{'-inf' if low is None else low}, {'inf' if high is None else high}]")
    items = getattr(declared, "items", None) if variable.type == "Enumeration" else None
    if items:
        allowed = sorted(int(item.value) for item in items)
        if int(value) not in allowed:
            raise ModelError(f"{label} = {value!r} is not an item of the enumeration "
                             f"{getattr(declared, 'name', '')!r}; allowed: {allowed}")


def convert_start_value(variable: Any, value: Any, major: int, what: str) -> Any:
    """Convert a user value for ``variable`` to its FMI type (float, int, bool or str)."""
    label = f"{what}: parameters[{variable.name!r}]"
    kind = variable_type(variable, major)
    if variable.type == "String":
        if not isinstance(value, str):
            raise ModelError(f"{label} must be a str (the variable has type String), got {value!r}")
        return value
    if kind is None:
        raise ModelError(f"{label}: variables of type {variable.type!r} cannot be set; allowed types: "
                         f"{_allowed_types(major)}, String")
    if kind.kind == "boolean":
        if isinstance(value, (bool, np.bool_)) or (isinstance(value, (int, np.integer)) and value in (0, 1)):
            return bool(value)
        raise ModelError(f"{label} must be True or False (the variable has type Boolean), got {value!r}")
    if isinstance(value, (bool, np.bool_)) or not isinstance(value, (int, float, np.integer, np.floating)):
        raise ModelError(f"{label} must be a real number, got {value!r}")
    if isinstance(value, (int, np.integer)):
        value = int(value)  # exact: a float would round integers beyond 2**53 (Int64, UInt64)
    elif not math.isfinite(value):
        raise ModelError(f"{label} must be finite, got {value!r}")
    _within_declared_range(variable, value, label)
    if kind.kind == "float":
        limit = float(np.finfo(kind.dtype).max)
        if abs(value) > limit:
            raise ModelError(f"{label} = {value!r} is outside the {variable.type} range +-{limit:.2g}")
        return float(value)
    if not isinstance(value, int) and value != math.floor(value):
        raise ModelError(f"{label} must be an integer (the variable has type {variable.type}), got {value!r}")
    info = np.iinfo(kind.dtype)
    if not info.min <= int(value) <= info.max:
        raise ModelError(f"{label} = {value!r} is outside the {variable.type} range [{info.min}, {info.max}]")
    return int(value)


def settable_values(values: Any, variables: Mapping[str, Any], major: int, what: str,
                    mapped_inputs: Sequence[str]) -> dict[str, tuple[Any, Any]]:
    """Validate the ``parameters`` mapping: name -> (variable, converted value).

    Accepted names: parameters (variability fixed or tunable), inputs that are not mapped to a
    signal (their start value), and other variables whose start value may be set before
    initialization (``initial="exact"`` or ``"approx"``).

    Raises
    ------
    ModelError
        Not a mapping, unknown name (lists the settable names), a variable that cannot be set
        (names its causality, variability and initial), an array, or a value of the wrong type.
    """
    if values is None:
        return {}
    if not isinstance(values, Mapping):
        raise ModelError(f"{what}: parameters must be a mapping of FMU variable name -> value, got {values!r}")
    result: dict[str, tuple[Any, Any]] = {}
    for name, value in values.items():
        variable = variables.get(name) if isinstance(name, str) else None
        if variable is None:
            known = [v.name for v in variables.values() if _settable(v) and v.name not in mapped_inputs]
            raise _unknown(what, "FMU parameter variable", str(name), known)
        if not _settable(variable):
            raise ModelError(f"{what}: FMU variable {name!r} (causality {variable.causality!r}, variability "
                             f"{variable.variability!r}, initial {variable.initial!r}) cannot be set; allowed: "
                             "parameters with variability 'fixed' or 'tunable', inputs, and variables with "
                             "initial 'exact' or 'approx'")
        if name in mapped_inputs:
            raise ModelError(f"{what}: FMU input {name!r} is mapped to a ctmm signal in inputs; it cannot also be "
                             "set in parameters")
        _refuse_array(variable, what)
        result[name] = (variable, convert_start_value(variable, value, major, what))
    return result


class ValueChannel:
    """Preallocated ctypes buffers for one FMI type among the mapped inputs or outputs.

    Parameters
    ----------
    kind : VariableType
        The FMI type of every variable in the channel.
    value_references : sequence of int
        Value references, in the order of ``positions``.
    positions : sequence of int
        Index of each variable in the ctmm input vector ``y`` or output vector ``u``.
    names : sequence of str
        Variable names (for error messages).
    scalings : sequence of (float, float), optional
        ``(factor, offset)`` of each variable's unit (:func:`si_scaling`): the SI value of a signal is
        ``factor * value + offset`` of the FMU's value; default: the FMU's values are SI values.
    """

    def __init__(self, kind: VariableType, value_references: Sequence[int], positions: Sequence[int],
                 names: Sequence[str], scalings: Sequence[tuple[float, float]] | None = None) -> None:
        n = len(value_references)
        self.kind = kind
        self.count = n
        self.positions = np.asarray(positions, dtype=np.intp)
        self.names = tuple(names)
        scalings = np.array(scalings, dtype=float).reshape(n, 2) if scalings else np.tile([1.0, 0.0], (n, 1))
        self.factors, self.offsets = scalings[:, 0], scalings[:, 1]
        self.scaled = bool(np.any(self.factors != 1.0) or np.any(self.offsets != 0.0))
        self.references = (ctypes.c_uint32 * n)(*value_references)
        self.buffer = (kind.ctype * n)()
        self.view = np.ctypeslib.as_array(self.buffer).view(kind.dtype) if n else np.zeros(0, kind.dtype)

    def load(self, y: np.ndarray, time: float, what: str) -> None:
        """Convert ``y[positions]`` into the buffer (see the module table).

        Raises
        ------
        SimulationError
            A value that cannot be converted (NaN for Integer/Boolean, out of range).
        """
        values = y[self.positions]
        signals = values
        if self.scaled:  # SI signal -> the FMU's unit
            values = (values - self.offsets) / self.factors
        kind = self.kind
        if kind.dtype == np.float64:
            self.view[:] = values
            return
        if kind.kind == "float":  # Float32: NaN and inf pass through like Float64
            bad = np.isfinite(values) & (np.abs(values) > float(np.finfo(np.float32).max))
            if not bad.any():
                self.view[:] = values
                return
        elif kind.kind == "integer":
            bad = ~np.isfinite(values)
            rounded = np.rint(np.where(bad, 0.0, values))
            info = np.iinfo(kind.dtype)
            # info.max + 1 is a power of two, exact as a float; float(info.max) of Int64/UInt64 rounds up to it
            bad |= (rounded < float(info.min)) | (rounded >= float(int(info.max) + 1))
            if not bad.any():
                self.view[:] = rounded.astype(kind.dtype)
                return
        else:
            bad = ~np.isfinite(values)
            if not bad.any():
                self.view[:] = values != 0.0
                return
        index = int(np.flatnonzero(bad)[0])
        unit = f" ({float(values[index])!r} in the FMU's unit)" if self.scaled else ""
        raise SimulationError(f"{what}: input {self.names[index]!r} = {float(signals[index])!r}{unit} at t = {time!r} "
                              f"cannot be converted to the FMU type {kind.name}; allowed: {_range_text(kind)}", time=time)

    def read(self) -> np.ndarray:
        """The values in the buffer as float64 SI values (after an fmiXGet* call)."""
        values = self.view.astype(float)
        return values * self.factors + self.offsets if self.scaled else values


def si_scaling(variable: Any, description: Any) -> tuple[float, float]:
    """``(factor, offset)`` of the variable's unit to SI (``<BaseUnit factor offset>`` of its unit definition).

    The SI value is ``factor * value + offset`` (FMI 2.0 sec. 2.2.2, FMI 3.0 sec. 2.4.3); the offset is
    ignored for a ``relativeQuantity`` (a difference: 10 degC = 10 K); a variable without a unit, or
    whose unit has no ``BaseUnit``, is taken as SI: ``(1.0, 0.0)``.
    """
    declared = getattr(variable, "declaredType", None)
    unit = getattr(variable, "unit", None) or getattr(declared, "unit", None)
    relative = getattr(variable, "relativeQuantity", None) or getattr(declared, "relativeQuantity", None)
    for definition in getattr(description, "unitDefinitions", None) or ():
        base = getattr(definition, "baseUnit", None)
        if definition.name == unit and base is not None:
            return float(base.factor or 1.0), 0.0 if relative else float(base.offset or 0.0)
    return 1.0, 0.0


def _range_text(kind: VariableType) -> str:
    if kind.kind == "float":
        return "finite values with |y| <= 3.4e38 (or non-finite values passed through)"
    if kind.kind == "boolean":
        return "finite values (0 is false, anything else true)"
    info = np.iinfo(kind.dtype)
    return f"finite values that round to [{info.min}, {info.max}]"
