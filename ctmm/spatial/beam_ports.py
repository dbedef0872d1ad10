"""Named station ports of a spatial beam (:class:`~ctmm.spatial.beam.SpatialBeam`) for
:class:`~ctmm.spatial.ports.SpatialPorts`.

At every point of a beam (its named stations and ``"tip"``), in the beam's floating (root tangent) frame:

* sensors ``"<beam>.<point>.w_y"``, ``".w_z"`` -- deflections along body ``y`` and ``z`` [m],
  ``".axial"`` -- axial displacement [m], ``".slope_y"`` (``w_y'``), ``".slope_z"`` (``w_z'``) -- elastic
  slopes [rad], ``".twist"`` -- twist angle [rad], and their rates ``"..._rate"`` [m/s, rad/s]: linear
  functionals of the modal coordinates ``eta`` (rates: of ``eta_dot``);
* actuators ``"<beam>.<point>.moment_x|y|z"`` -- moment at the point, world axes [N m] (with the force
  actuators ``"<beam>.<point>.force_x|y|z"`` every body point has).  Their virtual work is the exact load
  of the modal model (a piezo pair is ``-M`` at one station and ``+M`` at another).

The generic point sensors ``"<beam>.<point>.x|y|z"``, ``".vx|vy|vz"`` read the deformed point.  A beam has
no ``"com"`` point sensor (its centre of mass moves along the deformation, it is not a material point);
its ``"<beam>.force_x|y|z"`` actuators act at the axis point ``x = L/2``.
"""
from __future__ import annotations

from typing import Any

import numpy as np

__all__ = ["beam_sensor_rows", "beam_actuator_rows", "deformed_point"]

_AXES = "xyz"


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
                                     ("twist", Lam[0], "rad")):
            rows.append((f"{beam.name}.{point}.{label}", False, weights.copy(), unit))
            rows.append((f"{beam.name}.{point}.{label}_rate", True, weights.copy(), f"{unit}/s"))
    return rows


def beam_actuator_rows(beam: Any) -> list[tuple[str, int, tuple, str]]:
    """``(name, wrench component 3..5, point (3,) body axes, unit)`` of the point moment actuators."""
    if hasattr(beam, "actuator_rows"):                                  # a ctmm.fem.SpatialSubsystem
        return beam.actuator_rows()
    return [(f"{beam.name}.{point}.moment_{a}", 3 + c, tuple(r), "N m") for point, r in beam.points.items()
            for c, a in enumerate(_AXES)]


def deformed_point(beam: Any, point: Any, eta: np.ndarray, *, rate: bool = False) -> np.ndarray:
    """Body-axes position ``rho0 + Phi eta`` [m] of the beam axis point at ``point[0]`` (``rate``: its
    velocity relative to the frame ``Phi eta_dot`` [m/s]); ``eta`` (n_eta,) or a batch (B, n_eta), real or
    complex step (:mod:`ctmm.spatial.sensor_maps`) -> (3,) or (B, 3)."""
    if hasattr(beam, "deformed_point"):                                 # a ctmm.fem.SpatialSubsystem: its nodes
        return beam.deformed_point(point, eta, rate=rate)
    Phi = beam.data.station(float(point[0]))[0]
    eta = np.asarray(eta)
    moved = (eta if np.iscomplexobj(eta) else eta.astype(float)) @ Phi.T
    return moved if rate else moved + np.array([float(point[0]), 0.0, 0.0])
