"""Flexible bodies in the acceleration-based TMM and the implicit DT-TMM.

* :class:`ModalBeam` -- Euler-Bernoulli beam with clamped-free modes in its floating (root
  tangent) frame: a body type of :class:`ctmm.planar.PlanarModel` (:mod:`ctmm.flexible.beam`);
  :class:`ModalForce` is the hook for actuators and modal feedback on its modal equations.
* :mod:`ctmm.flexible.kernel` -- the O(n) sweep for trees of rigid bodies and modal beams
  (modal accelerations eliminated locally); used automatically by :mod:`ctmm.planar`'s
  ``accelerations``, ``simulate_rk4``, ``simulate_scipy`` and ``simulate_implicit``.
* :mod:`ctmm.flexible.segments` -- finite-segment beams (rigid segments + spring-damper hinges).
* :mod:`ctmm.flexible.outputs` -- tip deflections and other beam outputs of a simulation.

Derivations: ``docs/flexible.md``.
"""
from .beam import BeamData, ModalBeam, ModalForce
from .kernel import FlexibleSolution, solve_flexible
from .modes import ModeSet
from .outputs import axial_tip_displacement, mape, spinup_law, tip_deflection
from .segments import finite_segment_beam

__all__ = ["ModalBeam", "ModalForce", "BeamData", "ModeSet", "FlexibleSolution",
           "solve_flexible", "finite_segment_beam", "tip_deflection", "axial_tip_displacement",
           "mape", "spinup_law"]
