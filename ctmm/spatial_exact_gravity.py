"""Gravity on spatial chains and trees in the exact-field bridge (:mod:`ctmm.spatial_exact_fields`).

A spatial chain or tree whose every branch hangs or stands along gravity from its joint is in
equilibrium at its rest configuration, preloaded only axially (docs/spatial_beams.md §7).  About it the
second-order potential of gravity gives the terms of the field form:

* a beam along gravity (``g_a = g . b_1`` along its axis ``b_1``) carries the tension ``T(x) = g_a
  (rhoA (L - x) + sum of the masses of the subtrees hung at its stations beyond x)`` [N] -- only its own
  subtree: a sibling branch hung elsewhere does not pull on it --, linear between stations:
  :class:`~ctmm.spatial_beam_fields.SpatialVaryingTensionField` (:func:`beam_gravity` gives ``g_a``,
  :func:`beam_tension` the tension at the ends of a piece);
* a rigid body gets the rotational stiffness ``k (I - g g^T / |g|^2)`` with ``k = g . S`` and ``S`` its
  **outboard first moment** about its joint (:func:`rigid_preload`,
  :class:`~ctmm.spatial_beam_elements.SpatialGeometricStiffness`): the pendulum terms.

Derivation of the rigid term.  Give every body ``b`` a small absolute rotation ``theta_b`` (chain axes;
the field form's state carries exactly these rotations).  A point of body ``b`` at rest position ``x`` moves
to ``p_root + sum over the bodies a on the path root..b of R(theta_a) l_a``, where ``l_a`` is the lever of
body ``a`` from its joint to the next point of the path (the joint of its child towards ``b``, or for ``b``
itself the point).  With ``R(theta) = I + [theta]x + 1/2 [theta]x^2 + O(theta^3)`` the second-order part of
the position is ``sum_a 1/2 theta_a x (theta_a x l_a)``; the potential ``V = -sum m g . x`` of all the
bodies, regrouped by body ``a``, is ``V_2 = sum_a 1/2 theta_a^T K_a theta_a`` with

    K_a = (g . S_a) I - (g S_a^T + S_a g^T) / 2,      S_a = m_a c_a + sum_k M_k r_k      [N m/rad]

(``c_a``: its centre of mass, ``r_k``: the point of its child ``k``, ``M_k``: the whole mass of the subtree
of child ``k``, all from its joint).  The first-order part ``V_1 = -sum_a theta_a . (S_a x g)`` vanishes
for every ``theta_a`` iff every ``S_a`` is parallel to ``g``: then every joint carries no static moment
(the subtree of each joint has its first moment about it on the vertical, by induction from the tips),
the rest configuration is an equilibrium whatever the joints free, and ``K_a = (g . S_a) (I - g g^T /
|g|^2)``.  The children's points need not lie on the vertical, only ``S_a``: a hub carrying two equal
pendulums at ``+-d`` sideways is in equilibrium, and its term uses the outboard first moment, not just
the mass at one child point.  Rotating a whole subtree rigidly (``theta_b = theta`` for every ``b`` in it)
gives ``sum_b K_b = (g . S) (I - g g^T / |g|^2)`` with ``S`` the subtree's first moment about its joint:
the pendulum stiffness of the subtree's outboard mass at its outboard centre of mass.  Beams: the
transverse deflection ``w`` shortens the beam at second order by ``1/2 int_0^x |w'|^2``, which lowers
every mass hung beyond ``x`` (``V_2 = 1/2 int T |w'|^2``, the tension above); the bodies hung on a
beam add their own ``K_a`` from their own rotations.

About the unstretched rest geometry: the static axial stretch of extensible beams and elastic joints
under the preload (relative ``T / EA``, ``T / k``) is neglected, as in the consistent geometric
stiffness of linear finite elements.  Adding it is not only geometry: about the stretched state the
bending fields' coefficients change by ``O(T / EA)`` in a way that depends on the finite-strain law (an
extensible elastica with ``M = EI dtheta/dS`` has, per stretched length ``ds = (1 + T/EA) dS``, the
bending stiffness ``EI (1 + T/EA)`` and mass ``rhoA / (1 + T/EA)``; the modal beam's ``EI int w''^2 dS`` with
its axial modes is another law), which the linear theory of the exact fields does not choose.  So the
stretch stays out and is **warned** (:class:`StretchWarning`, :func:`warn_stretch`) when a beam with axial
modes (finite ``EA``) carries a relative stretch ``max |T| / EA`` above :data:`STRETCH_TOLERANCE`: its
frequencies are then that order away from the stretched beam's.  Measured
(``tests/test_spatial_exact_stretch.py``, a beam with a tip body hanging from a revolute joint, against an
extensible finite-segment chain linearised about its stretched equilibrium): the pendulum frequency of the
exact fields is above the stretched one by ``6.9e-4, 6.8e-5`` at ``EA = 5e3, 5e4 N`` (``max T / EA = 1.8e-3,
1.8e-4``: about half the mean strain, the lengthened pendulum), while the modal beam with axial modes, which
keeps the stretch, is within ``2e-6`` of the chain; in the first bending mode the two laws differ at the
same order (the modal beam ``8e-4`` from the chain, the exact fields ``1.1e-3``).  A beam without axial
modes is inextensible in both forms (no warning).

Refused (:class:`~ctmm.errors.ModelError`, naming the part): free and prismatic joints in gravity (their rest
configuration is not the equilibrium), beams across gravity (they bend under their weight) and bodies whose
outboard first moment ``S_a`` is off the vertical through their joint (they swing, or their joint carries a static
moment).
"""
from __future__ import annotations

import warnings
from typing import Any, Sequence

import numpy as np

from .errors import ModelError

