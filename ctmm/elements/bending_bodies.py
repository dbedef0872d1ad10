"""Rigid bodies and revolute joints in the bending layout (:data:`~ctmm.layouts.BENDING`, frequency domain).

The exact-field form of a straight planar chain (:mod:`ctmm.exact_fields`) needs, besides the
exact :class:`~ctmm.elements.beams.BeamField`, a rigid segment of the chain and a revolute joint
with a general law.  State ``z = [w, theta, shear, moment]`` (``shear`` and ``moment`` exerted by
the inboard part on the outboard part, in ``+w`` and ``+theta``), small motion about the straight
reference, ``w`` transverse to it.

* :class:`RigidSegment` -- a rigid body from its inboard point (``x = 0``) to its outboard point
  (``x = length``) with mass ``m``, centre of mass at ``x = a`` and inertia ``J_c`` about it.
  Kinematics ``w_out = w_in + length theta``, ``theta_out = theta_in``; Newton
  ``m s^2 (w_in + a theta) = shear_in - shear_out + F`` and Euler about the inboard point
  ``(J_c + m a^2) s^2 theta + m a s^2 w_in = moment_in - moment_out - length shear_out + M + a F``
  (``F`` transverse force at the centre of mass, ``M`` moment: inputs ``"force"``, ``"moment"``).
* :class:`RevoluteJoint` -- a massless joint with the law ``moment = tau - Z(s) (theta_out -
  theta_in)``, ``Z(s) = k + c s`` (``Z != 0``): ``theta_out = theta_in + (tau - moment) / Z``,
  ``w``, shear and moment continuous; input ``"torque"`` ``tau`` [N m] (parent on child).
"""
from __future__ import annotations

from typing import Any, Mapping

import numpy as np

from .. import validation
from ..errors import ModelError
from ..layouts import BENDING
from .base import Element
from .bending import identity_matrices, laplace_array

__all__ = ["RigidSegment", "RevoluteJoint"]


class RigidSegment(Element):
    """Rigid body of a straight chain in the bending layout (module docstring).

    Parameters
    ----------
    name : str
    length : float
        Inboard to outboard point [m], >= 0.
    mass : float
        ``m`` [kg], >= 0.
    inertia : float
        ``J_c`` [kg m^2] about the centre of mass, >= 0.
    center : float
        ``a`` [m], the centre of mass from the inboard point along the axis.
    """

    layout = BENDING
    is_point = False
    inputs = ("force", "moment")

    def __init__(self, name: str, *, length: float, mass: float, inertia: float, center: float = 0.0) -> None:
        super().__init__(name)
        self.length = validation.nonnegative(f"{name}: length", length)
        self.mass = validation.nonnegative(f"{name}: mass", mass)
        self.inertia = validation.nonnegative(f"{name}: inertia", inertia)
        self.center = validation.finite(f"{name}: center", center)

    def parameters(self) -> dict[str, Any]:
        return {"length": self.length, "mass": self.mass, "inertia": self.inertia, "center": self.center}

    def transfer_matrix(self, s: Any) -> np.ndarray:
        s = laplace_array(s)
        U = identity_matrices(s)
        ell, a, m, s2 = self.length, self.center, self.mass, s * s
        inertia = self.inertia + m * a * a
        U[..., 0, 1] = ell
        U[..., 2, 0] = -m * s2
        U[..., 2, 1] = -m * a * s2
        U[..., 3, 0] = (ell - a) * m * s2
        U[..., 3, 1] = (ell * a * m - inertia) * s2
        U[..., 3, 2] = -ell
        return U

    def load_vector(self, s: Any, amplitudes: Mapping[str, Any]) -> np.ndarray:
        self.check_inputs(amplitudes)
        s = laplace_array(s)
        u = np.zeros(s.shape + (4,), dtype=complex)
        force = amplitudes.get("force", 0.0)
        u[..., 2] = force
        u[..., 3] = amplitudes.get("moment", 0.0) + (self.center - self.length) * force
        return u


class RevoluteJoint(Element):
    """Massless revolute joint with the law ``moment = tau - (k + c s) (theta_out - theta_in)``.

    Parameters
    ----------
    name : str
    stiffness : float
        ``k`` [N m/rad], >= 0.
    damping : float
        ``c`` [N m s/rad], >= 0; ``k`` and ``c`` not both 0 (a free joint has no transfer
        matrix: its slope jump is not fixed by the moment).
    """

    layout = BENDING
    is_point = False
    inputs = ("torque",)

    def __init__(self, name: str, *, stiffness: float, damping: float = 0.0) -> None:
        super().__init__(name)
        self.stiffness = validation.nonnegative(f"{name}: stiffness", stiffness)
        self.damping = validation.nonnegative(f"{name}: damping", damping)
        if self.stiffness == 0.0 and self.damping == 0.0:
            raise ModelError(f"{name}: stiffness and damping are both 0: a free joint inside a chain has no "
                             "transfer matrix; give it a spring or a damper")

    def parameters(self) -> dict[str, Any]:
        return {"stiffness": self.stiffness, "damping": self.damping}

    def _impedance(self, s: np.ndarray) -> np.ndarray:
        impedance = self.stiffness + self.damping * s
        if np.any(impedance == 0):
            raise ModelError(f"{self.name}: the joint impedance k + c s vanishes at s = 0 (a pure damper): "
                             "omega = 0 is not allowed")
        return impedance

    def transfer_matrix(self, s: Any) -> np.ndarray:
        s = laplace_array(s)
        U = identity_matrices(s)
        U[..., 1, 3] = -1.0 / self._impedance(s)
        return U

    def load_vector(self, s: Any, amplitudes: Mapping[str, Any]) -> np.ndarray:
        self.check_inputs(amplitudes)
        s = laplace_array(s)
        u = np.zeros(s.shape + (4,), dtype=complex)
        u[..., 1] = amplitudes.get("torque", 0.0) / self._impedance(s)
        return u
