"""Gravity along a straight spatial chain in the exact-field bridge (:mod:`ctmm.spatial_exact_fields`).

A serial spatial chain whose beams hang or stand along gravity and whose rigid bodies carry their
centre of mass and child joint on the vertical through their own joint is in equilibrium at its rest
configuration, preloaded only axially (docs/spatial_beams.md §7):

* a beam along gravity (``g_a = g . b_1`` along its axis ``b_1``) carries the tension ``T(x) = g_a
  (m_outboard + rhoA (L - x))`` [N], linear along it:
  :class:`~ctmm.spatial_beam_fields.SpatialVaryingTensionField` (:func:`beam_gravity` gives ``g_a``);
* a rigid body with its child point at ``r`` and centre of mass at ``c`` (both on the vertical) gets
  the rotational stiffness ``k (I - g g^T / |g|^2)``, ``k = m_outboard (r . g) + m (c . g)``
  (:class:`~ctmm.spatial_beam_elements.SpatialGeometricStiffness`, :func:`rigid_preload`): the
  pendulum terms of the linearisation.

About the unstretched rest geometry: the static axial stretch of extensible beams and elastic joints
under the preload (relative ``T / EA``, ``T / k``) is neglected, as in the consistent geometric
stiffness of linear finite elements.  Refused (:class:`~ctmm.errors.ModelError`, naming the part):
trees in gravity, free and prismatic joints in gravity (their rest configuration is not the
equilibrium), beams across gravity and bodies with their centre of mass or child point off the
vertical (they bend or swing under their weight).
"""
from __future__ import annotations

from typing import Any

import numpy as np

from .errors import ModelError

__all__ = ["check_gravity", "beam_gravity", "rigid_preload"]


def _refuse(model: Any, reason: str) -> ModelError:
    return ModelError(f"fields='exact' cannot convert spatial model {model.name!r}: {reason}")


def check_gravity(model: Any, tree: bool) -> None:
    """Refuse gravity on a tree or with free / prismatic joints (module docstring)."""
    if not np.any(np.asarray(model.gravity) != 0.0):
        return
    gravity = np.asarray(model.gravity).tolist()
    if tree:
        raise _refuse(model, f"gravity = {gravity} m/s^2 with branches: a tree in gravity is not converted (only a "
                             "serial chain along gravity; give gravity=(0, 0, 0))")
    moving = [j.name for j in model.joints if j.kind in ("free", "prismatic")]
    if moving:
        raise _refuse(model, f"gravity = {gravity} m/s^2 with the free or prismatic joints {moving}: their rest "
                             "configuration is not the equilibrium (give gravity=(0, 0, 0))")


def beam_gravity(model: Any, axes: np.ndarray, beam: Any, axis: np.ndarray) -> float:
    """Gravity along the beam's axis ``axis`` (chain axes) [m/s^2], or a refusal if the beam lies across it.

    ``axes``: ``Q``, chain from world axes.
    """
    g = axes @ np.asarray(model.gravity, dtype=float)
    if np.linalg.norm(np.cross(axis, g)) > 1e-12 * np.linalg.norm(g):
        raise _refuse(model, f"beam {beam.name!r} lies along {np.round(axes.T @ axis, 12).tolist()} (world axes), not "
                             f"along gravity = {np.asarray(model.gravity).tolist()} m/s^2: it bends under its weight; "
                             "only beams hanging or standing along gravity")
    return float(axis @ g)


def rigid_preload(model: Any, axes: np.ndarray, body: Any, center: np.ndarray, child: np.ndarray,
                  outboard_mass: float) -> list:
    """The :class:`~ctmm.spatial_beam_elements.SpatialGeometricStiffness` of a rigid body in gravity ([] without).

    Parameters
    ----------
    axes : (3, 3) ndarray
        ``Q``, chain from world axes.
    center, child : (3,) ndarray
        Centre of mass and child joint point from the body's joint [m], chain axes (zero: none).
    outboard_mass : float
        Mass hanging at the child point [kg].
    """
    from .spatial_beam_elements import SpatialGeometricStiffness

    g = axes @ np.asarray(model.gravity, dtype=float)
    if not np.any(g):
        return []
    for label, r in (("centre of mass", center), ("child joint point", child)):
        if np.linalg.norm(np.cross(r, g)) > 1e-12 * np.linalg.norm(r) * np.linalg.norm(g):
            raise _refuse(model, f"body {body.name!r} has its {label} at {np.round(axes.T @ r, 12).tolist()} m (world "
                                 f"axes, from its joint) off the vertical of gravity = "
                                 f"{np.asarray(model.gravity).tolist()} m/s^2: its rest configuration is not the "
                                 "equilibrium; only bodies on the vertical through their joint")
    stiffness = outboard_mass * float(child @ g) + body.mass * float(center @ g)
    return [SpatialGeometricStiffness(f"{body.name}__gravity", stiffness, g)] if stiffness else []
