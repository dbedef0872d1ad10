"""Frequency responses of spatial models by the one sweep's frequency context (``d = 6``), batched over omega.

About a static operating point ``q0`` (rates 0) the body terms of :class:`ctmm.spatial.body_forms.SpatialScene`
are linearised once: ``Z_j(s) = s^2 M0 + s C0 + K0`` with ``M0`` the body's mass terms at ``q0`` and
``K0 = dh/d eta``, ``C0 = dh/d eta_dot`` of a flexible body (:class:`~ctmm.spatial.SpatialBeam`, ``ctmm.fem``
spatial subsystems) by complex step through the batched terms (exact to round-off); ``Kin``, ``RF`` and the
joints' free directions ``S`` at ``q0``, velocity products 0; joints ``kappa(s) = -(tau_q + s tau_v)`` of
their laws, driven joints held.  The unknowns are the displacement amplitudes ``[dp ; dphi ; d eta]`` of
every body's inboard point (world axes) and the joints' relative amplitudes in their velocity coordinates
(the tangent coordinates of :mod:`ctmm.spatial_linearization`).  The dimension-generic part (the batched
sweep, one per input column, pivots certified per frequency, loops closed per frequency) is
:mod:`ctmm.sweep_response`.

* An actuator loads the terms by the difference of the sweep's terms at unit and zero input: joint
  torques and forces enter their joint's ``tau``, body forces and moments (world or body axes, at any
  point of a rigid body or a beam) the body's ``h``;
* a sensor or tangent coordinate is the linear functional ``y = (dy/dr + s dy/dv) r_hat``
  (:func:`ctmm.spatial_linearization.output_matrix`).

**What this context states** (:func:`sweep_applies`; the caller answers everything else by the dense
resolvent of :func:`ctmm.linearize`).  The sweep's joint equation ``S^T F = tau`` linearises to
``S0^T dF + dS^T F0 = d tau``: the free directions of a spatial joint turn with its parent, and with a
static wrench ``F0`` across the joint that second term (the geometric stiffness of the preload across the
joint axes) couples the joint to its parent's rotation -- a term the protocol's joint terms do not carry.
It vanishes when every static joint wrench does: no gravity, no applied loads at ``q0``, and the static
sweep's joint wrenches zero (checked, :data:`PRELOAD_TOLERANCE`); then the body terms' rigid columns of
``K0`` vanish too (``h`` at rest does not depend on the body's pose).  Joints: revolute, prismatic and
universal (linear or nonlinear laws: their tangents are exact), spherical without a rotary spring, free,
weld, and any driven joint; not elastic 6-DOF hinges or sprung spherical joints (their law's tangent in
the rotation vector is the stiffness only at the rest rotation).  Models under gravity or preloaded take
the dense path whole (``info["method"]`` says which).
"""
from __future__ import annotations

import dataclasses
from typing import Any, Sequence

import numpy as np

from .articulated import articulated_sweep
from .errors import ModelError
from .ops import NUMPY
from .sweep_response import ArticulatedResponse

__all__ = ["SpatialSweepResponse", "sweep_applies", "model_applies", "PRELOAD_TOLERANCE"]

PRELOAD_TOLERANCE = 1e-10
"""Largest static joint wrench accepted as no preload, relative to ``1 + `` the largest entry of the mass
terms and joint stiffnesses (the round-off of an unloaded equilibrium)."""

_STEP = 1e-30


def model_applies(model: Any) -> bool:
    """The part of :func:`sweep_applies` that does not depend on the operating point: no gravity, and no
    elastic 6-DOF hinge or sprung spherical joint that is not driven."""
    if np.any(np.asarray(model.gravity) != 0.0):
        return False
    return not any(not joint.driven and (joint.kind == "elastic6" or (joint.kind == "spherical"
                                                                      and np.any(joint.stiffness)))
                   for joint in model.joints)


def sweep_applies(model: Any, point: Any) -> bool:
    """True when the frequency context states ``model`` about ``point`` (module docstring; the static
    joint wrenches are checked by :class:`SpatialSweepResponse`)."""
    if not point.equilibrium or np.any(point.qdot != 0.0) or not model_applies(model):
        return False
    return not any(np.any(np.asarray(load.values(point.t)) != 0.0) for load in model.loads)


