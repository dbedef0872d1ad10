"""Frequency responses of spatial models by the one sweep's frequency context (``d = 6``), batched over omega.

About a static operating point ``q0`` (rates 0) the body terms of :class:`ctmm.spatial.body_forms.SpatialScene`
are linearised once: ``Z_j(s) = s^2 M0 + s C0 + K0`` with ``M0`` the body's mass terms at ``q0``, ``K0`` the
slopes of ``h + sum_e RF_e F_e0`` in the body's rotation (below) and, of a flexible body
(:class:`~ctmm.spatial.SpatialBeam`, ``ctmm.fem`` spatial subsystems), in ``eta``, ``C0 = dh/d eta_dot``, by
complex step through the batched terms (exact to round-off); ``Kin``, ``RF`` and the
joints' free directions ``S`` at ``q0``, velocity products 0; joints ``kappa(s) = -(tau_q + s tau_v)`` of
their laws, driven joints held.  The unknowns are the displacement amplitudes ``[dp ; dphi ; d eta]`` of
every body's inboard point (world axes) and the joints' relative amplitudes in their velocity coordinates
(the tangent coordinates of :mod:`ctmm.spatial_linearization`).  The dimension-generic part (the batched
sweep, one per input column, pivots certified per frequency, loops closed per frequency) is
:mod:`ctmm.sweep_response`.  Rigid trees whose joints are revolute, prismatic, welds or driven (one free
direction ``S`` each, or held) take the compiled kernel of :mod:`ctmm.compiled_sweep` at ``d = 6`` when a C
compiler is present (every input column in one sweep, both certificates decided in C; the tangent amplitudes
are the joints' relative amplitudes, :meth:`SpatialSweepResponse.point_amplitudes`), rigid trees with universal,
spherical or free joints its multi-direction variant; beams, finite-element subsystems and every model without a
compiler, the generic sweep.

* An actuator loads the terms by the difference of the sweep's terms at unit and zero input: joint
  torques and forces enter their joint's ``tau``, body forces and moments (world or body axes, at any
  point of a rigid body or a beam) the body's ``h``;
* a sensor or tangent coordinate is the linear functional ``y = (dy/dr + s dy/dv) r_hat``
  (:func:`ctmm.spatial_linearization.output_matrix`).

**Preloaded equilibria** (gravity, static loads, static joint wrenches).  The static sweep at ``q0`` gives
every joint's wrench ``F0 = [f0 ; m0]`` (world axes, at the child's inboard point).  Linearising each of the
sweep's equations about it:

* body ``F_in = M A + h + sum_e RF_e F_e``: ``K0`` also holds ``d(h + sum_e RF_e F_e0)/d phi`` in the body's
  rotation columns (gravity's and the loads' moment arms, body-axes loads, the children's static wrenches
  carried by turning arms), by complex step of a rotation ``i h e_k`` of the body's terms alone
  (:meth:`ctmm.spatial.body_forms.SpatialScene.terms` ``turn``); nothing depends on a body's position;
* kinematics ``A = Kin_e x_p + S a``: already linear in the displacements (``S`` at ``q0``);
* joint ``S^T F = tau``: ``S0^T dF + dS^T F0 = d tau``.  A joint's free directions ``[u_i ; w_i]`` (world
  axes) turn rigidly with its parent point's rotation ``delta`` (the rotational rows of ``A_O``):
  ``dS_i = [delta x u_i ; delta x w_i]``, so ``dS_i^T F0 = (u_i x f0 + w_i x m0) . delta`` -- the coupling
  ``G = [0 , (u_i x f0 + w_i x m0)^T]`` (k x 6) of :func:`ctmm.articulated.articulated_inward`.  Directions
  that also turn with the joint's own coordinates add ``K_own[i, l] = (w_l x w_i) . m0`` to ``kappa``
  (``tau_q - K_own``): a universal joint's second axis turns with the first (``l = 0, i = 1``); revolute and
  prismatic directions do not; an unsprung spherical joint (its body axes turn with its coordinates) and a
  free joint carry no static moment, resp. wrench, at an equilibrium (``S^T F0 = 0``, ``S`` invertible on it).
  When a joint moves the child's inboard material point relative to the parent's point ``P`` (prismatic:
  ``u a``), the parent receives the child's wrench about the shifted point: ``H = [0 ; u_i x f0]``
  (:func:`ctmm.articulated.articulated_inward`).

**What this context states** (:func:`sweep_applies`; the caller answers everything else by the dense
resolvent of :func:`ctmm.linearize`): static operating points (rates 0, an equilibrium) of models whose joints
are revolute, prismatic and universal (linear or nonlinear laws: their tangents are exact), spherical
without a rotary spring, free, weld, and any driven joint; not elastic 6-DOF hinges or sprung spherical
joints (their law's tangent in the rotation vector is the stiffness only at the rest rotation).
``info["method"]`` says which path answered.
"""
from __future__ import annotations

