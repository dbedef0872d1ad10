"""The dimension-generic part of frequency responses by the one sweep's frequency context (planar and spatial).

:class:`ArticulatedResponse` holds the linearised terms of a tree about a static operating point
(per body ``(M0, C0, K0, Kin, RF)`` of ``Z(s) = s^2 M0 + s C0 + K0``; joints with their laws' tangents,
driven joints held) and answers ``G(s)`` of named actuators and sensors, batched over ``s``: one
articulated sweep (:func:`ctmm.articulated.articulated_sweep`, ``d = 3`` planar, ``d = 6`` spatial) per
input column (rigid trees -- spatial ones also on joints of several directions -- when a C compiler is
present: the compiled kernel of :mod:`ctmm.compiled_sweep`, every column in one sweep), :data:`CHUNK` frequencies at a time, certified per frequency twice: every pivot against its terms
(:data:`PIVOT_TOLERANCE`) and the answer's a-posteriori backward error (:data:`RESIDUAL_TOLERANCE`,
:func:`backward_error`).  :func:`closed_loop_response` closes the feedback loops of a
``ControlledModel`` at each frequency (with and without delay) and certifies the loop matrix.  The planar
(:mod:`ctmm.planar_transfer_response`) and spatial (:mod:`ctmm.spatial_transfer_response`) subclasses say
how their actuators load the terms, how sensors read the amplitudes and which models the context states;
frequencies not certified are answered by the callers' dense resolvent.
"""
from __future__ import annotations

import warnings
from typing import Any, Sequence

import numpy as np

from .articulated import Tree, articulated_sweep, frequency_kappa
from .compiled_sweep import CompiledSweep, SweepAnswer, applies as compiled_applies, compiler_present
from .controlled_linearization import RESOLVENT_CONDITION, controller_response, loop_ports
from .errors import ModelError
from .loop_phasors import close_loops as close_phasor_loops, loop_signal
from .ops import NUMPY
from .protocol import BodyTerms

__all__ = ["ArticulatedResponse", "closed_loop_response", "backward_error", "smallest_singular", "PIVOT_TOLERANCE",
           "RESIDUAL_TOLERANCE", "CHUNK"]

PIVOT_TOLERANCE = 1e-6
"""Smallest accepted pivot of the sweep relative to the terms it is made of.  A pivot ``P = s^2 P_M + (P - s^2 P_M)``
that keeps a fraction ``r`` of its terms amplifies their errors by ``1/r``, and those errors are not only the
rounding of this pivot: they carry the errors of the linearised terms (complex step, assembled finite elements) and
of the children's inverted pivots, which compound along the tree.  ``r >= 1e-6`` bounds the amplification by 1e6
(answers to about 1e-8 for terms good to 1e-14); closer to a resonance the frequency is handed to the dense
resolvent, which answers or refuses by its own scaled-condition rule.  The bound sees one pivot at a time: what the
children's cancellations left in its terms is the business of :data:`RESIDUAL_TOLERANCE`. Measured (session 8) on
the stiff plate chain of ``tests/test_resolvent_scaling.py``, 4e-10 from its hinge mode: hinge pivot 2.5e-8 of its
terms (the former bound ``sqrt(eps)`` = 1.5e-8 accepted it), plate block 3.2e-8, answer 5e-4 off the global
finite-element model."""

RESIDUAL_TOLERANCE = 1e-10
"""Largest accepted a-posteriori backward error of an answer of the sweep (:func:`backward_error`; the compiled kernel
of :mod:`ctmm.compiled_sweep` decides the same in C): the residual of the joint equations and modal rows at the
answer against the moduli of their terms.  It complements :data:`PIVOT_TOLERANCE`, which bounds each pivot alone:
the errors of eliminations compound along a path, and a pivot's ``1/r`` does not bound what its children's
cancellations left in its terms.  Measured (session 9): a 6-link chain whose hinge springs tune every sub-chain next
to a resonance at ``omega = 3`` (inner pivots ``r = 5e-4``, all accepted by the pivot test) answered 1.7e-3 off a
60-digit solve of the Lagrange model with backward error 8e-4; a 3-link one (``r = 5e-6``) 1e-6 off with 4e-7;
random chains of 30-60 links with stiffnesses over six decades at 4 000 frequencies stay below 4e-11 (the 100-link
pendulum of the benchmark below 3e-13). Above the bound the frequency goes to the dense resolvent like a small
pivot."""

CHUNK = 512
"""Frequencies swept at once (the batched terms of the sweep hold ``O(N CHUNK)`` numbers)."""


