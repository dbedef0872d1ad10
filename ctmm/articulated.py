"""The one articulated (Riccati) sweep over :class:`~ctmm.protocol.BodyTerms` for trees.

One recursion, three evaluation contexts (``docs/plans/one_core.md`` §1.10, §2.3; derivation in
``docs/planar.md``, "The one articulated sweep"):

* **explicit** accelerations: ``kappa = 0`` (:func:`explicit_kappa`);
* **implicit** Newton tangent: the integrator's ``kappa = -(tau_q cx + tau_v A)`` and
  tangent-modified terms (today ``planar/implicit.py``: ``kappa = k beta' h^2 + c gamma' h``);
* **frequency**: terms linearised about a static operating point, ``M -> Z(s) = s^2 M0 + s C0 + K0``,
  ``kappa(s) = -(tau_q + s tau_v)``, batched over ``s`` (:func:`frequency_kappa`); the pivots give
  the characteristic function ``prod det D_j prod det C_j`` (:attr:`Articulated.characteristic`).

Tip to base, for each body ``j`` (children already folded into ``M_j, h_j``): modal elimination
``W = C^-1 [M_er, h_e]``, ``Phi = M_rr - M_re W_A``, ``psi = h_r - M_re W_h`` (``C = M_ee``);
joint ``D = S^T Phi S + kappa``, ``Phi_hat = Phi - Phi S D^-1 S^T Phi``,
``psi_hat = psi' + Phi S D^-1 (tau - S^T psi')`` with ``psi' = psi + Phi c_joint`` (driven:
``psi_hat = psi' + Phi S a_rel``; weld ``k = 0``: ``psi_hat = psi'``), moved to the parent point
``e``: ``M_p += RF_e Phi_hat Kin_e``, ``h_p += RF_e (Phi_hat c_e + psi_hat)``.  Base to tip:
``A_O = Kin_e x_p + c_e`` (ground: 0), ``a_rel = D^-1 (tau - S^T (Phi A_O + psi'))``,
``A = A_O + S a_rel + c_joint``, ``eta'' = -(W_A A + W_h)``, ``F = Phi A + psi``.

Written in :mod:`ctmm.ops` only, so it runs batched on numpy (float, complex) and on casadi symbols; on numpy a
product of a constant matrix (``B = 1``: the points' ``Kin``, ``RF`` of the frequency context) and a batch is one 2-D
product.  A point's ``c`` may be ``None`` (zero: the frequency context).
"""
from __future__ import annotations

from dataclasses import dataclass
from typing import Any, Sequence

import numpy as np

from .errors import ModelError
from .ops import Ops
from .protocol import BodyTerms, JointTerms

__all__ = ["Tree", "Articulated", "Inward", "SingularPivotError", "articulated_bias", "articulated_inward",
           "articulated_outward", "articulated_sweep", "explicit_kappa", "frequency_kappa"]


class SingularPivotError(np.linalg.LinAlgError):
    """An exactly singular pivot of the numpy sweep: the ``free x free`` block ``D_j`` of a joint with more
    than one free direction, or the modal block ``C_j`` of a flexible body (a ``LinAlgError``: handlers of
    singular sweeps keep working).

    Parameters
    ----------
    message : str
        What was singular.
    body : int
        Index of the body in the tree (its inboard joint has the same index).
    """

    def __init__(self, message: str, body: int) -> None:
        super().__init__(message)
        self.body = body


def _solve(ops: Ops, a: Any, b: Any, body: int, what: str) -> Any:
    """``ops.solve(a, b)``; numpy's ``LinAlgError`` becomes :class:`SingularPivotError` naming the body."""
    try:
        return _one_solve(ops, a, b)
    except np.linalg.LinAlgError as exc:
        raise SingularPivotError(f"singular {what} of body {body}: {exc}", body) from exc


