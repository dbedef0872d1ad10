"""Named stations of a modal beam: where the station ports read and act.

A :class:`~ctmm.flexible.beam.ModalBeam` built with ``stations={"pzt1_start": 0.05, ...}``
(abscissae ``x`` [m] from the root, ``0 <= x <= L``) exposes, through
:mod:`ctmm.planar.ports`, the physical signals of those points in the beam's floating (root
tangent) frame:

* sensors ``"<beam>.<station>.w"`` -- transverse deflection ``w(x) = phi(x) . q`` [m],
  ``".slope"`` -- elastic slope ``w'(x) = phi'(x) . q`` [rad], and their rates ``".w_dot"``
  [m/s], ``".slope_rate"`` [rad/s];
* actuators ``"<beam>.<station>.force"`` -- transverse force ``F`` [N] (along the frame's y
  axis, turning with the beam) and ``".moment"`` -- moment ``M`` [N m], both applied at the
  station.  Their virtual work gives the exact loads of the modal model: on the modal equations
  ``phi_k(x) F`` and ``phi_k'(x) M``; on the floating frame the force ``F`` and the moment
  ``x F + M`` about the root (a self-equilibrated set such as a piezo moment pair ``-M`` at
  ``x1``, ``+M`` at ``x2`` loads the modal equations only).

These are form-independent: an exact beam field has the same ports (``w``, slope, shear,
moment at a station).
"""
from __future__ import annotations

from collections.abc import Mapping
from typing import Any

import numpy as np

from .. import validation
from ..errors import ModelError

__all__ = ["check_stations", "RESERVED_STATION_NAMES", "station_shapes", "station_abscissa"]

#: Point names a station may not take (they are the beam's own point sensors).
RESERVED_STATION_NAMES = ("inboard", "com", "theta", "omega")


def check_stations(beam: Any, stations: Any) -> dict[str, float]:
    """Validated stations ``{name: x}`` [m] of ``beam`` (``None`` -> no stations).

    A name must be a valid element name, unique among the beam's outboard ends, coordinate
    suffixes (``q1``...) and :data:`RESERVED_STATION_NAMES`; ``x`` must lie on the beam.
    """
    if stations is None:
        return {}
    owner = beam.name
    if not isinstance(stations, Mapping):
        raise ModelError(f"{owner}: stations must be a mapping {{name: x [m]}}, got {stations!r}")
    taken = set(beam.outboard) | set(beam.coordinate_suffixes) | set(RESERVED_STATION_NAMES)
    checked: dict[str, float] = {}
    for name, x in stations.items():
        validation.name(f"{owner}: station", name)
        if name in taken:
            raise ModelError(f"{owner}: station name {name!r} is taken (outboard ends, modal coordinates "
                             f"and {', '.join(RESERVED_STATION_NAMES)} are reserved)")
        value = validation.finite(f"{owner}: stations[{name!r}]", x)
        length = beam.length
        if value < -1e-12 * length or value > length * (1 + 1e-12):
            raise ModelError(f"{owner}: stations[{name!r}] = {x!r} m must lie on the beam, 0 <= x <= {length} m")
        checked[name] = min(max(value, 0.0), length)
    return checked


def station_shapes(beam: Any, station: str) -> tuple[float, np.ndarray, np.ndarray]:
    """``(x, phi(x), phi'(x))`` of a named station: abscissa [m], transverse shapes [1] and
    slopes [1/m] of the ``n_modes`` transverse modes."""
    x = beam.stations[station]
    return x, beam.shapes([x], 0)[:, 0], beam.shapes([x], 1)[:, 0]


def station_abscissa(owner: str, label: str, value: Any, length: float) -> float:
    """``value`` as an abscissa on a beam of ``length`` [m] (round-off outside ``[0, L]`` clipped), or a
    :class:`ModelError` naming ``owner`` and ``label``."""
    x = validation.finite(f"{owner}: {label}", value)
    if x < -1e-12 * length or x > length * (1 + 1e-12):
        raise ModelError(f"{owner}: {label} = {value!r} must lie on the beam, 0 <= x <= {length}")
    return min(max(x, 0.0), length)
