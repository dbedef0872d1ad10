"""Per-model data and body terms of planar trees of rigid bodies and modal beams, swept by the one
articulated sweep (:func:`ctmm.articulated.articulated_sweep`).

Every body ``j`` provides its transfer relations in the generalised form (``n_j`` modal
coordinates, ``n_j = 0`` for a rigid body; ``x_j = [A_I ; eta'']``):

``[F_I ; 0] = M_j x_j + h_j + sum_e RF_e F_e``   (Newton-Euler + modal equations)
``A_e = Kin_e x_j + c_e``                         (kinematics of outboard end ``e``)

``F_e`` is the wrench exerted by body ``j`` on what hangs at end ``e``.  For a rigid body
``M = K``, ``Kin = X``, ``RF = X^T`` (FORMULAS 3.4, ``docs/planar.md``); for a beam see
:mod:`ctmm.flexible.beam`.  :meth:`FlexibleSystem.sweep` hands these terms (unbatched 2-D
matrices, the ``B = 1`` fast path of :mod:`ctmm.ops`) with the joints (revolute ``S = e3`` with the
hinge torque and tangent ``kappa``, driven, free base) to the one sweep, which eliminates the modal
accelerations locally and the joints tip to base (``docs/planar.md``, "The one articulated
sweep"); cost O(sum (3 + n_j)^3), linear in the number of bodies.

The implicit DT-TMM (:mod:`ctmm.flexible.implicit`) feeds the same sweep with Newton-tangent
relations: the body relations depend on the body's own angle, rate, modal coordinates and
rates, which the integrator ties to the body's own unknowns (``d theta = beta' h^2 d alpha``,
``d eta = beta' h^2 d eta''``, rates with ``gamma' h``); the tangent columns are computed by
complex-step differentiation of the body terms (exact to round-off), so every Newton iteration
is again one O(n) sweep of transfer relations.
"""
from __future__ import annotations

import math
from dataclasses import dataclass

import numpy as np

from ..articulated import Tree, articulated_sweep
from ..errors import ModelError, SimulationError
from ..ops import NUMPY
from ..planar.body_forms import rigid_body_terms
from ..planar.hinge_laws import law_torques
from ..planar.model import DRIVEN, FREE, REVOLUTE, PlanarModel
from ..protocol import BodyTerms, JointTerms

_E3_COLUMN = np.array([[0.0], [0.0], [1.0]])
_EYE3 = np.eye(3)
_ZERO3 = np.zeros((3, 1))


class _StateOps:
    """The operations :func:`ctmm.planar.body_forms.rigid_body_terms` uses, at one real state: numpy's cosine and
    sine as Python floats (the numbers of :data:`ctmm.ops.NUMPY` on the same angle; float arithmetic is the numpy
    scalars' arithmetic) and 2-D matrices without the batch axis (the ``B = 1`` terms of the batched path)."""

    @staticmethod
    def cos(x: float) -> float:
        return float(np.cos(x))

    @staticmethod
    def sin(x: float) -> float:
        return float(np.sin(x))

    @staticmethod
    def block(rows: list) -> np.ndarray:
        return np.array(rows, dtype=float)

    @staticmethod
    def transpose(a: np.ndarray) -> np.ndarray:
        return a.T


_STATE_OPS = _StateOps()


@dataclass(frozen=True)
class FlexibleSolution:
    """Accelerations, joint forces and modal accelerations at one instant.

    Attributes
    ----------
    qddot : (n_coordinates,)
    body_acceleration : (n_bodies, 3)
        ``[a_x, a_y, alpha]`` at each body's inboard end.
    joint_force : (n_bodies, 3)
        ``[f_x, f_y, tau]`` exerted on each body at its inboard end by its parent / ground.
    hinge_acceleration : (n_bodies,)
        Relative angular acceleration of each body's joint.
    end_acceleration : (n_bodies, 3)
        State ``A`` of the parent end each body hangs on.
    modal_acceleration : dict
        ``{body name: eta''}`` of the flexible bodies.
    """

    qddot: np.ndarray
    body_acceleration: np.ndarray
    joint_force: np.ndarray
    hinge_acceleration: np.ndarray
    end_acceleration: np.ndarray
    modal_acceleration: dict