def _one_solve(ops: Ops, a: Any, b: Any) -> Any:
    """``ops.solve(a, b)``; on numpy one system ``(1, k, k)``, ``(1, k, m)`` (the single-state sweeps) is solved
    as the 2-D system ``a[0]``, ``b[0]`` (the same LAPACK ``gesv`` without the batched set-up, :class:`NumpyOps`)."""
    if type(a) is np.ndarray and type(b) is np.ndarray and a.ndim == 3 == b.ndim and a.shape[0] == 1 == b.shape[0]:
        return ops.solve(a[0], b[0])[None]
    return ops.solve(a, b)


def _product(ops: Ops, a: Any, b: Any) -> Any:
    """``ops.matmul(a, b)``; on numpy a constant factor (``B = 1``) times a batch is one 2-D product (numpy's
    batched product of small matrices costs a BLAS call per matrix)."""
    if type(a) is np.ndarray and type(b) is np.ndarray:
        if a.ndim == 3 == b.ndim:
            if a.shape[0] == 1 < b.shape[0]:            # (b^T a^T)^T
                batch, inner, columns = b.shape
                flat = b.swapaxes(1, 2).reshape(batch * columns, inner)
                return (flat @ a[0].T).reshape(batch, columns, -1).swapaxes(1, 2)
            if b.shape[0] == 1 < a.shape[0]:
                batch, rows, inner = a.shape
                return (a.reshape(batch * rows, inner) @ b[0]).reshape(batch, rows, -1)
        return a @ b                                    # np.matmul without the ops dispatch
    return ops.matmul(a, b)


def _congruence(ops: Ops, left: Any, middle: Any, right: Any) -> Any:
    """``left middle right``; on numpy with constant ``left, right`` (``B = 1``) and a batched ``middle`` one 2-D
    product of the flattened ``middle`` with ``kron(left^T, right)``."""
    if type(middle) is np.ndarray and type(left) is np.ndarray and type(right) is np.ndarray:
        if middle.ndim == 3 and left.shape[0] == 1 == right.shape[0] < middle.shape[0]:
            rows, inner = left.shape[1:]
            columns = right.shape[2]
            kron = left[0].T[:, None, :, None] * right[0][None, :, None, :]     # kron(left^T, right)
            kron = kron.reshape(inner * right.shape[1], rows * columns)
            return (middle.reshape(middle.shape[0], -1) @ kron).reshape(-1, rows, columns)
        if left.shape[:-2] == middle.shape[:-2] == right.shape[:-2]:    # one batch (or 2-D): two plain products
            return left @ middle @ right
    return _product(ops, _product(ops, left, middle), right)


@dataclass(frozen=True)
class Tree:
    """Topology of a tree of bodies in topological order (every parent before its children).

    Attributes
    ----------
    parent : tuple of int
        Parent body of each body's inboard joint, ``-1`` for the ground.
    point : tuple of str or None
        Name of the parent's point each body hangs on (``None`` at the ground).
    dimension : int
        Point state dimension ``d`` (planar 3, spatial 6).
    """

    parent: tuple[int, ...]
    point: tuple[str | None, ...]
    dimension: int = 3

    def __post_init__(self) -> None:
        if len(self.parent) != len(self.point):
            raise ModelError(f"Tree: parent ({len(self.parent)}) and point ({len(self.point)}) must have one "
                             "entry per body")
        for j, p in enumerate(self.parent):
            if not -1 <= p < j:
                raise ModelError(f"Tree: parent[{j}] = {p} is not -1 (ground) or an earlier body; bodies must be "
                                 "in topological order")


