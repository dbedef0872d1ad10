"""The one articulated sweep on the terms of a rigid planar tree, evaluated fast at one state.

:class:`RigidTreeSweep` hands the per-body terms of a rigid tree whose joints are revolute, driven or a
free base at the ground -- ``K``, ``b`` and the parent-point data ``E`` of
:func:`ctmm.planar.sweep.body_terms`, the hinge torques and the joint tangents ``kappa`` -- to the one
recursion, :func:`ctmm.articulated.articulated_sweep` (``Tree``, ``BodyTerms``, ``JointTerms``; the
recursion is not restated here).  It serves the explicit accelerations of :mod:`ctmm.planar.sweep`
(``kappa = 0``) and the Newton tangent of :mod:`ctmm.planar.implicit` (``kappa = k beta' h^2 + c
gamma' h``, non-symmetric ``K``).  Body ``j`` (``docs/planar.md`` section 3):

* ``M = K_j`` (3 x 3, row-major in ``K``), ``h = b_j``;
* the point child ``c`` hangs on: ``Kin = [[1, 0, kx], [0, 1, ky], [0, 0, 1]]``,
  ``RF = [[1, 0, 0], [0, 1, 0], [lx, ly, 1]]``, ``c = (cx, cy, 0)`` from ``E_c = (kx, ky, lx, ly, cx, cy)``;
* joints: revolute ``S = e3`` (``axis = 2``), ``tau``, ``kappa``; driven ``S = e3`` with the prescribed
  relative acceleration; free base ``S = I3``, ``tau = 0``.

Two evaluations of that one sweep (the numbers agree to round-off, ``tests/test_forms_contract.py``):

* float terms: the sweep **traced once on casadi symbols** (:data:`ctmm.ops.CASADI`) into a casadi
  ``Function`` of ``(K, b, E, kappa, tau, alpha_driven)``, run by casadi's virtual machine through
  a buffer per thread (no compiler; about 0.1 us per call on top of the arithmetic).  numpy spends
  about 1 us per operation on 3 x 3 blocks, ~30 operations per body; the traced sweep runs the
  same arithmetic without that overhead (``docs/planar.md`` section 8a has the step times).  The
  trace costs about 1 ms per body (15 ms at N = 5, 0.8 s at N = 1000), once per tree structure: :func:`rigid_tree_sweep` keeps the
  sweeps of the last 64 structures (a memo of a function of the structure only; the numbers do not
  depend on what ran before);
* complex terms (and :meth:`RigidTreeSweep.numpy_sweep`): numpy on unbatched 2-D terms.

:meth:`RigidTreeSweep.batch` runs the sweep at one state for a batch of applied terms ``b``, ``tau`` (a kinematic
loop's cut loads and unit loads): the traced function mapped over the batch (casadi's serial map, each row the
numbers of one call), one evaluation for the whole batch.
"""
from __future__ import annotations

import functools
import threading
from typing import Any

import numpy as np

from ..articulated import Articulated, Tree, articulated_sweep
from ..errors import ModelError, SimulationError
from ..ops import CASADI, NUMPY, Ops
from ..protocol import BodyTerms, JointTerms
from .model import DRIVEN, FREE, REVOLUTE, PlanarModel

__all__ = ["RigidTreeSweep", "model_sweep", "rigid_tree_sweep"]

_E3 = np.array([[0.0], [0.0], [1.0]])
_I3 = np.eye(3)
_ZERO3 = np.zeros((3, 1))