class ArticulatedResponse:
    """``G(s)`` of a tree's linearised terms by the batched sweep (module docstring).

    Subclasses call :meth:`prepare` and provide ``check(inputs, outputs)``, ``loads(name)`` (body load
    columns ``h`` (1, d + n_j, 1) and joint terms of one actuator at unit amplitude), ``rows(outputs)``
    (``(outputs, 2 n)``: ``[dy/dq, dy/dqdot]``) and ``amplitudes(solution)`` (``(B, n)`` coordinate amplitudes).
    """

    tree: Tree
    bodies: tuple
    joints: tuple

    coupling: Any = None
    compiled: CompiledSweep | None = None
    reads_joint_amplitudes = False
    """True when :meth:`point_amplitudes` reads the joints' relative amplitudes of the compiled kernel's answer."""

    def load_cases(self, names: list) -> list:
        """``loads(name)`` of every actuator in ``names`` (subclasses may form them at once)."""
        return [self.loads(name) for name in names]

    def point_amplitudes(self, answer: SweepAnswer) -> np.ndarray:
        """Coordinate amplitudes (L, B, n) from the compiled kernel's answer (``A_in`` (n, d, L, B) of every body,
        the joints' relative amplitudes (F, L, B)); subclasses that do not override it are answered by the generic
        sweep."""
        raise NotImplementedError

    def prepare(self, tree: Tree, bodies: Sequence[tuple], joints: Sequence[Any],
                coupling: Sequence[Any] | None = None) -> None:
        """Keep the linearised terms (``bodies``: ``(M0, C0, K0, Kin, RF)`` per body; ``joints``: held, the laws'
        torques zero; ``coupling``: the joints' preload coupling ``G_j`` of
        :func:`ctmm.articulated.articulated_inward`, ``None`` for none) and the pivots of their mass terms alone
        (the scale the pivots are measured by)."""
        self.tree, self.bodies, self.joints = tree, tuple(bodies), tuple(joints)
        self.coupling = None if coupling is None or all(g is None for g in coupling) else tuple(coupling)
        self.compiled = None
        reads_points = type(self).point_amplitudes is not ArticulatedResponse.point_amplitudes
        if reads_points and compiled_applies(tree, self.bodies, self.joints, self.coupling) and compiler_present():
            # rigid bodies, welds, held drives and free joints (ctmm.compiled_sweep.applies): its kernel
            try:
                self.compiled = CompiledSweep(tree, self.bodies, self.joints, self.coupling)
                return
            except ModelError as exc:               # a compiler that cannot build it: the generic sweep answers
                warnings.warn(f"the compiled frequency sweep is not available ({exc}); the generic numpy sweep "
                              "answers", RuntimeWarning, stacklevel=3)
        inertia = [BodyTerms(M0[None], np.zeros((1, M0.shape[0], 1)), Kin, dict.fromkeys(Kin), RF)   # c = None: zero
                   for M0, _, _, Kin, RF in self.bodies]
        with np.errstate(all="ignore"):
            masses = articulated_sweep(NUMPY, tree, inertia, self.joints, forces=False)
        self.mass_pivots, self.mass_modal = masses.pivot, masses.modal
        sizes: dict = {}
        for j, body in enumerate(self.bodies):
            sizes.setdefault(body[0].shape[0], []).append(j)
        # (members, M0, C0, K0) per body size, stacked (members, 1, size, size): Z of all of them in one operation
        self.stacks = [(members, *(np.stack([self.bodies[j][k] for j in members])[:, None] for k in range(3)))
                       for members in sizes.values()]
        self.moduli = [(members, np.abs(M0), np.abs(C0), np.abs(K0)) for members, M0, C0, K0 in self.stacks]
        self.undamped = not any(np.any(C0) for _, C0, _, _, _ in self.bodies) and not any(
            getattr(joint, "tau_v", None) is not None and np.any(joint.tau_v) for joint in self.joints)

    def response(self, s: np.ndarray, inputs: Sequence[str], outputs: Sequence[str]
                 ) -> tuple[np.ndarray, np.ndarray]:
        """``G[k, i_out, i_in]`` at the Laplace variables ``s`` (B,) and a mask (B,) of the frequencies it
        certifies (module docstring); entries at the others are not meaningful.

        Parameters
        ----------
        s : ndarray of complex, shape (B,)
            ``i omega`` [1/s].
        inputs : sequence of str
            Actuator names of the model's ports.
        outputs : sequence of str
            Sensor names of the model's ports.
        """
        self.check(inputs, outputs)
        s = np.asarray(s, dtype=complex).reshape(-1)
        rows = self.rows(list(outputs))
        loads = self.load_cases(list(inputs))
        G = np.zeros((s.size, len(outputs), len(inputs)), dtype=complex)
        good = np.zeros(s.size, dtype=bool)
        for start in range(0, s.size, CHUNK):       # the sweep's batched terms: O(N CHUNK) at a time
            part = slice(start, min(start + CHUNK, s.size))
            try:
                G[part], good[part] = self._batch(s[part], loads, rows)
                continue
            except np.linalg.LinAlgError:   # an exactly singular block at some s (a free base at omega = 0)
                pass
            for k in range(part.start, part.stop):
                try:
                    G[k:k + 1], good[k:k + 1] = self._batch(s[k:k + 1], loads, rows)
                except np.linalg.LinAlgError:
                    pass
        return G, good

    def _batch(self, s: np.ndarray, loads: list, rows: np.ndarray) -> tuple[np.ndarray, np.ndarray]:
        """:meth:`response` of the load cases ``loads`` and sensor ``rows`` at ``s`` (B,)."""
        if self.compiled is not None:
            return self._compiled(s, loads, rows)
        n = rows.shape[1] // 2
        column = s.reshape(-1, 1, 1)
        if self.undamped and not np.any(s.real):    # s^2 = -omega^2: the whole sweep is real (same numbers, faster)
            stiffness = self._dynamic_stiffness((column * column).real, None)
            moduli = self._dynamic_stiffness(np.abs(column * column), None, self.moduli)
            kappa = frequency_kappa(NUMPY, self.joints, 0.0)
        else:
            stiffness = self._dynamic_stiffness(column * column, column)
            moduli = self._dynamic_stiffness(np.abs(column * column), np.abs(column), self.moduli)
            kappa = frequency_kappa(NUMPY, self.joints, column)
        G = np.zeros((s.size, rows.shape[0], len(loads)), dtype=complex)
        good = np.ones(s.size, dtype=bool)
        for i, (body_loads, joints) in enumerate(loads):
            bodies = [BodyTerms(Z, h, Kin, dict.fromkeys(Kin), RF)           # c = None: zero
                      for Z, h, (_, _, _, Kin, RF) in zip(stiffness, body_loads, self.bodies)]
            with np.errstate(all="ignore"):
                solution = articulated_sweep(NUMPY, self.tree, bodies, joints, kappa, forces=False,
                                             coupling=self.coupling)
                amplitudes = self.amplitudes(solution)                           # (B, n)
                G[:, :, i] = amplitudes @ rows[:, :n].T + (s[:, None] * amplitudes) @ rows[:, n:].T
                backward = backward_error(self.tree, bodies, moduli, joints, kappa, self.coupling, solution)
            if i == 0:
                good &= self.pivots_certified(solution, s)
            good &= np.all(np.isfinite(G[:, :, i]), axis=1) & (backward <= RESIDUAL_TOLERANCE)
        return G, good

    def _compiled(self, s: np.ndarray, loads: list, rows: np.ndarray) -> tuple[np.ndarray, np.ndarray]:
        """:meth:`_batch` by the kernel of :mod:`ctmm.compiled_sweep` (every load case in one sweep, both
        certificates decided there)."""
        n, kernel = rows.shape[1] // 2, self.compiled
        h = np.zeros((len(self.bodies), self.tree.dimension, len(loads)))
        for i, (body_loads, _) in enumerate(loads):
            h[:, :, i] = np.stack([column[0, :, 0] for column in body_loads])
        tau = kernel.torques([joints for _, joints in loads])
        if not np.any(tau.imag):
            tau = tau.real
        solution = kernel.solve(s, h, tau, pivot_tolerance=PIVOT_TOLERANCE, residual_tolerance=RESIDUAL_TOLERANCE,
                                relative=self.reads_joint_amplitudes)
        with np.errstate(all="ignore"):
            amplitudes = self.point_amplitudes(solution)                   # (L, B, n)
            G = (amplitudes @ rows[:, :n].T + (s[:, None] * amplitudes) @ rows[:, n:].T).transpose(1, 2, 0)
        good = solution.good & np.all(np.isfinite(G), axis=(1, 2))
        return G.astype(complex, copy=False), good

    def _dynamic_stiffness(self, squared: np.ndarray, column: np.ndarray | None, stacks: list | None = None) -> list:
        """``Z_j = s^2 M0 + s C0 + K0`` (B, d + n_j, d + n_j) of every body (``column`` ``None``: no ``C0`` term),
        formed for all bodies of one size in one array operation (``stacks``: other ``M0, C0, K0``, e.g. their
        moduli)."""
        out: list = [None] * len(self.bodies)
        for members, M0, C0, K0 in self.stacks if stacks is None else stacks:
            Z = squared * M0 + K0 if column is None else squared * M0 + column * C0 + K0
            for position, j in enumerate(members):
                out[j] = Z[position]
        return out

    def pivots_certified(self, solution: Any, s: np.ndarray) -> np.ndarray:
        """(B,) True where every pivot ``P(s)`` (joint ``D_j``, modal ``C_j``) is at least :data:`PIVOT_TOLERANCE`
        of the terms it is made of: its smallest singular value against ``|s|^2 |P_M| + |P(s) - s^2 P_M|``
        (``P_M``: the same pivot of the mass terms alone, a positive articulated inertia; the second part the
        stiffness, damping and joint-law terms), largest moduli.  At a resonance of the model or of the
        substructure the pivot closes, ``s^2 P_M`` and the stiffness cancel, and the ratio falls."""
        good = np.ones(s.size, dtype=bool)
        squared = (s * s).reshape(-1, 1, 1)
        with np.errstate(all="ignore"):
            for pivot, mass in zip(solution.pivot + solution.modal, self.mass_pivots + self.mass_modal):
                if pivot is None:
                    continue
                inertia = squared * mass
                scale = np.abs(inertia).max(axis=(-2, -1)) + np.abs(pivot - inertia).max(axis=(-2, -1))
                good &= smallest_singular(pivot) >= PIVOT_TOLERANCE * scale
        return good


