"""Spatial multibody systems (issue 14): 3-D rigid bodies on revolute, prismatic, universal, spherical,
free, elastic and welded joints, solved by the one articulated sweep (:mod:`ctmm.articulated`, d = 6).

Modules: :mod:`~ctmm.spatial.elements` (descriptions), :mod:`~ctmm.spatial.model` (trees, coordinates),
:mod:`~ctmm.spatial.frames` (rotations in :mod:`ctmm.ops`), :mod:`~ctmm.spatial.body_forms` (protocol
terms, :class:`SpatialScene`), :mod:`~ctmm.spatial.dynamics` (accelerations, reactions); the modal spatial
beam :class:`SpatialBeam` (:mod:`~ctmm.spatial.beam`, ``docs/spatial_modal_beam.md``); closed kinematic loops
:class:`SpatialKinematicLoopModel` with :class:`SpatialCutJoint` (:mod:`~ctmm.spatial.closed_loops`,
``docs/closed_loops.md`` section 8).
Conventions and derivations: ``docs/spatial.md``.
"""
from .beam import SpatialBeam
from .body_forms import SpatialScene
from .closed_loops import SpatialCutJoint, SpatialKinematicLoopModel
from .dynamics import SpatialSolution, accelerations, energy, reactions, solve, state_rates
from .integrate import simulate_spatial
from .elements import Elastic6, Free, Load, Prismatic, Revolute, SpatialBody, Spherical, Universal, Weld
from .model import SpatialModel

__all__ = ["SpatialBody", "Revolute", "Prismatic", "Universal", "Spherical", "Free", "Elastic6", "Weld", "Load",
           "SpatialModel", "SpatialScene", "SpatialSolution", "solve", "accelerations", "reactions", "state_rates", "energy", "simulate_spatial", "SpatialBeam",
           "SpatialCutJoint", "SpatialKinematicLoopModel"]