import dataclasses
from typing import Any, Sequence

import numpy as np

from .articulated import articulated_sweep
from .errors import ModelError
from .ops import NUMPY
from .sweep_response import ArticulatedResponse

__all__ = ["SpatialSweepResponse", "sweep_applies", "model_applies"]

_STEP = 1e-30


def model_applies(model: Any) -> bool:
    """The part of :func:`sweep_applies` that does not depend on the operating point: no elastic 6-DOF hinge
    or sprung spherical joint that is not driven."""
    return not any(not joint.driven and (joint.kind == "elastic6" or (joint.kind == "spherical"
                                                                      and np.any(joint.stiffness)))
                   for joint in model.joints)


def sweep_applies(model: Any, point: Any) -> bool:
    """True when the frequency context states ``model`` about ``point`` (module docstring: a static equilibrium,
    preloaded or not, of a model whose joints the sweep states)."""
    return bool(point.equilibrium and not np.any(point.qdot != 0.0) and model_applies(model))


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
        The context does not state the model (:func:`sweep_applies`).
    """

    def __init__(self, model: Any, point: Any, ports: Any = None) -> None:
        from .spatial.body_forms import SpatialScene
        from .spatial.ports import SpatialPorts

        if not sweep_applies(model, point):
            raise ModelError(f"the one sweep's frequency context does not state {model.name!r} about this point "
                             "(elastic or sprung spherical joints, or a moving point or not an equilibrium)")
        self.model, self.point = model, point
        self.scene = SpatialScene(model)
        self.ports = SpatialPorts(model) if ports is None else ports
        q0, t, n = np.asarray(point.q, dtype=float), float(point.t), model.n_velocities
        modal = [(j, layout) for j, layout in enumerate(model.modal) if layout is not None]
        coordinates = [(j, p, v, k) for j, layout in modal
                       for k, (p, v) in enumerate(zip(range(layout.position.start, layout.position.stop),
                                                      range(layout.velocity.start, layout.velocity.stop)))]
        m = len(coordinates)
        rows = 1 + 2 * m + 3                                # q0, modal coordinates, modal rates, 3 rotations
        q_rows = np.repeat(q0[None], rows, axis=0).astype(complex)
        v_rows = np.zeros((rows, n), dtype=complex)
        turn = np.zeros((rows, 3, 1), dtype=complex)
        for r, (_, p, v, _) in enumerate(coordinates):       # complex steps of every modal coordinate and rate
            q_rows[1 + r, p] += 1j * _STEP
            v_rows[1 + m + r, v] += 1j * _STEP
        for k in range(3):                                  # ... and of every body's rotation (its terms alone)
            turn[1 + 2 * m + k, k, 0] = 1j * _STEP
        bodies, joints, _ = self.scene.terms(NUMPY, q_rows, v_rows, t, self.scene.numpy_inputs(None, t, rows),
                                             turn=turn)
        self.base_bodies, self.base_joints = self._real(bodies), self._real(joints)
        static = articulated_sweep(NUMPY, self.scene.tree, self.base_bodies, self.base_joints)
        wrench: dict = {}                                   # F_e0: the children's static wrenches at each point
        for c, parent in enumerate(self.scene.tree.parent):
            if parent >= 0:
                key = (parent, self.scene.tree.point[c])
                wrench[key] = wrench.get(key, 0.0) + static.force[c][0]
        linear = []
        for j, body in enumerate(bodies):
            M0 = np.asarray(body.M)[0].real.copy()
            K0, C0 = np.zeros_like(M0), np.zeros_like(M0)
            Q = np.broadcast_to(body.h, (rows,) + np.shape(body.h)[1:])
            for e, RF in body.RF.items():                   # Q = h + sum_e RF_e F_e0 at every row
                if (j, e) in wrench:
                    Q = Q + RF @ wrench[(j, e)]
            Q = Q[:, :, 0]
            K0[:, 3:6] = Q[1 + 2 * m:].imag.T / _STEP
            for r, (owner, _, _, k) in enumerate(coordinates):
                if owner == j:
                    K0[:, 6 + k] = Q[1 + r].imag / _STEP
                    C0[:, 6 + k] = Q[1 + m + r].imag / _STEP
            linear.append((M0, C0, K0, {e: v[:1].real for e, v in body.Kin.items()},
                           {e: v[:1].real for e, v in body.RF.items()}))
        held, coupling = [], []
        for j, (joint, spec) in enumerate(zip(self.base_joints, model.joints)):
            k = joint.free
            if joint.prescribed is not None:
                held.append(dataclasses.replace(joint, c=None, prescribed=np.zeros((1, k, 1))))
                coupling.append(None)
                continue
            F0 = static.force[j][0]
            tau_q = self._own_stiffness(spec.kind, joint, F0)
            if tau_q is not None:
                tau_q = tau_q if joint.tau_q is None else np.asarray(joint.tau_q)[0] + tau_q
            tau = None if joint.tau is None and tau_q is None else np.zeros((1, k, 1))
            held.append(dataclasses.replace(joint, c=None, tau=tau,
                                            tau_q=joint.tau_q if tau_q is None else tau_q[None]))
            coupling.append(self._coupling(joint, F0) if k and self.scene.tree.parent[j] >= 0 else None)
        self.prepare(self.scene.tree, linear, held, coupling)

    @staticmethod
    def _coupling(joint: Any, F0: np.ndarray) -> tuple | None:
        """``(G, H)`` of a joint with free directions ``[u_i ; w_i]`` under the static wrench ``F0`` (module
        docstring): ``G = [0 , (u_i x f0 + w_i x m0)^T]`` (1, k, 6), ``H = [0 ; u_i x f0]`` (1, 6, k);
        ``None`` where they vanish."""
        S = np.asarray(joint.S)[0].real
        shift = np.cross(S[:3].T, F0[:3, 0])                                    # (k, 3): u_i x f0
        arms = shift + np.cross(S[3:].T, F0[3:, 0])
        G = np.concatenate([np.zeros_like(arms), arms], axis=1)[None] if np.any(arms) else None
        H = np.concatenate([np.zeros_like(shift), shift], axis=1).T[None] if np.any(shift) else None
        return None if G is None and H is None else (G, H)

    @staticmethod
    def _own_stiffness(kind: str, joint: Any, F0: np.ndarray) -> np.ndarray | None:
        """``-K_own`` (2, 2), the change of ``tau_q`` of a universal joint whose second axis ``w_1`` turns with its
        first coordinate under the static moment ``m0`` (module docstring), or ``None`` (the other joints)."""
        if kind != "universal":
            return None
        w = np.asarray(joint.S)[0].real[3:]                # (3, 2): the rotational directions
        own = np.zeros((2, 2))
        own[1, 0] = np.dot(np.cross(w[:, 0], w[:, 1]), F0[3:, 0])
        return -own

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

    def loads(self, name: str) -> tuple[list, list]:
        """Body load columns ``h`` (1, 6 + n_j, 1) and joint terms of actuator ``name`` at unit amplitude: the
        difference of the sweep's terms at unit and zero input."""
        return self.load_cases([name])[0]

    def load_cases(self, names: list) -> list:
        """:meth:`loads` of every actuator in ``names``, from one batched evaluation of the terms (row ``i``: the
        unit input of ``names[i]``)."""
        count, t = len(names), float(self.point.t)
        if not count:
            return []
        joint_inputs: dict = {}
        wrenches: dict = {}
        for i, name in enumerate(names):
            inputs = self.ports.inputs({name: 1.0})
            for key, value in inputs.joint.items():
                joint_inputs.setdefault(key, np.zeros((count, np.size(value))))[i] += value
            for j, entries in inputs.wrenches.items():
                for point, column, *axes in entries:
                    rows = np.zeros((count,) + np.shape(column)[1:])
                    rows[i] = column[0]
                    wrenches.setdefault(j, []).append((point, rows, *axes))
        bodies, joints, _ = self.scene.terms(NUMPY, np.repeat(np.asarray(self.point.q, float)[None], count, axis=0),
                                             np.zeros((count, self.model.n_velocities)), t,
                                             self.scene.numpy_inputs(joint_inputs, t, count), wrenches)
        cases = []
        for i in range(count):
            loads = [row(unit.h, i, count) - base.h for unit, base in zip(bodies, self.base_bodies)]
            out = []
            for unit, base, held in zip(joints, self.base_joints, self.joints):
                if unit.tau is None or held.prescribed is not None:
                    out.append(held)
                    continue
                amplitude = row(unit.tau, i, count) - (0.0 if base.tau is None else base.tau)
                out.append(dataclasses.replace(held, tau=amplitude) if np.any(amplitude) else held)
            cases.append((loads, out))
        return cases

    def check(self, inputs: Sequence[str], outputs: Sequence[str]) -> None:
        """Every input an actuator of the model's ports (else its error); outputs are checked by :meth:`rows`."""
        for name in inputs:
            self.ports.check_actuator(name)

    def rows(self, outputs: list) -> np.ndarray:
        """``(outputs, 2 nv)``: ``[dy/dr, dy/dv]`` (:func:`ctmm.spatial_linearization.output_matrix`)."""
        from .spatial_linearization import output_matrix

        return output_matrix(self.model, outputs, self.point, self.ports)

    reads_joint_amplitudes = True

    def point_amplitudes(self, answer: Any) -> np.ndarray:
        """Tangent amplitudes ``r_hat`` (L, B, nv) from the compiled kernel's answer (rigid trees on one-direction
        joints, welds and held drives: the velocity coordinates are the free joints' relative amplitudes, in
        joint order -- :meth:`ctmm.spatial.body_forms.SpatialScene.velocity_rates`)."""
        if answer.relative.shape[0] != self.model.n_velocities:         # the kernel takes no other trees
            raise ModelError(f"the compiled sweep answered {answer.relative.shape[0]} joint amplitudes for "
                             f"{self.model.n_velocities} velocities of {self.model.name!r}")
        return np.moveaxis(answer.relative, 0, -1)

    def amplitudes(self, solution: Any) -> np.ndarray:
        """Tangent amplitudes ``r_hat`` (B, nv) of a frequency-context sweep (velocity order)."""
        parts = self.scene.velocity_rates(solution)
        batch = max(np.shape(part)[0] for part in parts) if parts else 1
        return np.concatenate([np.broadcast_to(part, (batch,) + np.shape(part)[1:])[:, :, 0] for part in parts],
                              axis=1) if parts else np.zeros((batch, 0))


def row(value: Any, index: int, count: int) -> np.ndarray:
    """Row ``index`` (1, ...) of a batched numpy term of ``count`` rows (or of one row broadcast), real."""
    value = np.asarray(value)
    return np.broadcast_to(value, (count,) + value.shape[1:])[index:index + 1].real
