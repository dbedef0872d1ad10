"""Planar multi-rigid-body systems: acceleration-based O(n) TMM, implicit DT-TMM, linear MSTMM.

See ``docs/planar.md`` for the derivations.
"""
from .elements import (ActuatedHinge, DamperHinge, DrivenHinge, ElasticHinge, Fixed, Free,
                       FreeBase, Load, Pinned, RigidBody, SmoothHinge, SpringDamperHinge)
from .model import PlanarModel
from .sweep import InstantaneousSolution, accelerations, ode_rhs, solve_instant

__all__ = ["ActuatedHinge", "DamperHinge", "DrivenHinge", "ElasticHinge", "Fixed", "Free",
           "FreeBase", "Load", "Pinned", "RigidBody", "SmoothHinge", "SpringDamperHinge",
           "PlanarModel", "InstantaneousSolution", "accelerations", "ode_rhs", "solve_instant"]
