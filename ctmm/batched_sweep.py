"""The articulated sweep's frequency context as one numpy kernel, the frequency batch as the last axis.

:func:`ctmm.articulated.articulated_sweep` is written once for every context on :mod:`ctmm.ops` (numpy and
casadi); on numpy its per-body work is a few dozen calls on ``(B, d, d)`` batches.  For the frequency context of
trees whose bodies are rigid (``d`` unknowns each) and whose joints are welds, held drives or one unit free
direction (``JointTerms.axis``: planar hinges), the same recursion is about fifteen array operations per body on
contiguous ``(d, d, B)`` blocks (small enough to stay in cache: no ``(N, d, d, B)`` array is formed): the joint
elimination as a rank-one update, the move to the parent point as one ``(d^2, d^2)`` product (``vec(RF Phi Kin) =
kron(RF, Kin^T) vec(Phi)``, row-major), every load case at once (the articulated inertias do not depend on the
loads), real arithmetic for undamped terms on the imaginary axis.  Same arithmetic as the generic sweep (answers
equal to round-off); :func:`applies` says which terms it takes, the others stay on the generic sweep.  Besides the
pivots it states the answer's a-posteriori backward error (:meth:`BatchedSweep.backward_error`), the second
certificate of :mod:`ctmm.sweep_response`.

Tip to base, body ``j`` with ``P = Z_j + sum_children RF Phi_hat Kin``, ``p = h_j + sum_children RF psi_hat``:
joint on unit axis ``a``: ``D = P_aa + kappa``, ``w = (P_a: + G) / D``, ``u = (P_:a + H) / D``, ``r = (tau - p_a) / D``,
``Phi_hat = P - (P_:a + H) w``, ``psi_hat = p + (P_:a + H) r``; weld or held drive: ``Phi_hat = P``, ``psi_hat = p``.
Base to tip: ``A_O = Kin_e x_parent`` (ground 0), ``a = r - w . A_O``, ``x = A_O + e_a a``.
"""
from __future__ import annotations

from dataclasses import dataclass
from typing import Any, Sequence

import numpy as np

from .articulated import Tree

__all__ = ["BatchedSweep", "applies"]


def applies(tree: Tree, bodies: Sequence[tuple], joints: Sequence[Any], coupling: Sequence[Any] | None) -> bool:
    """True when :class:`BatchedSweep` takes these frequency-context terms: every body rigid (``M0`` of size
    ``d``), every joint a weld, a drive held at zero or one unit free direction (``axis``) without inertance, no
    joint offset ``c``, coupling (if any) only on one-direction joints."""
    d = tree.dimension
    for j, (M0, _, _, _, _) in enumerate(bodies):
        if M0.shape != (d, d):
            return False
        joint = joints[j]
        if joint.c is not None or joint.tau_a is not None:
            return False
        if any(law is not None and np.size(law) != 1 for law in (joint.tau_q, joint.tau_v)):
            return False
        if joint.prescribed is not None:
            if np.any(joint.prescribed):
                return False
        elif joint.free and joint.axis is None:
            return False
        if coupling is not None and coupling[j] is not None and any(g is not None for g in coupling[j]) \
                and (joint.axis is None or joint.prescribed is not None):
            return False
    return True


@dataclass(frozen=True)
class Solution:
    """Result of :meth:`BatchedSweep.solve`.

    Attributes
    ----------
    x : list of ndarray, shape (d, L, B)
        ``A_in`` of every body (load cases, frequencies).
    pivot : ndarray, shape (F, B)
        ``D_j`` of the one-direction joints, in :attr:`BatchedSweep.free` order.
    mass_pivot : ndarray, shape (F,), or None
        The same pivots of the mass terms alone (when asked for).
    backward : ndarray, shape (B,), or None
        The a-posteriori backward error (:meth:`BatchedSweep.backward_error`, when asked for).
    """

    x: list
    pivot: np.ndarray
    mass_pivot: np.ndarray | None = None
    backward: np.ndarray | None = None


