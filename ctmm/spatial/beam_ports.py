"""Named station ports of a spatial beam (:class:`~ctmm.spatial.beam.SpatialBeam`) for
:class:`~ctmm.spatial.ports.SpatialPorts`.

At every point of a beam (its named stations and ``"tip"``), in the beam's floating (root tangent) frame:

* sensors ``"<beam>.<point>.w_y"``, ``".w_z"`` -- deflections along body ``y`` and ``z`` [m],
  ``".axial"`` -- axial displacement [m], ``".slope_y"`` (``w_y'``), ``".slope_z"`` (``w_z'``) -- elastic
  slopes [rad], ``".twist"`` -- twist angle [rad], ``".theta_x|y|z"`` -- the section's small rotation
  ``theta = Lambda eta = [twist, -w_z', w_y']`` about the frame axes [rad] (collocated with
  ``".moment_body_x|y|z"``), and their rates ``"..._rate"`` [m/s, rad/s]: linear functionals of the modal
  coordinates ``eta`` (rates: of ``eta_dot``);
* actuators ``"<beam>.<point>.moment_x|y|z"`` -- moment at the point, world axes [N m] (with the force
  actuators ``"<beam>.<point>.force_x|y|z"`` every body point has), and the same in the beam's **body
  axes** (the floating frame, turning with the beam): ``"<beam>.<point>.force_body_x|y|z"`` [N] at the
  deformed point and ``"<beam>.<point>.moment_body_x|y|z"`` [N m].  Their virtual work is the exact load
  of the modal model.  A piezo pair is ``-M`` at one station and ``+M`` at another about one body axis
  (:func:`patch_actuator`, :func:`patch_sensor`): its forces and moments on the floating frame cancel
  exactly, so it is a modal force ``M e_a^T (Theta(theta_2) Lambda_2 - Theta(theta_1) Lambda_1)``
  (``docs/spatial_modal_beam.md`` §2b).

The generic point sensors ``"<beam>.<point>.x|y|z"``, ``".vx|vy|vz"`` read the deformed point.  A beam has
no ``"com"`` point sensor (its centre of mass moves along the deformation, it is not a material point);
its ``"<beam>.force_x|y|z"`` actuators act at the axis point ``x = L/2``.
"""
from __future__ import annotations

from typing import Any

import numpy as np

from .. import validation
from ..errors import ModelError
from .beam import SpatialBeam

__all__ = ["beam_sensor_rows", "beam_actuator_rows", "deformed_point", "patch_actuator", "patch_sensor",
           "ACTUATOR_AXES"]

_AXES = "xyz"
#: Axes of the beam point actuators: ``"world"`` (``force_x``, ``moment_x``) or ``"body"`` (the floating frame:
#: ``force_body_x``, ``moment_body_x``).
ACTUATOR_AXES = ("world", "body")


def beam_sensor_rows(beam: Any) -> list[tuple[str, bool, np.ndarray, str]]:
    """``(name, rate, weights (n_eta,), unit)`` of the station sensors of ``beam`` (module docstring)."""
    if hasattr(beam, "sensor_rows"):                                    # a ctmm.fem.SpatialSubsystem
        return beam.sensor_rows()
    rows = []
    for point in beam.points:
        if point == "origin":
            continue
        Phi, Lam, _ = beam.data.station(float(beam.points[point][0]))
        for label, weights, unit in (("w_y", Phi[1], "m"), ("w_z", Phi[2], "m"), ("axial", Phi[0], "m"),
                                     ("slope_y", Lam[2], "rad"), ("slope_z", -Lam[1], "rad"),
                                     ("twist", Lam[0], "rad"), ("theta_x", Lam[0], "rad"),
                                     ("theta_y", Lam[1], "rad"), ("theta_z", Lam[2], "rad")):
            rows.append((f"{beam.name}.{point}.{label}", False, weights.copy(), unit))
            rows.append((f"{beam.name}.{point}.{label}_rate", True, weights.copy(), f"{unit}/s"))
    return rows


def beam_actuator_rows(beam: Any) -> list[tuple[str, int, tuple, str, str]]:
    """``(name, wrench component 0..5, point (3,) body axes, unit, axes)`` of the beam's own point actuators:
    the world-axes moments and the body-axes forces and moments (``axes`` in :data:`ACTUATOR_AXES`); a
    ``ctmm.fem.SpatialSubsystem`` states its own (world-axes node moments)."""
    if hasattr(beam, "actuator_rows"):                                  # a ctmm.fem.SpatialSubsystem
        return [(*row, "world") for row in beam.actuator_rows()]
    rows = []
    for point, r in beam.points.items():
        rows += [(f"{beam.name}.{point}.moment_{a}", 3 + c, tuple(r), "N m", "world") for c, a in enumerate(_AXES)]
        rows += [(f"{beam.name}.{point}.force_body_{a}", c, tuple(r), "N", "body") for c, a in enumerate(_AXES)]
        rows += [(f"{beam.name}.{point}.moment_body_{a}", 3 + c, tuple(r), "N m", "body")
                 for c, a in enumerate(_AXES)]
    return rows