class FlexibleSystem:
    """Per-model data of the mixed sweep (built once, by the model's constructor; see :func:`system_of`)."""

    def __init__(self, model: PlanarModel) -> None:
        if np.any(model.joint_kind == 3):
            raise ModelError("hinges with translational springs are not supported together with "
                             "flexible bodies yet")
        self.model = model
        nb = model.n_bodies
        self.nb = nb
        self.parent = model.parent.tolist()
        self.kind = model.joint_kind.tolist()
        self.pend = model.parent_end_index.tolist()
        self.beam_data = {j: b.data for j, b in model.beams.items()}
        # bodies whose data offer the terms at one real state (BeamData.terms_at_state; others: batched terms, B = 1);
        # the data, not their bound methods, are kept: a model holding this system stays describable (cache keys)
        self.at_state = {j: d for j, d in self.beam_data.items() if hasattr(d, "terms_at_state")}
        self.n_modal = [self.beam_data[j].n if j in self.beam_data else 0 for j in range(nb)]
        self.modal_index = model.modal_index
        self.rigid = [j for j in range(nb) if j not in self.beam_data]
        # rigid loads (beam loads are handled by the beam terms)
        lb = model.load_body
        self.rigid_load_rows = [k for k in range(len(lb)) if int(lb[k]) not in self.beam_data]
        # the rigid bodies' numbers as Python floats for rigid_body_terms (points keyed by end index)
        self.end_points = [{e: (float(v[0]), float(v[1])) for e, v in enumerate(model.ends[j].values())}
                           for j in range(nb)]
        self.mass, self.inertia = [float(v) for v in model.mass], [float(v) for v in model.inertia]
        self.com = [(float(c[0]), float(c[1])) for c in model.com]
        self.gravity = (float(model.gravity[0]), float(model.gravity[1]))
        self.free_base = [j for j in range(nb) if self.kind[j] == FREE]
        # row of each coordinate's acceleration in the stacked x = [A_I ; eta''] of all bodies
        rows = np.full(model.n_coordinates, -1)
        offset = 0
        for j in range(nb):
            if model.theta_index[j] >= 0:
                rows[model.theta_index[j]] = offset + 2
            if self.kind[j] == FREE:
                rows[model.xy_index[j, 0]], rows[model.xy_index[j, 1]] = offset, offset + 1
            rows[self.modal_index[j]] = offset + 3 + np.arange(self.n_modal[j])
            offset += 3 + self.n_modal[j]
        if np.any(rows < 0):                           # pragma: no cover - every coordinate has a row
            raise ModelError(f"model {model.name!r}: coordinates without an acceleration row in the sweep")
        self.coordinate_rows = rows
        # the tree of the one sweep; a body's points are keyed by their index in its terms' end list
        self.tree = Tree(tuple(self.parent), tuple(None if p < 0 else e for p, e in zip(self.parent, self.pend)), 3)
        # per body the ends that carry a child: the only points whose terms the sweep reads
        self.carrying = [tuple(sorted({e for p, e in zip(self.parent, self.pend) if p == j})) for j in range(nb)]

    # -- per-body terms -------------------------------------------------------------------
    def rigid_terms(self, j: int, theta, omega, t: float, loads, ends=None):
        """Batched complex-safe rigid-body relations: the one statement
        :func:`ctmm.planar.body_forms.rigid_body_terms` (FORMULAS 3.4), in this kernel's layout
        ``M (B, 3, 3)``, ``h (B, 3)``, per end ``(Kin, c (B, 3), RF, theta, omega)`` (``ends``: indices of the
        wanted ends, the others ``None``; default every end)."""
        m = self.model
        body_loads = [(*m.load_point[k], *loads[k]) for k in self.rigid_load_rows if m.load_body[k] == j]
        if theta.shape[0] == 1:             # one evaluation (a rigid body has no modal directions): numpy scalars
            theta_j, omega_j = theta[0], omega[0]
        else:
            theta_j, omega_j = theta[:, None, None], omega[:, None, None]
        points = self.end_points[j] if ends is None else {e: p for e, p in self.end_points[j].items() if e in ends}
        terms = rigid_body_terms(NUMPY, mass=self.mass[j], inertia=self.inertia[j], center_of_mass=self.com[j],
                                 points=points, gravity=self.gravity, theta=theta_j, omega=omega_j, loads=body_loads)
        return terms.M, terms.h[:, :, 0], [(terms.Kin[e], terms.c[e][:, :, 0], terms.RF[e], theta, omega)
                                           if e in points else None for e in self.end_points[j]]

    def rigid_terms_at_state(self, j: int, theta: float, omega: float, loads, ends) -> list:
        """:meth:`rigid_terms` of rigid body ``j`` at one real state, unbatched: ``[M (3, 3), h (3,), [(Kin, c (3,),
        RF) or None per end]]`` (``ends``: indices of the wanted ends), the same numbers as :meth:`rigid_terms` at
        ``B = 1`` (the one statement on Python floats instead of ``(1, 3, 3)`` arrays)."""
        m = self.model
        body_loads = [(*m.load_point[k], *loads[k]) for k in self.rigid_load_rows if m.load_body[k] == j]
        points = {e: p for e, p in self.end_points[j].items() if e in ends}
        terms = rigid_body_terms(_STATE_OPS, mass=self.mass[j], inertia=self.inertia[j], center_of_mass=self.com[j],
                                 points=points, gravity=self.gravity, theta=theta, omega=omega, loads=body_loads)
        return [terms.M, terms.h[:, 0], [(terms.Kin[e], terms.c[e][:, 0], terms.RF[e]) if e in points else None
                                         for e in self.end_points[j]]]

    def body_terms(self, j: int, theta, omega, eta, eta_dot, t: float, loads):
        """Terms of body ``j`` (batched over the leading axis of ``theta``)."""
        if j in self.beam_data:
            return self.beam_data[j].terms(theta, omega, eta, eta_dot, t, self.model.gravity)
        return self.rigid_terms(j, theta, omega, t, loads)

    def state(self, q, qdot, t: float, driven: list | None = None):
        """Angles, rates and modal coordinates of all bodies (``driven``: ``model.driven(t)`` if known)."""
        m = self.model
        theta, omega = m.body_angles(q, qdot, t, driven)
        eta = [q[idx] for idx in self.modal_index]
        eta_dot = [qdot[idx] for idx in self.modal_index]
        return theta, omega, eta, eta_dot

    def all_terms(self, q, qdot, t: float, driven: list | None = None, *, carrying: bool = False):
        """Unbatched terms of every body at one real state (see :meth:`sweep`) and the state; ``carrying=True``:
        only the ends that carry a child (the ones the sweep reads), ``None`` for the others."""
        theta, omega, eta, eta_dot = self.state(q, qdot, t, driven)
        loads = self.model.loads(t) if len(self.model.load_body) else np.zeros((0, 3))
        terms = []
        for j in range(self.nb):
            wanted = self.carrying[j] if carrying else None
            if j in self.at_state:                      # one real state: the body's unbatched fast path
                M, h, ends = self.at_state[j].terms_at_state(float(theta[j]), float(omega[j]), eta[j], eta_dot[j], t,
                                                             self.gravity, wanted)
                terms.append([M, h, [None if e is None else e[:3] for e in ends]])
            elif j in self.beam_data:
                M, h, ends = self.body_terms(j, theta[j:j + 1], omega[j:j + 1], eta[j][None, :], eta_dot[j][None, :],
                                             t, loads)
                terms.append([M[0], h[0], [(K[0], c[0], R[0]) for K, c, R, _, _ in ends]])
            else:
                terms.append(self.rigid_terms_at_state(j, float(theta[j]), float(omega[j]), loads,
                                                       self.end_points[j] if wanted is None else wanted))
        return terms, (theta, omega, eta, eta_dot, loads)

    def hinge_torques(self, q, qdot, theta, omega, t: float) -> np.ndarray:
        m = self.model
        dtheta, domega = m.relative_angles(theta, omega, q, qdot)
        reference, rate, torque = m.hinge_laws(t)
        tau = torque - m.stiffness * (dtheta - reference) - m.damping * (domega - rate)
        return tau + law_torques(m, dtheta, domega) if m.nonlinear_hinges else tau

    def driven_alpha(self, t: float, driven: list | None = None) -> list:
        """Prescribed joint accelerations [rad/s^2] per body (``driven``: ``model.driven(t)`` if known)."""
        alpha = [0.0] * self.nb
        for i, _, _, acceleration in (self.model.driven(t) if driven is None else driven):
            alpha[i] = acceleration
        return alpha

    # -- the sweep ----------------------------------------------------------------------------
    def sweep(self, terms, kappa, tau, alpha_driven, *, full: bool = True):
        """The one articulated sweep (:func:`ctmm.articulated.articulated_sweep`) of these terms.

        ``terms``: per body ``[M (3+n, 3+n), h (3+n,), [(Kin, c, RF) per end]]`` (unbatched, real);
        ``kappa``: joint tangent per body (revolute joints), or ``None`` for the explicit sweep
        (``kappa = 0``); ``tau``: hinge torques [N m]; ``alpha_driven``: prescribed relative
        accelerations of driven joints [rad/s^2].

        Returns ``x`` (list of ``[A_I ; eta'']``), ``F`` (nb, 3), ``A_O`` (nb, 3) and the joint
        accelerations (nb,); with ``full=False`` only ``x`` (the others ``None``).

        Raises
        ------
        SimulationError
            A singular modal matrix or articulated inertia, naming the element.
        """
        out, _ = self._articulated(terms, kappa, tau, alpha_driven, full)
        x = [xj[:, 0] for xj in out.x]
        if not full:
            return x, None, None, None
        F = np.concatenate(out.force, axis=1).T
        alpha = np.array([0.0 if r is None else r[-1, 0] for r in out.relative])
        AO = np.concatenate([xj[:3] for xj in out.x], axis=1).T   # A_O = A - S a_rel: revolute, driven S = e3
        AO[:, 2] -= alpha
        if self.free_base:
            AO[self.free_base] = 0.0                 # a free base hangs on the ground
        return x, F, AO, alpha

    def _articulated(self, terms, kappa, tau, alpha_driven, forces: bool):
        """:func:`ctmm.articulated.articulated_sweep` of these terms (see :meth:`sweep`) and its ``x`` stacked
        ``(sum (3 + n_j), 1)``, checked finite (else :class:`SimulationError` naming the element)."""
        bodies = []                                     # unbatched 2-D matrices: the B = 1 fast path of ops
        for (M, h, ends), carrying in zip(terms, self.carrying):
            if carrying:                                # only the ends that carry a child are read
                Kin, c, RF = {}, {}, {}
                for e in carrying:
                    Kin[e], ce, RF[e] = ends[e]
                    c[e] = ce.reshape(3, 1)
                bodies.append(BodyTerms(M, h.reshape(-1, 1), Kin, c, RF))
            else:
                bodies.append(BodyTerms(M, h.reshape(-1, 1)))
        tau_c = np.array(tau, dtype=float).reshape(-1, 1, 1)
        joints, kap = [], []
        for j, kj in enumerate(self.kind):
            if kj == REVOLUTE:
                joints.append(JointTerms(S=_E3_COLUMN, tau=tau_c[j], axis=2))
                kap.append(np.array([[kappa[j]]], dtype=float) if kappa is not None and kappa[j] else None)
            elif kj == DRIVEN:
                joints.append(JointTerms(S=_E3_COLUMN, prescribed=np.array([[alpha_driven[j]]], dtype=float), axis=2))
                kap.append(None)
            else:                                       # FREE: a free base (rejected elsewhere otherwise)
                joints.append(JointTerms(S=_EYE3, tau=_ZERO3))
                kap.append(None)
        with np.errstate(all="ignore"):
            try:
                out = articulated_sweep(NUMPY, self.tree, bodies, joints, kap, forces=forces)
            except np.linalg.LinAlgError as exc:
                raise SimulationError(f"articulated inertia or modal matrix of model {self.model.name!r} is "
                                      f"singular ({exc})", element=self._singular_element(terms)) from exc
        stacked = np.concatenate(out.x)
        if not math.isfinite(stacked.sum()) and not np.isfinite(stacked).all():
            # a zero or non-finite pivot leaves no finite x
            for j, pivot in enumerate(out.pivot):
                if pivot is not None and pivot.shape[-1] == 1:
                    d = pivot[0, 0]
                    if not (d != 0.0 and abs(d) < np.inf):
                        raise SimulationError(f"articulated inertia of joint {self.model.joint_names[j]!r} is "
                                              f"singular ({d!r})", element=self.model.joint_names[j])
            raise SimulationError(f"articulated inertia or modal matrix of model {self.model.name!r} is singular "
                                  "(non-finite accelerations)", element=self._singular_element(terms))
        return out, stacked

    def _singular_element(self, terms) -> str | None:
        """Name of the body whose own modal matrix is worst conditioned (for error messages)."""
        beams = [j for j in range(self.nb) if self.n_modal[j]]
        if not beams:
            return None
        worst = max(beams, key=lambda j: np.linalg.cond(terms[j][0][3:, 3:]))
        return self.model.body_names[worst]

    def qddot(self, x) -> np.ndarray:
        """Generalised accelerations from the sweep's ``x`` (list of ``[A_I ; eta'']``)."""
        return np.concatenate(x)[self.coordinate_rows]

    def apply_inputs(self, terms: list, theta: np.ndarray, tau: np.ndarray, inputs) -> np.ndarray:
        """Add actuator ``inputs`` (:class:`ctmm.planar.ports.ActuatorInputs`) to the body
        terms (in place: the terms are this step's work arrays) and return the hinge torques."""
        if inputs is None:
            return tau
        wrench = inputs.inboard_wrench(self.model, theta) if inputs.has_wrench() else None   # None: it is zero
        for j in self.rigid if wrench is not None else ():
            terms[j][1] = terms[j][1] - wrench[j]
        for j in set(inputs.modal_force) | set(inputs.frame_wrench):
            h = terms[j][1].copy()
            h[3:] -= inputs.modal_force.get(j, 0.0)
            if j in inputs.frame_wrench:         # station loads on the beam's floating frame
                h[:3] -= wrench[j]
            terms[j][1] = h
        return tau + inputs.hinge_torque

    def solve(self, q, qdot, t: float = 0.0, inputs=None) -> FlexibleSolution:
        """Explicit forward dynamics (one sweep), with optional actuator ``inputs``."""
        return self.solve_inputs(q, qdot, t, [inputs])[0]

    def solve_inputs(self, q, qdot, t: float, inputs_list) -> list[FlexibleSolution]:
        """:meth:`solve` at one state for each actuator inputs of ``inputs_list``: the body terms and hinge laws
        evaluated once, one sweep per entry (each result the same as with those inputs alone)."""
        q, qdot = self.model.state(q, qdot)
        driven = self.model.driven(t)
        terms, (theta, omega, _, _, _) = self.all_terms(q, qdot, t, driven, carrying=True)
        torques, alpha_driven = self.hinge_torques(q, qdot, theta, omega, t), self.driven_alpha(t, driven)
        solutions = []
        for inputs in inputs_list:
            own = [[M, h, ends] for M, h, ends in terms]      # apply_inputs replaces the h entries, never edits them
            tau = self.apply_inputs(own, theta, torques, inputs)
            x, F, AO, alpha = self.sweep(own, None, tau.tolist(), alpha_driven)
            A = np.array([xj[:3] for xj in x])
            modal = {self.model.body_names[j]: x[j][3:].copy() for j in self.beam_data}
            solutions.append(FlexibleSolution(self.qddot(x), A, F, alpha, AO, modal))
        return solutions

    def accelerations(self, q, qdot, t: float = 0.0, inputs=None, *, checked: bool = False) -> np.ndarray:
        """Generalised accelerations (one sweep), with optional actuator ``inputs``;
        ``q, qdot`` checked by :meth:`PlanarModel.state` (``checked=True``: the caller did)."""
        if not checked:
            q, qdot = self.model.state(q, qdot)
        driven = self.model.driven(t)
        terms, (theta, omega, _, _, _) = self.all_terms(q, qdot, t, driven, carrying=True)
        tau = self.apply_inputs(terms, theta, self.hinge_torques(q, qdot, theta, omega, t), inputs)
        _, stacked = self._articulated(terms, None, tau.tolist(), self.driven_alpha(t, driven), False)
        return stacked[self.coordinate_rows, 0]           # qddot of the stacked x


def system_of(model: PlanarModel) -> FlexibleSystem:
    """The :class:`FlexibleSystem` of a model with flexible bodies (built with the model,
    :attr:`ctmm.planar.PlanarModel.flexible_system`)."""
    if model.flexible_system is None:
        raise ModelError(f"model {model.name!r} has no flexible bodies")
    return model.flexible_system


def solve_flexible(model: PlanarModel, q, qdot, t: float = 0.0) -> FlexibleSolution:
    """Forward dynamics of a model with modal beams: accelerations, joint forces, modal
    accelerations (one O(n) sweep)."""
    return system_of(model).solve(q, qdot, t)


__all__ = ["FlexibleSolution", "FlexibleSystem", "solve_flexible", "system_of"]