class BatchedSweep:
    """The frequency-context sweep of one tree's linearised terms (module docstring), prepared once.

    Parameters
    ----------
    tree : Tree
    bodies : sequence of tuple
        ``(M0, C0, K0, Kin, RF)`` per body (``Kin``, ``RF``: dicts of ``(1, d, d)`` point maps).
    joints : sequence of JointTerms
        The held joints (``tau`` is the load cases' business: :meth:`solve`).
    coupling : sequence, optional
        ``(G_j, H_j)`` per joint or ``None`` (:func:`ctmm.articulated.articulated_inward`).
    """

    def __init__(self, tree: Tree, bodies: Sequence[tuple], joints: Sequence[Any],
                 coupling: Sequence[Any] | None = None) -> None:
        d = self.d = tree.dimension
        self.tree, self.n = tree, len(bodies)
        stacked = [np.stack([b[k] for b in bodies])[..., None] for k in range(3)]   # (N, d, d, 1)
        self.M0, self.C0, self.K0 = (list(terms) for terms in stacked)               # (d, d, 1) views
        self.damped_bodies = bool(np.any(stacked[1]))
        # [M0; K0; C0] (3 d, d) per body and its moduli: the products of the a-posteriori residual
        terms = np.concatenate([stacked[0], stacked[2], stacked[1]], axis=1)[..., 0]       # (N, 3 d, d)
        self.terms, self.moduli = list(terms), list(np.abs(terms))
        self.axis = [None if joint.prescribed is not None or not joint.free else joint.axis for joint in joints]
        self.free = [j for j, a in enumerate(self.axis) if a is not None]
        self.slot = {j: k for k, j in enumerate(self.free)}
        # the joints' law tangents -tau_q, -tau_v (real unless a law says otherwise)
        laws = np.array([[0.0 if law is None else complex(np.asarray(law).reshape(-1)[0])
                          for law in (joints[j].tau_q, joints[j].tau_v)] for j in self.free], dtype=complex)
        laws = laws.reshape(len(self.free), 2)
        self.real_laws = not np.any(laws.imag)
        laws = laws.real if self.real_laws else laws
        self.stiffness, self.damping = laws[:, 0], laws[:, 1]
        self.kron, self.RF, self.Kin = [None] * self.n, [None] * self.n, [None] * self.n
        children = [j for j, parent in enumerate(tree.parent) if parent >= 0]
        for j in children:
            e = tree.point[j]
            self.RF[j], self.Kin[j] = bodies[tree.parent[j]][4][e][0], bodies[tree.parent[j]][3][e][0]
        if children:                                # vec(RF X Kin) = kron(RF, Kin^T) vec(X), all in one product
            RF, Kin = np.stack([self.RF[j] for j in children]), np.stack([self.Kin[j] for j in children])
            kron = (RF[:, :, None, :, None] * Kin.swapaxes(1, 2)[:, None, :, None, :]).reshape(len(children),
                                                                                             d * d, d * d)
            for k, j in enumerate(children):
                self.kron[j] = kron[k]
        self.RF_moduli = [None if RF is None else np.abs(RF) for RF in self.RF]
        self.G, self.H = [None] * self.n, [None] * self.n
        for j, pair in enumerate(coupling or ()):
            if pair is not None and self.axis[j] is not None:
                G, H = pair
                self.G[j] = None if G is None else np.asarray(G).reshape(d, 1)
                self.H[j] = None if H is None else np.asarray(H).reshape(d, 1)
        self.undamped = not self.damped_bodies and not np.any(self.damping)

    def solve(self, s: np.ndarray, loads: np.ndarray, torques: np.ndarray, *, mass_only: bool = False,
              mass_pivots: bool = False, residual: bool = False) -> Solution:
        """The sweep at the Laplace variables ``s`` (B,) for the load cases ``loads`` (N, d, L) (body load
        columns ``h``) and ``torques`` (F, L) (the one-direction joints' ``tau``).

        ``mass_only``: the terms ``Z = M0``, ``kappa = 0`` and no coupling (``s`` is ignored but for its size): the
        pivots of the mass terms alone.  ``mass_pivots``: those pivots too (:attr:`Solution.mass_pivot`; one more
        column of the same sweep when there is no coupling).  ``residual``: the a-posteriori backward error of
        the answer too (:meth:`backward_error`, :attr:`Solution.backward`).  Real arithmetic where every term is
        real (undamped model, ``s`` on the imaginary axis, real loads).
        """
        d, n = self.d, self.n
        s = np.asarray(s).reshape(-1)
        coupled = any(g is not None for g in self.G + self.H)
        if mass_pivots and coupled:
            mass = self.solve(np.zeros(1), np.zeros((self.n, d, 1)), np.zeros((len(self.free), 1)),
                              mass_only=True).pivot[:, 0]
            solution = self.solve(s, loads, torques, residual=residual)
            return Solution(solution.x, solution.pivot, mass, solution.backward)
        extra = mass_pivots                         # the last column: Z = M0, kappa = 0
        real = (mass_only or (self.undamped and not np.any(s.real))) and self.real_laws \
            and not np.iscomplexobj(loads) and not np.iscomplexobj(torques)
        squared = np.ones(s.size) if mass_only else (s * s).real if real else s * s
        if mass_only:
            kappa = np.zeros((len(self.free), s.size))
        elif real:
            kappa = -np.broadcast_to(self.stiffness[:, None], (len(self.free), s.size))
        else:
            kappa = -(self.stiffness[:, None] + self.damping[:, None] * s)
        if extra:
            s, squared = np.append(s, 0.0), np.append(squared, 1.0)
            kappa = np.concatenate([kappa, np.zeros((len(self.free), 1))], axis=1)
        damped = self.damped_bodies and not mass_only and not real
        L = loads.shape[2]
        # the children's contributions per parent (no (N, d, d, B) array: first touches of large arrays
        # cost more than the arithmetic)
        inertia, bias = [None] * n, [None] * n
        w_all, r_all, relative = [None] * n, [None] * n, [None] * n
        pivot = np.empty((len(self.free), s.size), dtype=float if real else complex)
        for j in range(n - 1, -1, -1):
            P = self.M0[j] * squared if mass_only else self.M0[j] * squared + self.K0[j]      # (d, d, B)
            if damped:
                P = P + self.C0[j] * s
            if extra:
                P[..., -1] = self.M0[j][..., 0]
            if inertia[j] is not None:
                P += inertia[j]
            p = loads[j][:, :, None] if bias[j] is None else loads[j][:, :, None] + bias[j]  # (d, L, B)
            a = self.axis[j]
            parent = self.tree.parent[j]
            if a is not None:
                k = self.slot[j]
                D = pivot[k] = P[a, a] + kappa[k]
                row = P[a] if self.G[j] is None or mass_only else P[a] + self.G[j]
                column = P[:, a] if self.H[j] is None or mass_only else P[:, a] + self.H[j]
                w = w_all[j] = row / D                                      # (d, B)
                r = r_all[j] = (torques[k][:, None] - p[a]) / D             # (L, B)
                if parent < 0:
                    continue
                P = P - column[:, None] * w[None]
                p = p + column[:, None] * r[None]
            elif parent < 0:
                continue
            moved = (self.kron[j] @ P.reshape(d * d, -1)).reshape(d, d, -1)
            inertia[parent] = moved if inertia[parent] is None else inertia[parent] + moved
            load = (self.RF[j] @ p.reshape(d, -1)).reshape(d, L, -1)
            bias[parent] = load if bias[parent] is None else bias[parent] + load
        x: list = [None] * n
        for j in range(n):
            parent = self.tree.parent[j]
            a = self.axis[j]
            if parent >= 0:
                A = (self.Kin[j] @ x[parent].reshape(d, -1)).reshape(d, L, -1)
                if a is not None:
                    relative[j] = r_all[j] - np.einsum("kb,klb->lb", w_all[j], A)
                    A[a] += relative[j]
            else:
                A = np.zeros((d, L, s.size), dtype=pivot.dtype)
                if a is not None:
                    A[a] = relative[j] = r_all[j]
            x[j] = A
        backward = self.backward_error(squared, s if damped else None, loads, torques, kappa, x, relative) \
            if residual else None
        if extra:
            return Solution([A[..., :-1] for A in x], pivot[:, :-1], pivot[:, -1],
                            None if backward is None else backward[:-1])
        return Solution(x, pivot, None, backward)

    def backward_error(self, squared: np.ndarray, s: np.ndarray | None, loads: np.ndarray, torques: np.ndarray,
                       kappa: np.ndarray, x: list, relative: list) -> np.ndarray:
        """(B,) the largest relative residual of the joint equations at the answer ``x``: the a-posteriori
        certificate of :mod:`ctmm.sweep_response` (``RESIDUAL_TOLERANCE``).

        The wrenches follow from the amplitudes alone, tip to base, by products and sums (no division):
        ``F_j = (s^2 M0_j + s C0_j + K0_j) x_j + h_j + sum_children RF_c (F_c + H_c a_c)`` (``s`` ``None``: no
        ``C0`` term; ``squared``, ``s`` (B,)); each one-direction joint must then satisfy
        ``F_j[a] + G_j A_O + kappa_j a_j = tau_j``.  Its residual is measured against the moduli of the terms it
        is made of (``(|s|^2 |M0_j| + ...) |x_j| + |h_j| + ...``, carried along the same sums): a backward error,
        the relative change of the terms that makes ``x`` exact.  Rounding alone leaves about ``N eps``; errors of
        eliminations that cancel many digits -- one near-singular pivot, or moderate ones compounding along a
        path, which the pivot test does not see -- leave their size here.
        """
        d, n = self.d, self.n
        weights = [squared, np.ones(1)] + ([] if s is None else [s])               # of M0, K0, C0
        moduli_of = [np.abs(w) for w in weights]
        parts = slice(0, len(weights) * d)
        residuals, scales = [], []
        wrench, moduli = [None] * n, [None] * n
        loaded = np.any(loads != 0.0, axis=(1, 2))
        lawful = np.any(kappa != 0.0, axis=1)                               # joints with a spring or damper
        driven = np.any(torques != 0.0, axis=1)                             # joints with a torque
        for j in range(n - 1, -1, -1):
            A = x[j]
            flat = A.reshape(d, -1)
            # every term block times x in one product: [M0; K0; C0] x, then weighted by s^2, 1, s
            products = (self.terms[j][parts] @ flat).reshape(len(weights), d, *A.shape[1:])
            bounds = (self.moduli[j][parts] @ np.abs(flat)).reshape(products.shape)
            F, size = products[0] * weights[0] + products[1], bounds[0] * moduli_of[0] + bounds[1]
            if s is not None:
                F += products[2] * s
                size += bounds[2] * moduli_of[2]
            if loaded[j]:
                F += loads[j][:, :, None]
                size += np.abs(loads[j])[:, :, None]
            if wrench[j] is not None:
                F += wrench[j]
                size += moduli[j]
            a, parent = self.axis[j], self.tree.parent[j]
            if a is not None:
                k, rate = self.slot[j], relative[j]                       # a_j (L, B)
                residual, scale = F[a], size[a]
                if lawful[k]:
                    law = kappa[k] * rate
                    residual, scale = residual + law, scale + np.abs(law)
                if driven[k]:
                    residual, scale = residual - torques[k][:, None], scale + np.abs(torques[k])[:, None]
                if self.G[j] is not None and parent >= 0:
                    origin = (self.Kin[j] @ x[parent].reshape(d, -1)).reshape(d, *rate.shape)
                    residual = residual + np.einsum("k,klb->lb", self.G[j][:, 0], origin)
                    scale = scale + np.einsum("k,klb->lb", np.abs(self.G[j][:, 0]), np.abs(origin))
                if self.H[j] is not None:
                    F, size = F + self.H[j][:, :, None] * rate, size + np.abs(self.H[j])[:, :, None] * np.abs(rate)
                residuals.append(residual)
                scales.append(scale)
            if parent >= 0:
                moved = (self.RF[j] @ F.reshape(d, -1)).reshape(F.shape)
                bound = (self.RF_moduli[j] @ size.reshape(d, -1)).reshape(F.shape)
                wrench[parent] = moved if wrench[parent] is None else wrench[parent] + moved
                moduli[parent] = bound if moduli[parent] is None else moduli[parent] + bound
        if not residuals:
            return np.zeros(x[0].shape[-1])
        scale = np.stack(scales)
        with np.errstate(all="ignore"):
            ratio = np.abs(np.stack(residuals)) / np.where(scale > 0.0, scale, 1.0)
        ratio[~np.isfinite(ratio)] = np.inf
        return ratio.max(axis=(0, 1))