__all__ = ["check_gravity", "beam_gravity", "beam_tension", "rigid_preload", "subtree_masses", "hung_masses",
           "StretchWarning", "STRETCH_TOLERANCE", "warn_stretch"]

STRETCH_TOLERANCE = 1e-9
"""Largest relative static stretch ``max |T| / EA`` of a beam with axial modes that the exact fields neglect without
a :class:`StretchWarning` (the accuracy the bridge certifies elsewhere, ``RIGID_TOLERANCE``)."""


class StretchWarning(UserWarning):
    """The exact fields neglect a beam's static axial stretch above :data:`STRETCH_TOLERANCE` (module docstring)."""


def _refuse(model: Any, reason: str) -> ModelError:
    return ModelError(f"fields='exact' cannot convert spatial model {model.name!r}: {reason}")


def check_gravity(model: Any) -> None:
    """Refuse gravity with free or prismatic joints (module docstring)."""
    if not np.any(np.asarray(model.gravity) != 0.0):
        return
    gravity = np.asarray(model.gravity).tolist()
    moving = [j.name for j in model.joints if j.kind in ("free", "prismatic")]
    if moving:
        raise _refuse(model, f"gravity = {gravity} m/s^2 with the free or prismatic joints {moving}: their rest "
                             "configuration is not the equilibrium (give gravity=(0, 0, 0))")


def subtree_masses(model: Any) -> np.ndarray:
    """Mass [kg] of every body's subtree (the body and everything hung on it, at any depth)."""
    masses = np.array([float(body.mass) for body in model.bodies])
    for j in range(len(model.bodies) - 1, -1, -1):   # parents come before their children
        if model.parent[j] >= 0:
            masses[model.parent[j]] += masses[j]
    return masses


def hung_masses(model: Any, body: int, masses: np.ndarray) -> list[tuple[str, float]]:
    """``(point name, subtree mass [kg])`` of every child of ``body`` (``masses``: :func:`subtree_masses`)."""
    return [(model.joints[j].point, float(masses[j])) for j, p in enumerate(model.parent) if p == body]


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


def beam_tension(along: float, beam: Any, hung: Sequence[tuple[float, float]], start: float, end: float
                 ) -> tuple[float, float]:
    """Tension [N] at ``start`` and ``end`` [m] of a piece of ``beam`` with no station inside.

    Parameters
    ----------
    along : float
        Gravity along the beam's axis [m/s^2] (:func:`beam_gravity`).
    hung : sequence of (float, float)
        ``(x [m], subtree mass [kg])`` of every child hung on the beam: those at ``x >= end`` hang beyond
        the piece.
    """
    beyond = sum(mass for x, mass in hung if x >= end - 1e-12 * beam.length)
    return tuple(along * (beyond + beam.mass_per_length * (beam.length - x)) for x in (start, end))


def rigid_preload(model: Any, axes: np.ndarray, body: Any, center: np.ndarray,
                  children: Sequence[tuple[np.ndarray, float]]) -> list:
    """The :class:`~ctmm.spatial_beam_elements.SpatialGeometricStiffness` of a rigid body in gravity ([] without).

    Parameters
    ----------
    axes : (3, 3) ndarray
        ``Q``, chain from world axes.
    center : (3,) ndarray
        Centre of mass from the body's joint [m], chain axes.
    children : sequence of ((3,) ndarray, float)
        Point [m] (from the body's joint, chain axes) and subtree mass [kg] of every child.
    """
    from .spatial_beam_elements import SpatialGeometricStiffness

    g = axes @ np.asarray(model.gravity, dtype=float)
    if not np.any(g):
        return []
    moment = body.mass * center + sum((mass * point for point, mass in children), np.zeros(3))
    scale = body.mass * np.linalg.norm(center) + sum(mass * np.linalg.norm(point) for point, mass in children)
    if np.linalg.norm(np.cross(moment, g)) > 1e-12 * scale * np.linalg.norm(g):
        raise _refuse(model, f"body {body.name!r} has its outboard first moment (m c + sum of its children's "
                             f"subtree masses x their points) at {np.round(axes.T @ moment, 12).tolist()} kg m (world "
                             f"axes, from its joint; centre of mass at {np.round(axes.T @ center, 12).tolist()} m) off "
                             f"the vertical of gravity = {np.asarray(model.gravity).tolist()} m/s^2: its rest "
                             "configuration is not the equilibrium; only bodies whose outboard mass centres on the "
                             "vertical through their joint")
    stiffness = float(moment @ g)
    return [SpatialGeometricStiffness(f"{body.name}__gravity", stiffness, g)] if stiffness else []


def warn_stretch(model: Any, beam: Any, tension: float) -> None:
    """Warn (:class:`StretchWarning`) when ``beam``, with axial modes, stretches by more than :data:`STRETCH_TOLERANCE`
    under its largest static tension ``tension`` [N] (at its root; module docstring)."""
    if not beam.n_axial_modes or not beam.axial_stiffness:
        return
    strain = abs(tension) / beam.axial_stiffness
    if strain > STRETCH_TOLERANCE:
        warnings.warn(f"fields='exact' on spatial model {model.name!r}: beam {beam.name!r} (EA = "
                      f"{beam.axial_stiffness:g} N, axial modes) carries a static axial force of up to "
                      f"{abs(tension):.6g} N, a relative stretch of {strain:.3g} that the exact fields neglect "
                      "(linear theory about the unstretched beam): its frequencies differ from the stretched beam's "
                      "by that order (a pendulum mode by about half the mean strain).  fields='modal' keeps the "
                      "stretch; n_axial_modes=0 makes the beam inextensible in both forms", StretchWarning,
                      stacklevel=4)