class SpatialSweepResponse(ArticulatedResponse):
    """The open-loop response ``G(s)`` of a spatial model about a static operating point by the batched sweep.

    Parameters
    ----------
    model : SpatialModel
    point : OperatingPoint
        A static equilibrium (:func:`ctmm.spatial_linearization.operating_point`).
    ports : SpatialPorts, optional
        The model's resolved ports (built when omitted).

    Raises
    ------
    ModelError
        The context does not state the model (:func:`sweep_applies`, or a static joint wrench above
        :data:`PRELOAD_TOLERANCE`).
    """

    def __init__(self, model: Any, point: Any, ports: Any = None) -> None:
        from .spatial.body_forms import SpatialScene
        from .spatial.ports import SpatialPorts

        if not sweep_applies(model, point):
            raise ModelError(f"the one sweep's frequency context does not state {model.name!r} about this point "
                             "(gravity, applied loads, elastic or sprung spherical joints, or a moving point)")
        self.model, self.point = model, point
        self.scene = SpatialScene(model)
        self.ports = SpatialPorts(model) if ports is None else ports
        q0, t, n = np.asarray(point.q, dtype=float), float(point.t), model.n_velocities
        modal = [(j, layout) for j, layout in enumerate(model.modal) if layout is not None]
        coordinates = [(j, p, v, k) for j, layout in modal
                       for k, (p, v) in enumerate(zip(range(layout.position.start, layout.position.stop),
                                                      range(layout.velocity.start, layout.velocity.stop)))]
        m = len(coordinates)
        q_rows = np.repeat(q0[None], 1 + 2 * m, axis=0).astype(complex)
        v_rows = np.zeros((1 + 2 * m, n), dtype=complex)
        for r, (_, p, v, _) in enumerate(coordinates):       # complex steps of every modal coordinate and rate
            q_rows[1 + r, p] += 1j * _STEP
            v_rows[1 + m + r, v] += 1j * _STEP
        bodies, joints, _ = self.scene.terms(NUMPY, q_rows, v_rows, t, self.scene.numpy_inputs(None, t, 1 + 2 * m))
        self.base_bodies, self.base_joints = self._real(bodies), self._real(joints)
        static = articulated_sweep(NUMPY, self.scene.tree, self.base_bodies, self.base_joints)
        self._check_preload(static)
        linear = []
        for j, body in enumerate(bodies):
            M0 = np.asarray(body.M)[0].real.copy()
            K0, C0 = np.zeros_like(M0), np.zeros_like(M0)
            h = np.broadcast_to(body.h, (1 + 2 * m,) + np.shape(body.h)[1:])[:, :, 0]
            for r, (owner, _, _, k) in enumerate(coordinates):
                if owner == j:
                    K0[:, 6 + k] = h[1 + r].imag / _STEP
                    C0[:, 6 + k] = h[1 + m + r].imag / _STEP
            linear.append((M0, C0, K0, {e: v[:1].real for e, v in body.Kin.items()},
                           {e: v[:1].real for e, v in body.RF.items()}))
        held = []
        for joint in self.base_joints:
            k = joint.free
            if joint.prescribed is not None:
                held.append(dataclasses.replace(joint, c=None, prescribed=np.zeros((1, k, 1))))
            else:
                held.append(dataclasses.replace(joint, c=None, tau=None if joint.tau is None else np.zeros((1, k, 1))))
        self.prepare(self.scene.tree, linear, held)

    @staticmethod
    def _real(terms: list) -> list:
        """The first row (the unperturbed point) of batched body or joint terms, real."""
        def first(value: Any) -> Any:
            if isinstance(value, dict):
                return {e: first(v) for e, v in value.items()}
            if isinstance(value, np.ndarray) and value.ndim == 3:
                return value[:1].real.copy()
            return value

        return [dataclasses.replace(item, **{f.name: first(getattr(item, f.name))
                                             for f in dataclasses.fields(item)}) for item in terms]

    def _check_preload(self, static: Any) -> None:
        """Refuse (``ModelError``) a static joint wrench above :data:`PRELOAD_TOLERANCE` (module docstring)."""
        scale = 1.0 + max(float(np.max(np.abs(body.M))) for body in self.base_bodies)
        for joint in self.model.joints:
            scale += float(np.max(np.abs(getattr(joint, "stiffness", 0.0)), initial=0.0))
        largest = max(float(np.max(np.abs(force), initial=0.0)) for force in static.force)
        if not largest <= PRELOAD_TOLERANCE * scale:
            raise ModelError(f"the one sweep's frequency context does not state {self.model.name!r}: a static joint "
                             f"wrench of {largest:.3e} (the joints' free directions turn with their parents under it)")

    def loads(self, name: str) -> tuple[list, list]:
        """Body load columns ``h`` (1, 6 + n_j, 1) and joint terms of actuator ``name`` at unit amplitude: the
        difference of the sweep's terms at unit and zero input."""
        inputs = self.ports.inputs({name: 1.0})
        t = float(self.point.t)
        bodies, joints, _ = self.scene.terms(NUMPY, np.asarray(self.point.q, float)[None],
                                             np.zeros((1, self.model.n_velocities)), t,
                                             self.scene.numpy_inputs(inputs.joint, t, 1), inputs.wrenches)
        loads = [np.asarray(unit.h)[:1].real - base.h
                 for unit, base in zip(bodies, self.base_bodies)]
        out = []
        for unit, base, held in zip(joints, self.base_joints, self.joints):
            if unit.tau is None or held.prescribed is not None:
                out.append(held)
                continue
            amplitude = np.asarray(unit.tau)[:1].real - (0.0 if base.tau is None else base.tau)
            out.append(dataclasses.replace(held, tau=amplitude) if np.any(amplitude) else held)
        return loads, out

    def check(self, inputs: Sequence[str], outputs: Sequence[str]) -> None:
        """Every input an actuator of the model's ports (else its error); outputs are checked by :meth:`rows`."""
        for name in inputs:
            self.ports.check_actuator(name)

    def rows(self, outputs: list) -> np.ndarray:
        """``(outputs, 2 nv)``: ``[dy/dr, dy/dv]`` (:func:`ctmm.spatial_linearization.output_matrix`)."""
        from .spatial_linearization import output_matrix

        return output_matrix(self.model, outputs, self.point)

    def amplitudes(self, solution: Any) -> np.ndarray:
        """Tangent amplitudes ``r_hat`` (B, nv) of a frequency-context sweep (velocity order)."""
        parts = self.scene.velocity_rates(solution)
        batch = max(np.shape(part)[0] for part in parts) if parts else 1
        return np.concatenate([np.broadcast_to(part, (batch,) + np.shape(part)[1:])[:, :, 0] for part in parts],
                              axis=1) if parts else np.zeros((batch, 0))
