"""Pinocchio models of the spatial test models (the independent peer of the spatial tests)."""
from __future__ import annotations

from typing import Any

import numpy as np


def pinocchio_driven_chain(pin: Any, model: Any) -> tuple[Any, int]:
    """Pinocchio's model of the three-body chain ``ja`` (revolute about x) - ``jb`` (revolute about
    ``(0, 1, 1)``, at the tip 1 m below) - ``jc`` (ball) with ``model``'s bodies and gravity, and ``jb``'s joint
    index."""
    pm = pin.Model()
    pm.gravity = pin.Motion(model.gravity, np.zeros(3))
    j1 = pm.addJoint(0, pin.JointModelRevoluteUnaligned(np.array([1.0, 0, 0])), pin.SE3.Identity(), "ja")
    j2 = pm.addJoint(j1, pin.JointModelRevoluteUnaligned(np.array([0, 1.0, 1.0]) / np.sqrt(2)),
                     pin.SE3(np.eye(3), np.array([0, 0, -1.0])), "jb")
    j3 = pm.addJoint(j2, pin.JointModelSpherical(), pin.SE3(np.eye(3), np.array([0, 0, -1.0])), "jc")
    for j, b in zip((j1, j2, j3), model.bodies):
        pm.appendBodyToJoint(j, pin.Inertia(b.mass, b.center_of_mass, b.inertia), pin.SE3.Identity())
    return pm, j2
