"""Units of named signals and inputs: the one table used by plots, data frames and result files.

Signals are named ``"<element>.<quantity>"`` (see :mod:`ctmm.system`); the unit follows from the
quantity, and for loop signals from the loop's sensor and actuator:

================================  ===========  =================================================
quantity                          unit         meaning
================================  ===========  =================================================
``x``, ``w`` (and planar ``y``)   m            displacement
``phi``, ``theta``                rad          rotation
``f``, ``fx``, ``fy``, ``shear``  N            internal force
``torque``, ``moment``, ``tau``   N*m          internal moment
``v`` / ``a``                     m/s, m/s^2   velocity / acceleration of the first component
``<c>_dot`` / ``<c>_ddot``        [c]/s, ...   time derivatives of a displacement component
``ax``, ``ay`` / ``alpha``        m/s^2 /      planar accelerations
                                  rad/s^2
``<loop>.y``, ``.reference``      sensor       unit of the sensed signal(s) (m for ``m6.x``)
``<loop>.u``                      N (N*m)      control force (moment for a moment actuator)
``<loop>.L``                      1            loop transfer function (dimensionless)
inputs ``force`` / ``moment``     N / N*m      external loads
input ``displacement``            m (rad)      prescribed motion
``deflection``, ``slope``,        m, rad,      manipulator tip deflection, patch slope and its
``slope_rate``, ``voltage``       rad/s, V     rate, PZT voltage
================================  ===========  =================================================

An unknown quantity (a controller output, an extra layout component) has the unit ``""``
(unknown), and labels then show the name alone: a unit is never guessed.
"""
from __future__ import annotations

from typing import Any

UNKNOWN = ""
"""The unit of a signal whose unit ctmm does not know (labels show the name alone)."""

QUANTITY_UNITS: dict[str, str] = {
    "x": "m", "w": "m", "phi": "rad", "theta": "rad",
    "f": "N", "fx": "N", "fy": "N", "shear": "N",
    "torque": "N*m", "moment": "N*m", "tau": "N*m",
    "v": "m/s", "a": "m/s^2",
    "ax": "m/s^2", "ay": "m/s^2", "alpha": "rad/s^2",
    "force": "N", "displacement": "m", "L": "1",
    "deflection": "m", "deflection_dot": "m/s", "slope": "rad", "slope_rate": "rad/s", "voltage": "V",
}
"""Unit of each signal quantity that has one meaning whatever the system (the 1-D kinds included)."""

_DERIVATIVE_SUFFIXES = (("_ddot", "/s^2"), ("_dot", "/s"))


def _quantity_unit(quantity: str, layout: Any = None) -> str:
    """Unit of a quantity name; ``layout`` resolves layout-dependent names (``y``, ``v``, inputs)."""
    for suffix, per in _DERIVATIVE_SUFFIXES:
        if quantity.endswith(suffix):
            base = _quantity_unit(quantity[: -len(suffix)], layout)
            return base + per if base and base not in ("1",) else UNKNOWN
    if layout is not None:
        displacements = tuple(getattr(layout, "displacements", ()))
        forces = tuple(getattr(layout, "forces", ()))
        if quantity == "y":
            return "m" if "y" in displacements else UNKNOWN
        if displacements and quantity in ("v", "a"):
            base = _quantity_unit(displacements[0])
            return base + ("/s" if quantity == "v" else "/s^2") if base else UNKNOWN
        if displacements and quantity == "displacement":
            return _quantity_unit(displacements[0])
        if forces and quantity == "force":
            return _quantity_unit(forces[0])
    return QUANTITY_UNITS.get(quantity, UNKNOWN)


