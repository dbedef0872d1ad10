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

__all__ = ["NamedPorts"]


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
