"""The articulated sweep of a serial chain of equal segments as two folds over its segments
(generated kernels, issue 13), for any point dimension ``d`` (planar 3, spatial 6).

A chain of ``count`` equal segments is swept with the code of one segment, called once per segment
(``casadi.Function.mapaccum``), so the generated C does not grow with the number of bodies:

* ``eliminate`` (tip to base): the segment's body and joint terms and the tip-to-base half of the one
  articulated sweep (:func:`~ctmm.articulated.articulated_inward`) on the segment between a virtual parent
  (``Kin = I``, ``RF = I``) and a virtual welded child holding the articulated inertia and bias of the rest
  of the chain; the virtual parent's articulated terms are carried to the next segment inboard, and the
  formed terms the base-to-tip half reads (articulated inertias, biases and pivots, the points'
  kinematics, the joints' laws: those of their entries that are not constants) are handed on per segment;
* ``accelerate`` (base to tip): the base-to-tip half (:func:`~ctmm.articulated.articulated_outward`) on
  those handed-on terms with the virtual parent's acceleration prescribed (the inboard point's, carried
  from the previous segment), giving the segment's outputs and the virtual child's acceleration carried on.

Each segment's terms are formed once, as in the straight-line sweep; the fold adds the calls and the
handed-on columns.  Used by :func:`ctmm.compiled_spatial.folded_velocity_rate` and
:func:`ctmm.compiled_scene_fold.folded_acceleration`.
"""
from __future__ import annotations

from dataclasses import fields, replace
from typing import Any, Callable, Sequence

from .articulated import Articulated, Inward, Tree, articulated_inward, articulated_outward
from .errors import ModelError
from .ops import CASADI
from .protocol import BodyTerms, JointTerms

__all__ = ["fold_segments"]


def fold_segments(bodies: Sequence[BodyTerms], joints: Sequence[JointTerms], outboard: Sequence[str],
                  symbols: Sequence[Any], columns: Sequence[Any], outputs: Callable[[Articulated], Any],
                  kappa: Sequence[Any] | None = None) -> Any:
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
    kappa : sequence, optional
        Joint tangent ``(k, k)`` of each joint of the segment (on ``symbols``; ``None`` entries and default: 0),
        added to its pivot as in :func:`~ctmm.articulated.articulated_sweep` (an implicit hinge law).

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
    all_bodies, all_joints = [virtual_parent, *bodies, virtual_child], [weld, *joints, weld]
    inward = articulated_inward(CASADI, tree, all_bodies, all_joints,
                                None if kappa is None else [None, *kappa, None])
    reduced = ca.vertcat(ca.reshape(inward.inertia[0], d * d, 1), inward.bias[0])
    # the outward pass on stand-ins of the formed terms it reads (the inward results, the points' Kin and
    # c, the joints' S, c and tau): the eliminate fold hands their values to the accelerate fold
    formed = _Formed()
    stand_in = Inward(*[[formed.stand_in(term) for term in getattr(inward, field.name)] for field in fields(inward)])
    bodies_in = [replace(body, Kin={e: formed.stand_in(body.Kin[e]) for e in body.Kin},
                         c={e: formed.stand_in(body.c[e]) for e in body.c}) for body in all_bodies]
    joints_in = [replace(joint, S=formed.stand_in(joint.S), c=formed.stand_in(joint.c), tau=formed.stand_in(joint.tau))
                 for joint in all_joints]
    inboard_acceleration = ca.SX.sym("A", d)
    joints_in[0] = JointTerms(S=eye, prescribed=inboard_acceleration)
    solution = articulated_outward(CASADI, tree, bodies_in, joints_in, stand_in)
    carried_on, result = solution.x[period + 1], outputs(solution)
    read, values = formed.read(ca.vertcat(carried_on, result))
    eliminate = ca.Function("eliminate", [carried, *symbols], [reduced, values])
    # (casadi refuses a free symbol here: a term the outward pass reads that has no stand-in)
    accelerate = ca.Function("accelerate", [inboard_acceleration, read], [carried_on, result])
    # the tip-to-base fold runs on the columns reversed by a constant permutation
    reverse = ca.DM(ca.Sparsity.triplet(count, count, list(range(count)), list(range(count - 1, -1, -1))),
                    [1.0] * count)
    _, values_reversed = eliminate.mapaccum("eliminate_fold", count)(
        ca.DM.zeros(d * d + d, 1), *[ca.mtimes(column, reverse) for column in columns])
    _, result = accelerate.mapaccum("accelerate_fold", count)(ca.DM.zeros(d, 1), ca.mtimes(values_reversed, reverse))
    return result


class _Formed:
    """Stand-ins for formed terms: a symbol for each structural entry that is not a constant (constants are
    kept, so the outward pass keeps its simplifications), with the expression it stands for."""

    def __init__(self) -> None:
        self.symbols: list = []
        self.expressions: list = []

    def stand_in(self, term: Any) -> Any:
        """``term`` (SX, DM or None) with its non-constant entries replaced by new symbols."""
        import casadi as ca

        if term is None:
            return None
        term = ca.SX(term)
        entries = []
        for i in range(term.nnz()):
            entry = term.nz[i]
            if not entry.is_constant():
                symbol = ca.SX.sym(f"formed_{len(self.symbols)}")
                self.symbols.append(symbol)
                self.expressions.append(entry)
                entry = symbol
            entries.append(entry)
        return ca.SX(term.sparsity(), ca.vertcat(*entries)) if entries else term

    def read(self, expression: Any) -> tuple[Any, Any]:
        """``(symbols, expressions)`` columns of the stand-ins ``expression`` depends on (in order)."""
        import casadi as ca

        if not self.symbols:
            return ca.SX(0, 1), ca.SX(0, 1)
        used = ca.which_depends(expression, ca.vertcat(*self.symbols), 1, False)
        keep = [i for i, flag in enumerate(used) if flag]
        return (ca.vertcat(*[self.symbols[i] for i in keep]), ca.vertcat(*[self.expressions[i] for i in keep]))