@dataclass(frozen=True)
class Articulated:
    """Result of one sweep (per body ``j``, ops matrices).

    Attributes
    ----------
    x : list
        ``[A_in ; eta'']`` (d + n_j, 1).
    force : list
        ``F_in`` (d, 1): wrench of the parent (or ground) on the body at its inboard point.
    relative : list
        ``a_rel`` (k_j, 1) of the inboard joint (``None`` for a weld).
    pivot : list
        ``D_j`` (k_j, k_j) of free joints (``None`` otherwise).
    modal : list
        ``C_j`` (n_j, n_j) of bodies with internal coordinates (``None`` otherwise).
    characteristic : matrix (1, 1) or None
        ``prod det D_j * prod det C_j`` (the frequency context's characteristic function), when
        asked for.
    inertia : list or None
        ``Phi_j`` (d, d): the articulated inertia at each inboard point before the joint is
        eliminated, ``D_j = S^T Phi_j S + kappa_j`` (the terms of a pivot, for its relative size).
    """

    x: list
    force: list
    relative: list
    pivot: list
    modal: list
    characteristic: Any = None
    inertia: Any = None


def explicit_kappa(joints: Sequence[JointTerms]) -> list:
    """``kappa = 0`` for every joint (explicit accelerations)."""
    return [None] * len(joints)


def frequency_kappa(ops: Ops, joints: Sequence[JointTerms], s: Any) -> list:
    """``kappa(s) = -(tau_q + s tau_v)`` of the joint laws (connector ``k + c s``)."""
    out = []
    for joint in joints:
        if joint.tau is None or joint.free == 0:
            out.append(None)
            continue
        k = joint.free
        tq = joint.tau_q if joint.tau_q is not None else ops.zeros(k, k)
        tv = joint.tau_v if joint.tau_v is not None else ops.zeros(k, k)
        out.append((tq + s * tv) * -1.0)
    return out


@dataclass(frozen=True)
class Inward:
    """Result of the tip-to-base elimination (:func:`articulated_inward`), per body ``j`` (ops matrices,
    ``None`` where the body or joint has none); all the base-to-tip pass (:func:`articulated_outward`)
    needs besides the body and joint terms.

    Attributes
    ----------
    inertia : list
        ``Phi_j`` (d, d): articulated inertia at the inboard point before the joint is eliminated.
    bias : list
        ``psi'_j`` (d, 1): articulated bias at the inboard point (with ``Phi_j c_joint``).
    transposed : list
        ``S^T Phi_j`` (one unit axis) or ``S^T`` (k, d) of free joints.
    pivot : list
        ``D_j`` (k, k) of free joints.
    modal : list
        ``C_j`` (n_j, n_j) of bodies with internal coordinates.
    modal_inertia, modal_bias : list
        ``W_A`` (n_j, d) and ``W_h`` (n_j, 1) of bodies with internal coordinates.
    """

    inertia: list
    bias: list
    transposed: list
    pivot: list
    modal: list
    modal_inertia: list
    modal_bias: list


def articulated_sweep(ops: Ops, tree: Tree, bodies: Sequence[BodyTerms], joints: Sequence[JointTerms],
                      kappa: Sequence[Any] | None = None, *, characteristic: bool = False,
                      forces: bool = True, coupling: Sequence[Any] | None = None) -> Articulated:
    """Tip-to-base elimination and base-to-tip pass (module docstring): :func:`articulated_outward` of
    :func:`articulated_inward`.

    Parameters
    ----------
    ops : Ops
    tree : Tree
    bodies : sequence of BodyTerms
        One per body, in the tree's order.
    joints : sequence of JointTerms
        The inboard joint of each body.
    kappa : sequence, optional
        Joint tangent ``(k, k)`` per joint (``None`` entries: 0); default explicit.
    characteristic : bool
        Also form ``prod det D_j prod det C_j``.
    forces : bool
        Also form the joint wrenches (:func:`articulated_outward`).
    coupling : sequence, optional
        Joint coupling ``(G_j, H_j)`` per joint, ``G_j`` ``(k, d)``, ``H_j`` ``(d, k)`` or ``None`` (``None``
        entries and default: none): the joint equation gains ``G_j A_O`` and the wrench handed to the parent
        ``H_j a_rel`` (the frequency context about a preloaded equilibrium, :func:`articulated_inward`).

    Returns
    -------
    Articulated
        Singular pivots are not detected here (no branching on values): numpy callers check the
        result for finiteness; an exactly singular multi-direction pivot (numpy) raises
        :class:`SingularPivotError` naming the body.
    """
    inward = articulated_inward(ops, tree, bodies, joints, kappa, coupling)
    return articulated_outward(ops, tree, bodies, joints, inward, characteristic=characteristic, forces=forces,
                               coupling=coupling)