def loop_unit(ports: Any, loop: Any, quantity: str) -> str:
    """Unit of ``"<loop>.<quantity>"``: the one rule for every model and for stored systems.

    Parameters
    ----------
    ports : object
        Gives the unit of one term: ``ports.sensor_unit(name)`` and ``ports.actuator_unit(name)``
        (:class:`~ctmm.named_ports.NamedPorts` of a chain, planar or spatial plant).
    loop : Feedback
        The loop (its weighted ``terms`` and ``actuator_terms``).
    quantity : str
        ``"y"`` or ``"reference"`` (the unit of the sensed terms), ``"u"`` (of the actuator terms)
        or ``"L"`` (``"1"``, the loop transfer function).

    Returns
    -------
    str
        The terms' common unit when every weight is ``+1`` or ``-1``; :data:`UNKNOWN` when they mix units,
        for another quantity, or when a weight is another number (its unit is not known: e.g. a PZT loop's
        slope-rate gains [V s/rad] and moments per volt [N m/V] make its ``y`` and ``u`` volts).
    """
    if quantity == "L":
        return "1"
    if quantity in ("y", "reference"):
        names, unit = getattr(loop, "terms", ()), ports.sensor_unit
    elif quantity == "u":
        names, unit = getattr(loop, "actuator_terms", ()), ports.actuator_unit
    else:
        return UNKNOWN
    if any(abs(weight) != 1.0 for _, weight in names):
        return UNKNOWN
    units = {unit(name) for name, _ in names}
    return units.pop() if len(units) == 1 else UNKNOWN


def loop_units(ports: Any, loops: Any, names: Any) -> dict[str, str]:
    """``{"<loop>.y" / ".reference" / ".u": unit}`` by :func:`loop_unit` for those of ``names`` that are loop signals
    of ``loops`` (the units of a frequency response's loop inputs and outputs)."""
    wanted = set(names)
    return {f"{loop.name}.{quantity}": loop_unit(ports, loop, quantity) for loop in loops
            for quantity in ("y", "reference", "u") if f"{loop.name}.{quantity}" in wanted}


class _ChainUnits:
    """Units of the sensor and actuator names of a chain ``plant``, from the names alone (for
    :func:`loop_unit` on a :class:`~ctmm.control.loops.ControlledChain` or a stored system)."""

    def __init__(self, plant: Any) -> None:
        self.plant = plant

    def sensor_unit(self, name: str) -> str:
        return signal_unit(name, self.plant)

    def actuator_unit(self, name: str) -> str:
        element_name, _, input_name = name.partition(".")
        if not input_name:
            inputs = getattr(self.plant.element(element_name), "inputs", ())
            input_name = inputs[0] if inputs else ""
        return _quantity_unit(input_name, self.plant.layout)


def signal_unit(name: str, system: Any = None) -> str:
    """Unit of a named signal or input, e.g. ``"m"`` for ``"m6.x"``, ``"N"`` for ``"loop.u"``.

    Parameters
    ----------
    name : str
        Signal or input name (``"m6.x"``, ``"k3.f"``, ``"loop.y"``, ``"m1.force"``, ...).
    system : Chain, ControlledChain or stored system, optional
        The system the name belongs to; it resolves names whose unit depends on the system
        (loop sensors and actuators, planar ``y``, the layout of ``v``/``a`` and of inputs).
        Without it, those names get :data:`UNKNOWN` rather than a guess.

    Returns
    -------
    str
        Unit string (SI, ``*`` for products, ``^`` for powers, ``"1"`` dimensionless), or ``""``
        if unknown.
    """
    stored = getattr(system, "stored_units", None)
    if stored is not None:
        return stored.get(name, UNKNOWN)
    if not isinstance(name, str) or "." not in name:
        return UNKNOWN
    owner, quantity = name.split(".", 1)[0], name.rsplit(".", 1)[-1]
    for loop in getattr(system, "loops", ()) or ():
        if getattr(loop, "name", None) == owner and "." not in name[len(owner) + 1:]:
            return loop_unit(_ChainUnits(system.plant), loop, quantity)
    if system is None:
        # names alone are read as the 1-D (axial) kinds; "y" (planar displacement or loop sensor)
        # and "reference" (loop sensor unit) cannot be resolved without the system
        if quantity in ("y", "reference"):
            return UNKNOWN
        if quantity == "u":
            return "N"
    layout = getattr(getattr(system, "plant", system), "layout", None)
    return _quantity_unit(quantity, layout)


def label(name: str, unit: str) -> str:
    """Axis or column label ``"name [unit]"`` (``"name"`` alone if the unit is unknown)."""
    return f"{name} [{unit}]" if unit else name