class RigidTreeSweep:
    """The one articulated sweep of a rigid revolute, driven and free-base planar tree (module docstring).

    Parameters
    ----------
    parent : sequence of int
        Parent body of each body (-1: ground), in topological order.
    kind : sequence of int
        Joint kind of each body (:data:`ctmm.planar.model.REVOLUTE`, ``DRIVEN``, ``FREE`` at the ground).
    names : sequence of str, optional
        Joint names (for messages); default ``"hinge <index>"``.

    Raises
    ------
    ModelError
        A joint kind off this sweep (translational-spring hinges run
        :class:`ctmm.planar.body_forms.PlanarScene`) or a free joint that is not at the ground.
    """

    def __init__(self, parent: Any, kind: Any, names: Any = None) -> None:
        self.parent = [int(p) for p in parent]
        self.kind = [int(k) for k in kind]
        nb = len(self.parent)
        if len(self.kind) != nb:
            raise ModelError(f"RigidTreeSweep: kind has {len(self.kind)} entries, parent {nb}; give one per body")
        self.names = list(names) if names is not None else [f"hinge {j}" for j in range(nb)]
        for j, (p, k) in enumerate(zip(self.parent, self.kind)):
            if k not in (REVOLUTE, DRIVEN, FREE) or (k == FREE and p >= 0):
                raise ModelError(f"RigidTreeSweep: joint {self.names[j]!r} has kind {k}; allowed: revolute ({REVOLUTE}), "
                                 f"driven ({DRIVEN}) and a free base at the ground ({FREE})")
        self.tree = Tree(tuple(self.parent), tuple(None if p < 0 else j for j, p in enumerate(self.parent)), 3)
        self.children = [[c for c in range(nb) if self.parent[c] == j] for j in range(nb)]
        self._function: Any = None
        self._local = threading.local()

    # -- the terms (one statement for both evaluations) -------------------------------------
    def terms(self, ops: Ops, M: list, h: list, Kin: list, RF: list, c: list, tau: list, kappa: list,
              driven: list, S: Any, free_S: Any, zero: Any) -> tuple[list, list, list]:
        """``BodyTerms``, ``JointTerms`` and joint tangents of the tree from per-body ops matrices.

        ``M[j]`` (3 x 3), ``h[j]`` (3 x 1); ``Kin[j]``, ``RF[j]``, ``c[j]``: the parent point body ``j``
        hangs on (unused at the ground); ``tau[j]``, ``kappa[j]``, ``driven[j]``: 1 x 1; ``S``, ``free_S``,
        ``zero``: the revolute column, the free base's ``I3`` and its ``tau = 0`` in ``ops``.
        """
        bodies = [BodyTerms(M[j], h[j], {k: Kin[k] for k in self.children[j]}, {k: c[k] for k in self.children[j]},
                            {k: RF[k] for k in self.children[j]}) for j in range(len(self.parent))]
        joints, tangents = [], []
        for j, kind in enumerate(self.kind):
            if kind == REVOLUTE:
                joints.append(JointTerms(S=S, tau=tau[j], axis=2))
                tangents.append(kappa[j])
            elif kind == DRIVEN:
                joints.append(JointTerms(S=S, prescribed=driven[j], axis=2))
                tangents.append(None)
            else:
                joints.append(JointTerms(S=free_S, tau=zero))
                tangents.append(None)
        return bodies, joints, tangents

    # -- evaluation --------------------------------------------------------------------------
    def __call__(self, K: Any, b: Any, E: Any, kappa: Any, tau: Any, alpha_driven: Any
                 ) -> tuple[np.ndarray, np.ndarray, np.ndarray]:
        """One sweep at one state.

        Parameters
        ----------
        K : array_like, shape (n_bodies, 9)
            Inertia about the inboard point, row-major 3 x 3 [kg, kg m, kg m^2].
        b : array_like, shape (n_bodies, 3)
            Velocity, gravity and load terms [N, N m].
        E : array_like, shape (n_bodies, 6)
            ``(kx, ky, lx, ly, cx, cy)`` of the parent point carrying each body.
        kappa : array_like, shape (n_bodies,)
            Joint tangent of revolute joints [N m s^2/rad] (0: explicit).
        tau : array_like, shape (n_bodies,)
            Torque of revolute joints [N m].
        alpha_driven : array_like, shape (n_bodies,)
            Prescribed relative angular acceleration of driven joints [rad/s^2].

        Returns
        -------
        A, F : ndarray, shape (n_bodies, 3)
            Body accelerations at the inboard ends [m/s^2, rad/s^2] and joint forces [N, N m].
        alpha : ndarray, shape (n_bodies,)
            Relative hinge accelerations [rad/s^2] (free base: its angular acceleration).

        Raises
        ------
        SimulationError
            A singular articulated inertia (non-finite accelerations), naming the first such joint.
        """
        arrays = [np.asarray(x) for x in (K, b, E, kappa, tau, alpha_driven)]
        if "c" in [x.dtype.kind for x in arrays]:
            with np.errstate(all="ignore"):
                A, F, alpha, pivots = self._numpy(*arrays)
        else:
            A, F, alpha, pivots = self._run_traced(arrays)
        self._check_finite(A, pivots)
        return A, F, alpha

    def batch(self, K: Any, b: Any, E: Any, kappa: Any, tau: Any, alpha_driven: Any
              ) -> tuple[np.ndarray, np.ndarray, np.ndarray]:
        """:meth:`__call__` at one state for a batch of applied terms: ``b`` (n_batch, n_bodies, 3) and ``tau``
        (n_batch, n_bodies) (e.g. a kinematic loop's loads and its unit loads), the other arguments as
        :meth:`__call__`; returns ``A``, ``F`` (n_batch, n_bodies, 3) and ``alpha`` (n_batch, n_bodies), each row the
        numbers of :meth:`__call__` with that row's ``b`` and ``tau`` (float terms: the traced sweep mapped over the
        rows in one call; complex terms: one numpy sweep per row).

        Raises
        ------
        SimulationError
            As :meth:`__call__`, at the first row with non-finite accelerations.
        """
        b, tau = np.asarray(b), np.asarray(tau)
        arrays = [np.asarray(x) for x in (K, E, kappa, alpha_driven)]
        if "c" in [x.dtype.kind for x in arrays + [b, tau]]:
            with np.errstate(all="ignore"):
                rows = [self._numpy(arrays[0], b_k, arrays[1], arrays[2], tau_k, arrays[3]) for b_k, tau_k in zip(b, tau)]
            A, F, alpha, pivots = (np.array([row[k] for row in rows]) for k in range(4))
        else:
            A, F, alpha, pivots = self._run_traced_batch(arrays, b, tau)
        for A_k, pivots_k in zip(A, pivots):
            self._check_finite(A_k, pivots_k)
        return A, F, alpha

    def _check_finite(self, A: np.ndarray, pivots: np.ndarray) -> None:
        """:class:`SimulationError` naming the singular joint unless the accelerations ``A`` are finite."""
        if not np.isfinite(A).all():
            # the first singular pivot of the tip-to-base pass (the bodies below it inherit non-finite terms)
            singular = [j for j in range(len(self.parent)) if not (np.isfinite(pivots[j]) and pivots[j] != 0)]
            bad = singular[-1] if singular else next(j for j in range(len(A)) if not np.isfinite(A[j]).all())
            raise SimulationError(f"articulated inertia of joint {self.names[bad]!r} is singular (pivot "
                                  f"{pivots[bad]!r}, non-finite accelerations in the articulated sweep)",
                                  element=self.names[bad])

    def numpy_sweep(self, K: np.ndarray, b: np.ndarray, E: np.ndarray, kappa: np.ndarray, tau: np.ndarray,
                    alpha_driven: np.ndarray) -> tuple[np.ndarray, np.ndarray, np.ndarray]:
        """The sweep on numpy, unbatched 2-D terms (the arguments and results of :meth:`__call__`; no finiteness
        check)."""
        with np.errstate(all="ignore"):
            return self._numpy(K, b, E, kappa, tau, alpha_driven)[:3]

    def _numpy(self, K: np.ndarray, b: np.ndarray, E: np.ndarray, kappa: np.ndarray, tau: np.ndarray,
               alpha_driven: np.ndarray) -> tuple[np.ndarray, np.ndarray, np.ndarray, np.ndarray]:
        """:meth:`numpy_sweep` and the revolute pivots ``D`` (1 for other joints)."""
        nb = len(self.parent)
        dtype = np.result_type(K, b, E, kappa, tau, alpha_driven, float)
        E = np.asarray(E, dtype=dtype).reshape(nb, 6)
        Kin = np.zeros((nb, 3, 3), dtype=dtype)
        Kin[:, 0, 0] = Kin[:, 1, 1] = Kin[:, 2, 2] = 1.0
        RF = Kin.copy()
        Kin[:, 0, 2], Kin[:, 1, 2] = E[:, 0], E[:, 1]
        RF[:, 2, 0], RF[:, 2, 1] = E[:, 2], E[:, 3]
        c = np.zeros((nb, 3, 1), dtype=dtype)
        c[:, 0, 0], c[:, 1, 0] = E[:, 4], E[:, 5]
        column = [np.asarray(x, dtype=dtype).reshape(nb, 1, 1) for x in (tau, kappa, alpha_driven)]
        bodies, joints, tangents = self.terms(
            NUMPY, list(np.asarray(K, dtype=dtype).reshape(nb, 3, 3)), list(np.asarray(b, dtype=dtype).reshape(nb, 3, 1)),
            list(Kin), list(RF), list(c), *(list(x) for x in column), _E3, _I3, _ZERO3)
        return self._unpack(articulated_sweep(NUMPY, self.tree, bodies, joints, tangents),
                            lambda m: np.asarray(m, dtype=dtype)[..., 0].reshape(-1))

    def _unpack(self, out: Articulated, vector: Any) -> tuple[Any, Any, Any, Any]:
        """``A``, ``F`` (n_bodies, 3), ``alpha`` and the revolute pivots from the sweep's result (``vector``: a
        column as 1-D)."""
        A = np.array([vector(x) for x in out.x])
        F = np.array([vector(f) for f in out.force])
        alpha = np.array([vector(r)[2] if k == FREE else vector(r)[0] for r, k in zip(out.relative, self.kind)])
        pivots = np.array([vector(d)[0] if k == REVOLUTE else 1.0 for d, k in zip(out.pivot, self.kind)])
        return A, F, alpha, pivots

    def traced(self) -> Any:
        """The sweep traced on casadi symbols: ``Function(z) -> w`` with ``z = [K; b; E; kappa; tau; alpha_driven]``
        (21 values per body, each block in numpy's row-major order of the arguments of :meth:`__call__`) and
        ``w = [A; F; alpha; D]`` (8 per body, likewise; ``D`` the revolute pivots, 1 for other joints)."""
        import casadi as ca

        nb = len(self.parent)
        z = ca.SX.sym("z", 21 * nb)
        offsets = np.cumsum([0, 9 * nb, 3 * nb, 6 * nb, nb, nb, nb])
        K, b, E, kappa, tau, driven = (ca.reshape(z[int(offsets[k]):int(offsets[k + 1])], size, nb)
                                       for k, size in enumerate((9, 3, 6, 1, 1, 1)))
        block = CASADI.block
        Kin = [block([[1.0, 0.0, E[0, j]], [0.0, 1.0, E[1, j]], [0.0, 0.0, 1.0]]) for j in range(nb)]
        RF = [block([[1.0, 0.0, 0.0], [0.0, 1.0, 0.0], [E[2, j], E[3, j], 1.0]]) for j in range(nb)]
        c = [block([[E[4, j]], [E[5, j]], [0.0]]) for j in range(nb)]
        bodies, joints, tangents = self.terms(
            CASADI, [ca.reshape(K[:, j], 3, 3).T for j in range(nb)], [b[:, j] for j in range(nb)], Kin, RF, c,
            [tau[0, j] for j in range(nb)], [kappa[0, j] for j in range(nb)], [driven[0, j] for j in range(nb)],
            ca.SX(_E3), ca.SX(_I3), ca.SX(_ZERO3))
        out = articulated_sweep(CASADI, self.tree, bodies, joints, tangents)
        alpha = [r[2] if k == FREE else r[0] for r, k in zip(out.relative, self.kind)]
        pivots = [d if k == REVOLUTE else 1.0 for d, k in zip(out.pivot, self.kind)]
        return ca.Function("rigid_tree_sweep", [z], [ca.vertcat(*out.x, *out.force, *alpha, *pivots)])

    def _run_traced(self, arrays: list) -> tuple[np.ndarray, np.ndarray, np.ndarray, np.ndarray]:
        """Evaluate :meth:`traced` through this thread's buffer (float arguments as :meth:`__call__`; results as
        :meth:`_numpy`)."""
        nb = len(self.parent)
        self._check_sizes([x.size for x in arrays])
        z = np.concatenate(arrays, axis=None, dtype=float)      # each flattened in row-major order
        w = self._evaluate(z, 1)
        return w[:3 * nb].reshape(nb, 3), w[3 * nb:6 * nb].reshape(nb, 3), w[6 * nb:7 * nb], w[7 * nb:]

    def _run_traced_batch(self, arrays: list, b: np.ndarray, tau: np.ndarray
                          ) -> tuple[np.ndarray, np.ndarray, np.ndarray, np.ndarray]:
        """:meth:`_run_traced` for each row of ``b`` and ``tau`` (``arrays``: ``K``, ``E``, ``kappa``,
        ``alpha_driven``), one evaluation of the traced sweep mapped over the rows; results with a leading batch
        axis."""
        nb, count = len(self.parent), len(b)
        K, E, kappa, driven = arrays
        self._check_sizes([K.size, b[0].size if count else 3 * nb, E.size, kappa.size,
                           tau[0].size if count else nb, driven.size])
        z = np.empty((count, 21 * nb))                          # row k: the z of row k (its b and tau)
        z[:, :9 * nb] = K.reshape(-1)
        z[:, 9 * nb:12 * nb] = b.reshape(count, 3 * nb)
        z[:, 12 * nb:18 * nb] = E.reshape(-1)
        z[:, 18 * nb:19 * nb] = kappa.reshape(-1)
        z[:, 19 * nb:20 * nb] = tau.reshape(count, nb)
        z[:, 20 * nb:] = driven.reshape(-1)
        w = self._evaluate(z.reshape(-1), count).reshape(count, 8 * nb)
        return (w[:, :3 * nb].reshape(count, nb, 3), w[:, 3 * nb:6 * nb].reshape(count, nb, 3), w[:, 6 * nb:7 * nb],
                w[:, 7 * nb:])

    def _check_sizes(self, sizes: list) -> None:
        """:class:`ModelError` unless the arguments of one sweep have 9, 3, 6, 1, 1 and 1 values per body."""
        nb = len(self.parent)
        if sizes != [9 * nb, 3 * nb, 6 * nb, nb, nb, nb]:
            raise ModelError(f"RigidTreeSweep: the arguments K, b, E, kappa, tau, alpha_driven have {sizes} values; "
                             f"{nb} bodies need 9, 3, 6, 1, 1 and 1 per body")

    def _evaluate(self, z: np.ndarray, count: int) -> np.ndarray:
        """The traced sweep on ``count`` stacked inputs ``z`` (``count`` blocks of 21 values per body): the
        stacked outputs (8 per body each), through this thread's buffer of the sweep mapped over ``count``
        columns (casadi's serial map: the one traced function on each column, column-major = the blocks)."""
        if self._function is None:
            self._function = self.traced()
        buffers = getattr(self._local, "buffers", None)
        if buffers is None:
            buffers = self._local.buffers = {}
        buffer = buffers.get(count)
        if buffer is None:
            buffer = buffers[count] = (self._function if count == 1 else self._function.map(count)).buffer()
        memory, run = buffer
        w = np.empty(8 * len(self.parent) * count)
        memory.set_arg(0, memoryview(z))
        memory.set_res(0, memoryview(w))
        run()                                   # z and w are alive: the buffer holds their addresses only
        return w


@functools.lru_cache(maxsize=64)
def rigid_tree_sweep(parent: tuple, kind: tuple, names: tuple) -> RigidTreeSweep:
    """The :class:`RigidTreeSweep` of a tree structure (``parent``, ``kind``, joint ``names`` as tuples), kept for
    the last 64 structures so that the traced sweep is built once per structure."""
    return RigidTreeSweep(parent, kind, names)


def model_sweep(model: PlanarModel) -> RigidTreeSweep:
    """:func:`rigid_tree_sweep` of a rigid revolute, driven and free-base :class:`PlanarModel`."""
    return rigid_tree_sweep(tuple(model.parent.tolist()), tuple(model.joint_kind.tolist()), tuple(model.joint_names))