def articulated_inward(ops: Ops, tree: Tree, bodies: Sequence[BodyTerms], joints: Sequence[JointTerms],
                       kappa: Sequence[Any] | None = None, coupling: Sequence[Any] | None = None) -> Inward:
    """Tip-to-base elimination (module docstring): the articulated terms of every body.

    Parameters are those of :func:`articulated_sweep`.

    **Joint coupling** (``coupling``; the frequency context about a preloaded equilibrium).  The joint equation
    ``S^T F = tau`` linearised about a static wrench ``F0`` across the joint is
    ``S0^T dF + dS^T F0 = d tau``; when the joint's free directions turn with its parent (world axes), ``dS``
    holds a term in the parent point's rotation, ``dS^T F0 = G A_O`` with ``G`` ``(k, d)`` acting on the parent
    point's displacement ``A_O`` (terms in the joint's own coordinates belong in ``kappa``).  And when the
    joint moves the child's reference point (the material point at the parent's point ``P`` at the operating
    point) by ``u a`` relative to ``P``, the wrench reaches the parent at ``P`` as ``F + H a`` with
    ``H = [0 ; u_i x f0]`` (the static force's moment about the shifted point).  With both
    ``S^T (Phi (A_O + S a) + psi') + G A_O + kappa a = tau``, so ``D`` is unchanged,
    ``a = D^-1 (tau - S^T psi' - (S^T Phi + G) A_O)``, and the parent receives
    ``Phi_hat = Phi - (Phi S + H) D^-1 (S^T Phi + G)`` (not symmetric) and
    ``psi_hat = psi' + (Phi S + H) D^-1 (tau - S^T psi')``.  A joint on the ground has no coupling.  At the ground only the pivot is formed: the
    prescribed relative acceleration of a driven joint on the ground is read by the outward pass only
    (:mod:`ctmm.segment_fold` eliminates with a weld there and prescribes in the outward pass).

    Raises
    ------
    ModelError
        Sizes that do not match the tree.
    SingularPivotError
        An exactly singular multi-direction pivot or modal block (numpy).
    """
    nb = len(tree.parent)
    if len(bodies) != nb or len(joints) != nb:
        raise ModelError(f"articulated_sweep: {nb} bodies in the tree, got {len(bodies)} body terms and "
                         f"{len(joints)} joint terms")
    kappa = list(kappa) if kappa is not None else explicit_kappa(joints)
    coupling = [(None, None) if c is None else c for c in coupling] if coupling is not None else [(None, None)] * nb
    d = tree.dimension
    M = [b.M for b in bodies]
    h = [b.h for b in bodies]
    Phi, psi, WA, Wh, D, C = [None] * nb, [None] * nb, [None] * nb, [None] * nb, [None] * nb, [None] * nb
    St = [None] * nb                                # S^T of the free joints
    rd = slice(0, d)
    for j in range(nb - 1, -1, -1):
        Mj, hj = M[j], h[j]
        size = ops.shape(Mj)[0]
        if size > d:
            rest = slice(d, size)
            C[j] = ops.sub(Mj, rest, rest)
            Mre = ops.sub(Mj, rd, rest)
            W = _solve(ops, C[j], ops.block([[ops.sub(Mj, rest, rd), ops.sub(hj, rest, slice(0, 1))]]), j,
                       "modal mass block")
            WA[j], Wh[j] = ops.sub(W, slice(0, size - d), rd), ops.sub(W, slice(0, size - d), slice(d, d + 1))
            MW = ops.matmul(Mre, W)                 # [M_re W_A, M_re W_h] in one product
            P = ops.sub(Mj, rd, rd) - ops.sub(MW, rd, rd)
            p = ops.sub(hj, rd, slice(0, 1)) - ops.sub(MW, rd, slice(d, d + 1))
        else:
            P, p = Mj, hj
        joint = joints[j]
        if joint.c is not None:
            p = p + ops.matmul(P, joint.c)
        Phi[j], psi[j] = P, p
        par = tree.parent[j]
        axis = joint.axis                           # S = column `axis` of the identity: index, no products
        if par < 0:                                 # at the ground only the pivot is needed
            if joint.prescribed is None and joint.free:
                if axis is not None:
                    St[j] = ops.sub(P, slice(axis, axis + 1), rd)       # S^T Phi
                    D[j] = ops.sub(P, slice(axis, axis + 1), slice(axis, axis + 1))
                else:
                    St[j] = ops.transpose(joint.S)
                    D[j] = ops.matmul(ops.matmul(St[j], P), joint.S)
                if kappa[j] is not None:
                    D[j] = D[j] + kappa[j]
            continue
        if joint.prescribed is not None:
            P_hat, p_hat = P, _prescribed_bias(ops, joint, P, p, rd)
        elif joint.free == 0:
            P_hat, p_hat = P, p
        elif axis is not None:                      # one unit free direction: rows, columns and a division
            row = slice(axis, axis + 1)
            StP = St[j] = ops.sub(P, row, rd)
            PS = ops.sub(P, rd, row)
            Dj = ops.sub(P, row, row)
            if kappa[j] is not None:
                Dj = Dj + kappa[j]
            D[j] = Dj
            rhs = _joint_load(joint, ops.sub(p, row, slice(0, 1)))
            G, H = coupling[j]
            if G is not None:                       # the outward pass reads S^T Phi + G as its row
                StP = St[j] = StP + G
            if H is not None:
                PS = PS + H
            P_hat = P - ops.matmul(PS, StP / Dj)
            p_hat = _free_bias(ops, joint, p, PS, Dj, rhs)
        else:
            St[j] = ops.transpose(joint.S)
            PS = ops.matmul(P, joint.S)
            StP = ops.matmul(St[j], P)
            Dj = ops.matmul(StP, joint.S)
            if kappa[j] is not None:
                Dj = Dj + kappa[j]
            D[j] = Dj
            rhs = _joint_load(joint, ops.matmul(St[j], p))
            G, H = coupling[j]
            if G is not None:
                StP = StP + G
            if H is not None:
                PS = PS + H
            if joint.free == 1:                     # one free direction: D is 1 x 1, divide
                P_hat = P - ops.matmul(PS, StP / Dj)
            else:
                P_hat = P - ops.matmul(PS, _solve(ops, Dj, StP, j, "joint pivot"))
            p_hat = _free_bias(ops, joint, p, PS, Dj, rhs)
        e = tree.point[j]
        parent = bodies[par]
        RF = parent.RF[e]
        M[par] = M[par] + _congruence(ops, RF, P_hat, parent.Kin[e])
        if parent.c[e] is not None:                 # None: c_e = 0 (the frequency context)
            p_hat = ops.matmul(P_hat, parent.c[e]) + p_hat
        h[par] = h[par] + _product(ops, RF, p_hat)
    return Inward(Phi, psi, St, D, C, WA, Wh)


