"""Planar multi-rigid-body systems: acceleration-based O(n) TMM, implicit DT-TMM, linear MSTMM.

Modules: :mod:`~ctmm.planar.elements` (bodies, hinges, boundaries), :mod:`~ctmm.planar.model`
(chains and trees, validation, coordinates), :mod:`~ctmm.planar.sweep` (O(n) Riccati sweep,
forward dynamics), :mod:`~ctmm.planar.integrate` (RK4, ``solve_ivp``),
:mod:`~ctmm.planar.implicit` (Newmark / generalized-alpha DT-TMM with Newton),
:mod:`~ctmm.planar.equilibrium` (static equilibrium and its hanging guess; the frequency domain
about it: the verbs ``ctmm.natural_frequencies`` etc.).  Compiled RK4: :mod:`ctmm.compiled_scene`
(generated from the element definitions).  Derivations: ``docs/planar.md``.
"""
from .elements import (ActuatedHinge, DamperHinge, DrivenHinge, ElasticHinge, Fixed, Free, NonlinearHinge,
                       FreeBase, Load, Pinned, RigidBody, SmoothHinge, SpringDamperHinge)
from .implicit import simulate_implicit
from .integrate import PlanarSimulation, simulate_rk4, simulate_scipy
from .model import PlanarModel
from .sweep import InstantaneousSolution, accelerations, ode_rhs, solve_instant

__all__ = ["ActuatedHinge", "DamperHinge", "DrivenHinge", "ElasticHinge", "Fixed", "Free",
           "FreeBase", "Load", "NonlinearHinge", "Pinned", "RigidBody", "SmoothHinge", "SpringDamperHinge",
           "PlanarModel", "InstantaneousSolution", "accelerations", "ode_rhs", "solve_instant",
           "PlanarSimulation", "simulate_rk4", "simulate_scipy", "simulate_implicit"]
