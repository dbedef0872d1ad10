"""What every model's ports share: the resolved sensor and actuator tables and their look-ups.

:class:`NamedPorts` is the base of :class:`ctmm.planar.ports.PlanarPorts` and
:class:`ctmm.spatial.ports.SpatialPorts` (the ports half of the plant protocol,
:mod:`ctmm.control.plants`).  A subclass fills ``model``, ``sensors`` and ``actuators`` (mappings by
name of resolved entries with a ``unit``) and implements ``check_sensor`` / ``check_actuator`` (which
know the model's reasons for refusing a name), ``values`` and ``inputs``.
"""
from __future__ import annotations

from collections.abc import Mapping, Sequence
from typing import Any

from .errors import ModelError

__all__ = ["NamedPorts", "merged_values", "split_actuator_values", "split_by_kind", "NOT_GIVEN"]

NOT_GIVEN = object()
"""The default ``inputs`` of the kinematic loop ports' ``values``: not given (their cut-force sensors, which depend on
the actuator values, are then refused by name)."""


class NamedPorts:
    """Sensor and actuator tables of one model (see the module docstring)."""

    model: Any
    sensors: Mapping[str, Any]
    actuators: Mapping[str, Any]

    def check_sensor(self, name: str, what: str = "sensor") -> str:  # pragma: no cover - abstract
        raise NotImplementedError

    def check_actuator(self, name: str, what: str = "actuator") -> str:  # pragma: no cover - abstract
        raise NotImplementedError

    def sensor_unit(self, name: str) -> str:
        """SI unit of sensor ``name``."""
        return self.sensors[self.check_sensor(name)].unit

    def actuator_unit(self, name: str) -> str:
        """SI unit of actuator ``name``."""
        return self.actuators[self.check_actuator(name)].unit

    def resolve(self, names: Sequence[str]) -> list:
        """The resolved sensors ``names`` (for ``values`` in a loop)."""
        if isinstance(names, str):
            raise ModelError(f"names must be a sequence of sensor names, got the string {names!r}")
        if not isinstance(names, (list, tuple)):
            raise ModelError(f"names must be a list or tuple of sensor names (str), got {names!r}")
        return [self.sensors[self.check_sensor(name)] for name in names]


def split_by_kind(items: Sequence[Any], kind: type) -> tuple[list[int], list[int]]:
    """Positions of the entries of ``items`` that are not of ``kind`` and of those that are (a kinematic loop model's
    ports: the tree's resolved entries and the cut joints')."""
    extra = [k for k, item in enumerate(items) if isinstance(item, kind)]
    chosen = set(extra)
    return [k for k in range(len(items)) if k not in chosen], extra


def merged_values(sensors: Sequence[Any], kind: type, tree_values: Any, extra_values: Any) -> Any:
    """Values of resolved ``sensors`` of two kinds: ``tree_values(sensors)`` for those not of ``kind``,
    ``extra_values(sensors)`` for those of ``kind``, each a sequence of floats in the order given."""
    import numpy as np

    tree, extra = split_by_kind(sensors, kind)
    if not extra:
        return tree_values(list(sensors))
    values = np.empty(len(sensors))
    if tree:
        values[tree] = tree_values([sensors[k] for k in tree])
    values[extra] = extra_values([sensors[k] for k in extra])
    return values


def split_actuator_values(values: Mapping[str, float], actuators: Mapping[str, Any], kind: type
                          ) -> tuple[dict[str, float], list[tuple[str, float]]]:
    """``values`` (``{actuator name: value}``) split into those of the tree (a mapping, checked by the tree's ports)
    and the ``(name, value)`` pairs whose actuator is of ``kind``; :class:`ModelError` unless a mapping."""
    if not isinstance(values, Mapping):
        raise ModelError(f"values must be a mapping of actuator name to value, got {values!r}")
    tree = {name: value for name, value in values.items() if not isinstance(actuators.get(name), kind)}
    return tree, [(name, value) for name, value in values.items() if isinstance(actuators.get(name), kind)]