def _prescribed_bias(ops: Ops, joint: JointTerms, P: Any, p: Any, rd: slice) -> Any:
    """``p + Phi S a`` passed across a joint of prescribed relative acceleration ``a`` (its inertia ``Phi``
    unchanged)."""
    if joint.axis is not None:
        return p + ops.sub(P, rd, slice(joint.axis, joint.axis + 1)) * joint.prescribed
    return p + ops.matmul(ops.matmul(P, joint.S), joint.prescribed)


def _joint_load(joint: JointTerms, load: Any) -> Any:
    """``tau - S^T psi'`` of a joint's free directions (``-S^T psi'`` without joint forces)."""
    return load * -1.0 if joint.tau is None else joint.tau - load


def _free_bias(ops: Ops, joint: JointTerms, p: Any, PS: Any, pivot: Any, rhs: Any) -> Any:
    """``psi_hat = psi' + (Phi S + H) D^-1 (tau - S^T psi')`` passed across a joint with free directions
    (``PS``: ``Phi S + H``; one direction: a division)."""
    if joint.axis is not None or joint.free == 1:
        return p + PS * (rhs / pivot)
    return p + ops.matmul(PS, _one_solve(ops, pivot, rhs))


def articulated_outward(ops: Ops, tree: Tree, bodies: Sequence[BodyTerms], joints: Sequence[JointTerms],
                        inward: Inward, *, characteristic: bool = False, forces: bool = True,
                        coupling: Sequence[Any] | None = None) -> Articulated:
    """Base-to-tip pass (module docstring) on the elimination ``inward`` of the same tree.

    It reads of ``bodies`` only ``Kin`` and ``c`` of the points carrying children, and of ``joints``
    ``S``, ``c``, ``tau``, ``prescribed`` and the structure (free directions, ``axis``).

    Parameters
    ----------
    ops, tree, bodies, joints
        As for :func:`articulated_sweep`.
    inward : Inward
        :func:`articulated_inward` of these terms (or terms carrying the same numbers).
    characteristic : bool
        Also form ``prod det D_j prod det C_j``.
    forces : bool
        Also form the joint wrenches ``F_in`` (``False``: :attr:`Articulated.force` holds ``None``).
    coupling : sequence, optional
        The joint coupling of the same :func:`articulated_inward` (its one-direction rows already carry ``G``).

    Returns
    -------
    Articulated
    """
    nb = len(tree.parent)
    d = tree.dimension
    Phi, psi, St, D, C = inward.inertia, inward.bias, inward.transposed, inward.pivot, inward.modal
    WA, Wh = inward.modal_inertia, inward.modal_bias
    x, force, relative = [None] * nb, [None] * nb, [None] * nb
    for j in range(nb):
        par = tree.parent[j]
        joint = joints[j]
        if par >= 0:
            e = tree.point[j]
            A_O = _product(ops, bodies[par].Kin[e], x[par])
            if bodies[par].c[e] is not None:
                A_O = A_O + bodies[par].c[e]
        else:
            A_O = None                              # the ground does not move
        if joint.prescribed is not None:
            a = joint.prescribed
        elif joint.free == 0:
            a = None
        elif joint.axis is not None:                # St[j] holds the row S^T Phi
            row = slice(joint.axis, joint.axis + 1)
            load = ops.sub(psi[j], row, slice(0, 1))
            if A_O is not None:
                load = load + ops.matmul(St[j], A_O)
            rhs = load * -1.0 if joint.tau is None else joint.tau - load
            a = rhs / D[j]
        else:
            load = ops.matmul(St[j], psi[j] if A_O is None else ops.matmul(Phi[j], A_O) + psi[j])
            if coupling is not None and coupling[j] is not None and coupling[j][0] is not None and A_O is not None:
                load = load + ops.matmul(coupling[j][0], A_O)
            rhs = load * -1.0 if joint.tau is None else joint.tau - load
            a = rhs / D[j] if joint.free == 1 else _solve(ops, D[j], rhs, j, "joint pivot")
        if a is None:
            A = ops.zeros(d, 1) if A_O is None else A_O
        elif joint.axis is not None:                # S a = a in row `axis`
            A = joint.S * a if A_O is None else A_O + joint.S * a
        else:
            A = ops.matmul(joint.S, a) if A_O is None else A_O + ops.matmul(joint.S, a)
        if joint.c is not None:
            A = A + joint.c
        relative[j] = a
        x[j] = A if C[j] is None else ops.block([[A], [(ops.matmul(WA[j], A) + Wh[j]) * -1.0]])
        if forces:                                  # F = Phi (A - c_joint) + psi  (psi carries Phi c_joint)
            force[j] = ops.matmul(Phi[j], A if joint.c is None else A - joint.c) + psi[j]
    char = None
    if characteristic:
        for block in [b for b in D if b is not None] + [b for b in C if b is not None]:
            char = ops.det(block) if char is None else char * ops.det(block)
    return Articulated(x, force, relative, D, C, char, Phi)


