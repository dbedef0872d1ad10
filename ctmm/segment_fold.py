"""The articulated sweep of a serial chain of equal segments as two folds over its segments
(generated kernels, issue 13), for any point dimension ``d`` (planar 3, spatial 6).

A chain of ``count`` equal segments is swept with the code of one segment, called once per segment
(``casadi.Function.mapaccum``), so the generated C does not grow with the number of bodies:

* ``eliminate`` (tip to base): the segment's body and joint terms and the one articulated sweep
  (:func:`~ctmm.articulated.articulated_sweep`) on the segment between a virtual parent (``Kin = I``,
  ``RF = I``) and a virtual welded child holding the articulated inertia and bias of the rest of the
  chain; the virtual parent's articulated terms are carried to the next segment inboard;
* ``accelerate`` (base to tip): the same sweep with the virtual parent's acceleration prescribed (the
  inboard point's, carried from the previous segment), giving the segment's outputs and the virtual
  child's acceleration carried on.

The segment's terms are formed twice (once per sweep): about twice the arithmetic of the straight-line
sweep.  Used by :func:`ctmm.compiled_spatial.folded_velocity_rate` and
:func:`ctmm.compiled_scene_fold.folded_acceleration`.
"""
from __future__ import annotations

from typing import Any, Callable, Sequence

from .articulated import Articulated, Tree, articulated_sweep
from .errors import ModelError
from .ops import CASADI
from .protocol import BodyTerms, JointTerms

__all__ = ["fold_segments"]


def fold_segments(bodies: Sequence[BodyTerms], joints: Sequence[JointTerms], outboard: Sequence[str],
                  symbols: Sequence[Any], columns: Sequence[Any], outputs: Callable[[Articulated], Any]) -> Any:
    """The outputs of every segment of a chain of equal segments, swept as two folds.

    Parameters
    ----------
    bodies, joints : sequence of BodyTerms, JointTerms
        Terms of the ``period`` bodies of one segment and their inboard joints (casadi SX, on ``symbols``);
        the segment's first body hangs on the inboard point of the chain (the previous segment's last
        body, or the ground) through its joint.
    outboard : sequence of str
        For each body of the segment, the name of its point carrying the next body (for the last one:
        the point carrying the next segment's first body).
    symbols : sequence of casadi.SX
        The segment's input columns (coordinates, rates, numbers, ...) the terms are stated on.
    columns : sequence of casadi.MX or DM
        One matrix per symbol: ``(symbol size, count)``, column ``k`` its value on segment ``k`` (from the
        base).
    outputs : callable
        ``outputs(solution) -> SX column`` of one segment from its sweep (:class:`~ctmm.articulated.Articulated`
        over ``[virtual parent, *bodies, virtual child]``: the segment's bodies are entries ``1..period``).

    Returns
    -------
    casadi.MX (rows of outputs, count)
        The outputs of each segment, column ``k`` of segment ``k``.

    Raises
    ------
    ModelError
        Sizes that do not match.
    """
    import casadi as ca

    period = len(bodies)
    if period < 1 or len(joints) != period or len(outboard) != period or len(symbols) != len(columns):
        raise ModelError(f"fold_segments: bodies ({len(bodies)}), joints ({len(joints)}) and outboard points "
                         f"({len(outboard)}) must be one per body of the segment (>= 1), symbols ({len(symbols)}) and "
                         f"columns ({len(columns)}) one per input")
    count = int(columns[0].size2()) if columns else 0
    if count < 1 or any(int(c.size2()) != count or int(c.size1()) != int(s.numel()) for s, c in zip(symbols, columns)):
        raise ModelError("fold_segments: every column matrix must have one row per entry of its symbol and one "
                         f"column per segment (>= 1); got {[c.shape for c in columns]} for {[s.shape for s in symbols]}")
    d = int(bodies[0].M.shape[0])
    eye, zero = ca.DM.eye(d), ca.DM.zeros(d, 1)
    virtual_parent = BodyTerms(M=ca.DM.zeros(d, d), h=zero, Kin={"in": eye}, c={"in": zero}, RF={"in": eye})
    carried = ca.SX.sym("carried", d * d + d)
    virtual_child = BodyTerms(M=ca.reshape(carried[:d * d], d, d), h=carried[d * d:])
    tree = Tree(tuple(range(-1, period + 1)), (None, "in") + tuple(outboard), dimension=d)
    weld = JointTerms(S=ca.DM.zeros(d, 0))
    solution = articulated_sweep(CASADI, tree, [virtual_parent, *bodies, virtual_child], [weld, *joints, weld])
    reduced = ca.vertcat(ca.reshape(solution.inertia[0], d * d, 1), solution.force[0])
    eliminate = ca.Function("eliminate", [carried, *symbols], [reduced, carried])
    inboard_acceleration = ca.SX.sym("A", d)
    prescribed = JointTerms(S=eye, prescribed=inboard_acceleration)
    solution = articulated_sweep(CASADI, tree, [virtual_parent, *bodies, virtual_child], [prescribed, *joints, weld])
    accelerate = ca.Function("accelerate", [inboard_acceleration, carried, *symbols],
                             [solution.x[period + 1], outputs(solution)])
    # the tip-to-base fold runs on the columns reversed by a constant permutation
    reverse = ca.DM(ca.Sparsity.triplet(count, count, list(range(count)), list(range(count - 1, -1, -1))),
                    [1.0] * count)
    _, carried_reversed = eliminate.mapaccum("eliminate_fold", count)(
        ca.DM.zeros(d * d + d, 1), *[ca.mtimes(column, reverse) for column in columns])
    _, result = accelerate.mapaccum("accelerate_fold", count)(
        ca.DM.zeros(d, 1), ca.mtimes(carried_reversed, reverse), *columns)
    return result