def backward_error(tree: Tree, bodies: Sequence[BodyTerms], moduli: Sequence[np.ndarray], joints: Sequence[Any],
                   kappa: Sequence[Any], coupling: Sequence[Any] | None, solution: Any) -> np.ndarray:
    """(B,) the largest relative residual of a numpy frequency-context sweep's answer: the a-posteriori
    certificate (:data:`RESIDUAL_TOLERANCE`; the compiled kernel of
    :mod:`ctmm.compiled_sweep` decides its twin in C).

    Tip to base, from the amplitudes alone (products and sums, no division), every body's generalised force
    ``Q_j = Z_j x_j + h_j + sum_children RF_c (F_c + H_c a_c)`` (``F_c`` the child's first ``d`` rows): its modal
    rows must vanish, and each free joint must satisfy ``S^T F_j + G_j A_O + kappa_j a_j = tau_j``.  Each
    residual is measured against the moduli of its terms (``moduli``: ``|s|^2 |M0| + |s| |C0| + |K0|`` per body,
    carried along the same sums).

    Parameters
    ----------
    tree : Tree
    bodies : sequence of BodyTerms
        The terms swept (``M`` holds ``Z_j(s)``, ``h`` the load).
    moduli : sequence of ndarray
        ``(B, d + n_j, d + n_j)`` per body.
    joints, kappa, coupling
        As swept (:func:`ctmm.articulated.articulated_sweep`).
    solution : Articulated
        Its result.
    """
    d, count = tree.dimension, len(bodies)
    coupling = list(coupling) if coupling is not None else [None] * count
    batch = max(np.shape(x)[0] for x in solution.x)
    worst = np.zeros(batch)
    wrench, size = [None] * count, [None] * count

    def ratio(residual: np.ndarray, scale: np.ndarray) -> np.ndarray:
        value = np.abs(residual) / np.where(scale > 0.0, scale, 1.0)
        return np.where(np.isfinite(value), value, np.inf).max(axis=(1, 2))

    for j in range(count - 1, -1, -1):
        x = solution.x[j]
        Q = bodies[j].M @ x + bodies[j].h
        S = moduli[j] @ np.abs(x) + np.abs(bodies[j].h)
        if wrench[j] is not None:
            Q, S = Q + wrench[j], S + size[j]
        Q, S = np.broadcast_to(Q, (batch,) + Q.shape[1:]), np.broadcast_to(S, (batch,) + S.shape[1:])
        if Q.shape[1] > d:                                          # the modal rows: no force reaches them
            worst = np.maximum(worst, ratio(Q[:, d:], S[:, d:]))
        F, bound = Q[:, :d], S[:, :d]
        joint, a, parent = joints[j], solution.relative[j], tree.parent[j]
        if a is not None and joint.prescribed is None and joint.free:
            St = np.swapaxes(joint.S, -1, -2)
            residual, scale = St @ F, np.abs(St) @ bound
            if kappa[j] is not None:
                residual, scale = residual + kappa[j] @ a, scale + np.abs(kappa[j]) @ np.abs(a)
            if joint.tau is not None:
                residual, scale = residual - joint.tau, scale + np.abs(joint.tau)
            G, H = coupling[j] if coupling[j] is not None else (None, None)
            if G is not None and parent >= 0:
                origin = bodies[parent].Kin[tree.point[j]] @ solution.x[parent]
                residual, scale = residual + G @ origin, scale + np.abs(G) @ np.abs(origin)
            if H is not None:
                F, bound = F + H @ a, bound + np.abs(H) @ np.abs(a)
            worst = np.maximum(worst, ratio(residual, scale))
        if parent >= 0:
            RF = bodies[parent].RF[tree.point[j]]
            moved, moved_size = RF @ F, np.abs(RF) @ bound
            wrench[parent] = moved if wrench[parent] is None else wrench[parent] + moved
            size[parent] = moved_size if size[parent] is None else size[parent] + moved_size
    return worst


