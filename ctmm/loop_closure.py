"""Closing delay-free feedback loops of a state-space plant (linear fractional transformation).

Used by :func:`ctmm.lumped_realisation.chain_state_space` (controller realisations) and by the planar
linearisation (:mod:`ctmm.planar_linearization`).
"""
from __future__ import annotations

from typing import Any, Sequence

import numpy as np

from .controller_state_space import controller_state_space
from .errors import ModelError

__all__ = ["controller_matrices", "block_controller", "close_loops"]


def controller_matrices(loop: Any, verb: str = "to_state_space"
                        ) -> tuple[np.ndarray, np.ndarray, np.ndarray, np.ndarray]:
    """``(A, B, C, D)`` of a loop's controller as 2-D arrays: its LTI ``C(s)`` realised, or ``D = gain`` (no states),
    by :func:`ctmm.controller_state_space.controller_state_space`.

    ``verb`` names the caller in the refusal of an improper ``C(s)``."""
    A, B, C, D = controller_state_space(loop.name, loop.gain, f"by {verb}")
    k = A.shape[0]
    return A, B.reshape(k, 1), C.reshape(1, k), np.array([[D]])


def block_controller(loops: Sequence[Any], verb: str = "to_state_space") -> tuple:
    """Block-diagonal controller ``K = diag(C_l)`` of ``loops``: ``xi' = Ak xi + Bk e``, ``v = Ck xi + Dk e``.

    Returns
    -------
    Ak, Bk, Ck, Dk : ndarray
        One input ``e_l`` and one output ``v_l`` per loop.
    sizes : list of int
        Number of controller states per loop.
    """
    blocks = [controller_matrices(lp, verb) for lp in loops]
    sizes = [blk[0].shape[0] for blk in blocks]
    nk, nl = sum(sizes), len(blocks)
    Ak, Bk, Ck, Dk = np.zeros((nk, nk)), np.zeros((nk, nl)), np.zeros((nl, nk)), np.zeros((nl, nl))
    o = 0
    for i, (a_, b_, c_, d_) in enumerate(blocks):
        m = a_.shape[0]
        Ak[o:o + m, o:o + m], Bk[o:o + m, i], Ck[i, o:o + m], Dk[i, i] = a_, b_[:, 0], c_[0], d_[0, 0]
        o += m
    return Ak, Bk, Ck, Dk, sizes


def close_loops(plant: tuple, loops: Sequence[Any], n_exogenous: int) -> tuple:
    """Close delay-free loops of a state-space plant by an LFT; delayed loops stay open.

    Parameters
    ----------
    plant : (A, B, C, D)
        Inputs ``[w (n_exogenous), u_1 .. u_L]`` (the loop forces, one per loop, in the order of
        ``loops``); outputs ``[z ..., y_1 .. y_L]`` (the loop sensor sums last).
    loops : sequence of Feedback
        ``u = -C(s) y`` for ``delay == 0``; loops with ``delay > 0`` keep ``u_l`` as an input and
        ``y_l`` as an output.
    n_exogenous : int
        Number of exogenous inputs ``w``.

    Returns
    -------
    A, B, C, D : ndarray
        Inputs ``[w, u_delayed...]``, outputs ``[z, y_delayed...]``; states ``[x, xi]`` (the
        controller states of the real-time LTI loops appended).
    n_controller : list of int
        Number of controller states per real-time loop (in loop order, delayed loops skipped).
    C_u, D_u : ndarray
        The forces of the real-time loops, ``u = C_u [x, xi] + D_u [w, u_delayed]`` (one row per
        real-time loop, in loop order).
    """
    A, B, C, D = (np.asarray(m, dtype=float) for m in plant)
    nl = len(loops)
    nz = C.shape[0] - nl
    nw = n_exogenous
    rt = [i for i, lp in enumerate(loops) if lp.delay == 0.0]
    dl = [i for i, lp in enumerate(loops) if lp.delay > 0.0]
    v_cols = list(range(nw)) + [nw + i for i in dl]           # open inputs
    u_cols = [nw + i for i in rt]                              # closed inputs
    z_rows = list(range(nz)) + [nz + i for i in dl]            # outputs kept
    y_rows = [nz + i for i in rt]                              # sensed by real-time loops
    B1, B2 = B[:, v_cols], B[:, u_cols]
    C1, Cy = C[z_rows], C[y_rows]
    D11, D12, D21, D22 = (D[np.ix_(z_rows, v_cols)], D[np.ix_(z_rows, u_cols)],
                          D[np.ix_(y_rows, v_cols)], D[np.ix_(y_rows, u_cols)])
    Ak, Bk, Ck, Dk, sizes = block_controller([loops[i] for i in rt], "linearize")
    nr = len(rt)
    # u = -(Ck xi + Dk y), y = Cy x + D21 v + D22 u  ->  (I + Dk D22) u = -Dk Cy x - Ck xi - Dk D21 v
    E = np.eye(nr) + Dk @ D22
    if nr and np.linalg.cond(E) > 1e12:
        raise ModelError("algebraic loop without a solution: I + D_K D_yu is singular")
    Einv = np.linalg.inv(E) if nr else np.zeros((0, 0))
    Ux, Uxi, Uv = -Einv @ Dk @ Cy, -Einv @ Ck, -Einv @ Dk @ D21
    Yx, Yxi, Yv = Cy + D22 @ Ux, D22 @ Uxi, D21 + D22 @ Uv
    A_cl = np.block([[A + B2 @ Ux, B2 @ Uxi], [Bk @ Yx, Ak + Bk @ Yxi]])
    B_cl = np.vstack([B1 + B2 @ Uv, Bk @ Yv])
    C_cl = np.hstack([C1 + D12 @ Ux, D12 @ Uxi])
    D_cl = D11 + D12 @ Uv
    return A_cl, B_cl, C_cl, D_cl, sizes, np.hstack([Ux, Uxi]), Uv