def articulated_bias(ops: Ops, tree: Tree, bodies: Sequence[BodyTerms], joints: Sequence[JointTerms],
                     inward: Inward) -> Inward:
    """The tip-to-base elimination of new bias terms about the articulated inertias of ``inward``.

    For terms that differ from those ``inward`` was eliminated from only in the body biases ``h``, the
    joint forces ``tau`` and prescribed accelerations (the same ``M``, ``S``, ``kappa``, ``Kin``, ``RF``):
    :func:`articulated_inward`'s bias statements alone, on its stored ``Phi_j``, ``S^T Phi_j`` and ``D_j``;
    the articulated inertias are not formed again.  :func:`articulated_outward` of the result is then the
    sweep of the new terms (numbers equal to those of :func:`articulated_sweep` of them: the same
    operations on the same numbers).  The response of a sweep to changed loads at a fixed iterate
    (:func:`ctmm.spatial.implicit.input_response`) is its use.

    Parameters
    ----------
    ops, tree, bodies, joints
        As for :func:`articulated_sweep`: the new terms.  Their points' ``c`` must be ``None`` (zero): the
        eliminated ``Phi_hat`` is not kept.
    inward : Inward
        :func:`articulated_inward` of terms with the same inertias, without joint coupling.

    Returns
    -------
    Inward
        ``inward`` with the new biases ``psi'_j``.

    Raises
    ------
    ModelError
        A body with internal coordinates (its modal bias is solved together with its inertia) or a point
        with a velocity term ``c``.
    """
    nb = len(tree.parent)
    d = tree.dimension
    rd = slice(0, d)
    h = [b.h for b in bodies]
    psi = [None] * nb
    for j in range(nb - 1, -1, -1):
        if inward.modal[j] is not None:
            raise ModelError(f"articulated_bias: body {j} has internal coordinates; sweep its terms with "
                             "articulated_sweep")
        P, p = inward.inertia[j], h[j]
        joint = joints[j]
        if joint.c is not None:
            p = p + ops.matmul(P, joint.c)
        psi[j] = p
        par = tree.parent[j]
        if par < 0:
            continue
        axis = joint.axis
        if joint.prescribed is not None:
            p_hat = _prescribed_bias(ops, joint, P, p, rd)
        elif joint.free == 0:
            p_hat = p
        elif axis is not None:
            row = slice(axis, axis + 1)
            p_hat = _free_bias(ops, joint, p, ops.sub(P, rd, row), inward.pivot[j],
                               _joint_load(joint, ops.sub(p, row, slice(0, 1))))
        else:
            p_hat = _free_bias(ops, joint, p, ops.matmul(P, joint.S), inward.pivot[j],
                               _joint_load(joint, ops.matmul(inward.transposed[j], p)))
        e = tree.point[j]
        if bodies[par].c[e] is not None:
            raise ModelError(f"articulated_bias: the point {e!r} of body {par} has a velocity term c; sweep its "
                             "terms with articulated_sweep")
        h[par] = h[par] + _product(ops, bodies[par].RF[e], p_hat)
    return Inward(inward.inertia, psi, inward.transposed, inward.pivot, inward.modal, inward.modal_inertia,
                  inward.modal_bias)