def smallest_singular(blocks: np.ndarray) -> np.ndarray:
    """Smallest singular value of each block (B, k, k) (``|D|`` for 1 x 1)."""
    if blocks.shape[-1] == 1:
        return np.abs(blocks[..., 0, 0])
    values = np.linalg.svd(blocks, compute_uv=False)
    return np.where(np.all(np.isfinite(values), axis=-1), values[..., -1], 0.0)


def closed_loop_response(plant: ArticulatedResponse, loops: Sequence[Any], s: np.ndarray, inputs: Sequence[str],
                         outputs: Sequence[str]) -> tuple[np.ndarray, np.ndarray]:
    """``response[i_out, i_in, k]`` of the plant with ``loops`` closed at each ``s`` and the mask (B,) of the
    certified frequencies.  ``inputs``: actuators and ``"<loop>.reference"``; ``outputs``: sensors,
    ``"<loop>.y"`` and ``"<loop>.u"`` (of loops with and without delay).  Each loop
    ``u = -C(s) e^{-s tau} (y - r)`` is closed by ``(I + K G_yu) u = K (r - G_yw w)``,
    ``K = diag(C_l(s) e^{-s tau_l})`` (:func:`ctmm.loop_phasors.close_loops`); a loop matrix whose smallest
    singular value is below ``(1 + |K G_yu|_2) / RESOLVENT_CONDITION`` (a closed-loop pole at or next to ``s``)
    marks the frequency as not certified."""
    index = {lp.name: j for j, lp in enumerate(loops)}
    plain_in = [x for x in inputs if loop_signal(x, index, ("reference",)) is None]
    plain_out = [x for x in outputs if loop_signal(x, index, ("y", "u")) is None]
    actuators, sensors = loop_ports(loops)
    plant_in = list(dict.fromkeys(plain_in + actuators))
    plant_out = list(dict.fromkeys(plain_out + sensors))
    G, good = plant.response(s, plant_in, plant_out)
    # plant ports -> [plain inputs, one force per loop], [plain outputs, one sensed sum per loop]
    S_in = np.zeros((len(plant_in), len(plain_in) + len(loops)))
    S_out = np.zeros((len(plain_out) + len(loops), len(plant_out)))
    for k, name in enumerate(plain_in):
        S_in[plant_in.index(name), k] = 1.0
    for k, name in enumerate(plain_out):
        S_out[k, plant_out.index(name)] = 1.0
    for j, lp in enumerate(loops):
        for name, weight in lp.actuator_terms:
            S_in[plant_in.index(name), len(plain_in) + j] += weight
        for name, weight in lp.terms:
            S_out[len(plain_out) + j, plant_out.index(name)] += weight
    G = S_out @ G @ S_in
    n_i, n_o = len(plain_in), len(plain_out)
    blocks = (G[:, :n_o, :n_i], G[:, :n_o, n_i:], G[:, n_o:, :n_i], G[:, n_o:, n_i:])
    K = np.zeros((s.size, len(loops), len(loops)), dtype=complex)
    for j, loop in enumerate(loops):
        K[:, j, j] = controller_response(loop.gain, s) * np.exp(-s * loop.delay)
    if loops:                       # I + K G_yu against its terms: a closed-loop pole on the axis closes it
        with np.errstate(all="ignore"):
            loop = np.where(good[:, None, None], K @ blocks[3], 0.0)
            smallest = np.linalg.svd(np.eye(len(loops)) + loop, compute_uv=False)[:, -1]
            largest = np.linalg.svd(loop, compute_uv=False)[:, 0]
        good &= smallest * RESOLVENT_CONDITION >= 1.0 + largest
        blocks = tuple(np.where(good[:, None, None], b, 0.0) for b in blocks)
    return close_phasor_loops(blocks, K, inputs, outputs, plain_in, plain_out, index), good