def _patch_points(beam: Any, first: str, second: str, axis: str) -> None:
    if not (isinstance(beam, SpatialBeam) or hasattr(beam, "spatial_terms")):   # or a ctmm.fem.SpatialSubsystem
        raise ModelError(f"a patch beam must be a ctmm.spatial.SpatialBeam (or a ctmm.fem.SpatialSubsystem), got "
                         f"{beam!r:.80}")
    if not isinstance(axis, str) or axis not in ("x", "y", "z"):
        raise ModelError(f"{beam.name}: a patch axis must be 'x' (twist), 'y' (bending in the x-z plane) or 'z' "
                         f"(bending in the x-y plane), got {axis!r}")
    for label, point in (("first", first), ("second", second)):
        if point not in beam.points or point == "origin":
            raise ModelError(f"{beam.name}: patch {label} point {point!r} is not a station of the beam; stations: "
                             f"{', '.join(p for p in beam.points if p != 'origin')}")
    if not beam.points[first][0] < beam.points[second][0]:
        raise ModelError(f"{beam.name}: a patch needs its first point before its second, got {first!r} at "
                         f"{beam.points[first][0]} m and {second!r} at {beam.points[second][0]} m")


def patch_actuator(beam: Any, first: str, second: str, *, axis: str = "z", coefficient: float = 1.0
                   ) -> list[tuple[str, float]]:
    """Actuator terms of a piezo patch between the points ``first`` and ``second`` (stations, ``x1 < x2``):
    ``-c V`` about body ``axis`` at ``first`` and ``+c V`` at ``second`` for a patch input ``V``
    (``coefficient`` ``c`` [N m per unit input], e.g. N m/V), for :class:`ctmm.control.Feedback`'s
    ``actuator``.

    Raises
    ------
    ModelError
        Unknown points, ``x1 >= x2``, an axis other than ``"x"``, ``"y"``, ``"z"``.
    """
    _patch_points(beam, first, second, axis)
    c = validation.finite(f"{beam.name}: patch coefficient", coefficient)
    return [(f"{beam.name}.{first}.moment_body_{axis}", -c), (f"{beam.name}.{second}.moment_body_{axis}", c)]


def patch_sensor(beam: Any, first: str, second: str, *, axis: str = "z", gain: float = 1.0, rate: bool = True
                 ) -> list[tuple[str, float]]:
    """Sensor terms ``gain (theta_a(x2) - theta_a(x1))`` (``rate``: of its rate) of a patch about body ``axis``:
    the rotation collocated with :func:`patch_actuator` (``theta_z = w_y'``, ``theta_y = -w_z'``, ``theta_x``
    the twist), for :class:`ctmm.control.Feedback`'s ``sensor``."""
    _patch_points(beam, first, second, axis)
    k = validation.finite(f"{beam.name}: patch sensor gain", gain)
    rate = validation.flag(f"{beam.name}: patch sensor rate", rate)
    suffix = f"theta_{axis}_rate" if rate else f"theta_{axis}"
    return [(f"{beam.name}.{first}.{suffix}", -k), (f"{beam.name}.{second}.{suffix}", k)]


def deformed_point(beam: Any, point: Any, eta: np.ndarray, *, rate: bool = False,
                   coordinates: np.ndarray | None = None) -> np.ndarray:
    """Body-axes position ``rho0 + Phi eta`` [m] of the beam axis point at ``point[0]`` (``rate``: its
    velocity relative to the frame ``Phi eta_dot`` [m/s]); ``eta`` (n_eta,) or a batch (B, n_eta), real or
    complex step (:mod:`ctmm.spatial.sensor_maps`) -> (3,) or (B, 3).  With ``second_order_inertia`` the point
    moves with the shortening, ``+ e1 u``, ``u = -1/2 eta^T G1(x) eta`` (its rate ``-eta^T G1 eta_dot`` needs the
    modal ``coordinates`` beside the rates ``eta``), like the beam's children (:mod:`ctmm.spatial.beam_terms`)."""
    if hasattr(beam, "deformed_point"):                                 # a ctmm.fem.SpatialSubsystem: its nodes
        return beam.deformed_point(point, eta, rate=rate)
    Phi, _, G1 = beam.data.station(float(point[0]))
    eta = np.asarray(eta)
    eta = eta if np.iscomplexobj(eta) or eta.dtype == object else eta.astype(float)   # object: traced symbols
    moved = eta @ Phi.T
    if beam.data.second_order is not None:
        if rate and coordinates is None:
            raise ModelError(f"{beam.name}: the rate of a point of a second-order beam needs its modal coordinates")
        left = np.asarray(coordinates) if rate else eta
        moved = moved - np.multiply.outer(((left @ G1) * eta).sum(-1) * (1.0 if rate else 0.5), [1.0, 0.0, 0.0])
    return moved if rate else moved + np.array([float(point[0]), 0.0, 0.0])
