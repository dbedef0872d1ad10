"""Generated planar accelerations of a serial chain folded over its segments (issue 13: first compile of
a 100-body chain in seconds).

A planar serial chain of rigid bodies on revolute hinges (:func:`planar_fold_refusal`) is swept by
:func:`ctmm.segment_fold.fold_segments`: the code of one segment of ``period`` bodies, called once per
segment, instead of straight-line code of every body, so the C text and its compile time do not grow
with N.  Each segment takes its own column of numbers (masses, inertias, centres of mass, the point
carrying the next body, gravity, hinge laws, actuator torques and forces: :func:`segment_numbers`), so
the bodies need not be equal: only the structure (rigid bodies, revolute hinges with linear laws, no
loads) repeats.  Planar coordinates are absolute angles, so each segment's inboard angle and rate are
the previous segment's last coordinates (no kinematic fold).

:class:`~ctmm.compiled_scene.CompiledScene` compiles through it with ``fold=True``, or by default for
foldable chains of at least :data:`FOLD_MIN_BODIES` bodies.
"""
from __future__ import annotations

from typing import Any, Sequence

import numpy as np

from .compiled_parameters import parameter_vector, symbolic_numbers
from .errors import ModelError
from .ops import CASADI
from .planar.body_forms import SceneNumbers, revolute_terms, rigid_body_terms
from .planar.model import REVOLUTE, PlanarModel
from .planar.ports import ActuatorInputs, PlanarPorts
from .segment_fold import fold_segments

__all__ = ["FOLD_MIN_BODIES", "SCHEME_FOLD_MIN_BODIES", "SEGMENT_BODIES", "SEGMENT_ENTRIES", "fold_period",
           "folded_acceleration", "folded_accelerations_with_inputs", "planar_fold_refusal", "scheme_fold_period",
           "segment_numbers", "symbolic_inputs"]

FOLD_MIN_BODIES = 30
"""Foldable planar chains (:func:`planar_fold_refusal`) with at least this many bodies compile through the
fold by default (``fold=None``).  Measured (``benchmarks/planar_chain.py``, pendulum chains, loaded 2-core
machine): the straight-line code's first compile passes 3 s near N = 30 (1.8 s at 20, 16 s at 100, 69 s at
300), the fold's stays near 1-5 s at N = 100-300.  Per step (session 8, each segment's terms formed once; CPU
time) folded / straight-line 6.7 / 2.4 us at N = 20, 32 / 14 us at N = 100, 104 / 53 us at N = 300 (the
calls, the handed-on columns and the numbers taken per segment)."""
SCHEME_FOLD_MIN_BODIES = 20
"""Foldable planar chains with at least this many bodies and no loops sweep folded inside the generated DT-TMM
schemes whose Newton tangent is mapped (:mod:`ctmm.mapped_tangent`, :func:`scheme_fold_period`).  Measured
(pendulum chain, Newmark, mapped tangent, CPU incl. gcc, fresh cache, load ~18 on 2 cores, 2026-11-25): first
compile folded / straight-line 1.7 / 3.4 s at N = 12, 2.5 / 6.6 s at 20, 2.9 / 10.9 s at 30; per step 0.35 / 0.17
ms, 1.4 / 0.42 ms, 2.9 / 1.2 ms (the fold's calls, ``2 n`` directional derivatives per Newton iteration).  The
straight-line compile passes ~3 s from N ~ 12; from 20 the fold's is a third of it."""
SEGMENT_BODIES = 4
"""Preferred bodies per folded segment (:func:`fold_period`): fewer calls per sweep than one body per
segment, still short code."""
SEGMENT_ENTRIES = 16
"""Numbers per body of a segment's column (:func:`segment_numbers`)."""


def symbolic_inputs(model: PlanarModel, units: Sequence[ActuatorInputs], u: Any) -> ActuatorInputs | None:
    """Actuator inputs as affine expressions of the symbols ``u``: ``sum_k u_k units[k]`` (each input's
    loads per unit value; :class:`~ctmm.compiled_scene.CompiledScene`, straight-line and folded).

    Raises
    ------
    ModelError
        A station force or moment on a beam's floating frame (not on the element protocol).
    """
    if not units:
        return None
    torque = np.zeros(model.n_bodies, dtype=object)
    force = np.zeros((model.n_bodies, 3), dtype=object)
    modal: dict[int, np.ndarray] = {}
    for k, unit in enumerate(units):
        if unit.frame_wrench:
            raise ModelError(f"input {k}: a station force or moment on a beam's floating frame is not on the "
                             "element protocol yet, so generated kernels cannot take it; use ctmm.simulate without "
                             "compiled=True")
        for j in np.flatnonzero(unit.hinge_torque):
            torque[j] = torque[j] + u[k] * float(unit.hinge_torque[j])
        for j, c in zip(*np.nonzero(unit.body_force)):
            force[j, c] = force[j, c] + u[k] * float(unit.body_force[j, c])
        for j, pattern in unit.modal_force.items():
            pattern = np.asarray(pattern, dtype=float)
            current = modal.get(j, np.zeros(pattern.size, dtype=object))
            modal[j] = np.array([current[i] + (u[k] * pattern[i] if pattern[i] else 0.0)
                                 for i in range(pattern.size)], dtype=object)
    return ActuatorInputs(torque, force, modal)


def planar_fold_refusal(model: PlanarModel, period: int = 1) -> str:
    """Why ``model`` cannot be folded into segments of ``period`` bodies ("" when it can).

    Foldable: a serial chain (body ``j`` on body ``j - 1``, body 0 on the ground) of at least two
    segments of rigid bodies on revolute hinges with linear laws (smooth, elastic, damper,
    spring-damper, actuated; not driven, free, translational-spring or nonlinear), without loads, whose
    coordinates are the bodies' angles in order.
    """
    n = model.n_bodies
    if isinstance(period, bool) or not isinstance(period, (int, np.integer)) or period < 1:
        return f"the fold's period must be an integer >= 1 (bodies per segment), got {period!r}"
    if n < 2 * period or n % period:
        return (f"the fold needs at least two segments of {period} bodies (N a multiple of the period); model "
                f"{model.name!r} has {n} bodies")
    if any(int(model.parent[j]) != j - 1 for j in range(n)):
        return f"model {model.name!r} is not a serial chain (body j on body j - 1, body 0 on the ground)"
    if model.beams:
        return f"model {model.name!r} has modal beams (the fold takes rigid bodies)"
    kinds = [j for j in range(n) if int(model.joint_kind[j]) != REVOLUTE or j in model.nonlinear_hinges]
    if kinds:
        return (f"joint {model.joint_names[kinds[0]]!r} of model {model.name!r} is not a revolute hinge with a linear "
                "law (driven, free-base, translational-spring and nonlinear hinges are not folded)")
    if len(model.load_body):
        return f"model {model.name!r} has rigid-body loads (not folded)"
    if model.n_coordinates != n or list(np.asarray(model.theta_index, dtype=int)) != list(range(n)):
        return f"the coordinates of model {model.name!r} are not the bodies' angles in order"
    return ""


def fold_period(model: PlanarModel) -> int:
    """Bodies per segment the fold uses for ``model``: the largest of ``SEGMENT_BODIES, ..., 1`` that
    :func:`planar_fold_refusal` accepts (0: the model does not fold)."""
    return next((period for period in range(SEGMENT_BODIES, 0, -1) if not planar_fold_refusal(model, period)), 0)


def scheme_fold_period(model: PlanarModel, tangent: str, loops: Any) -> int:
    """Bodies per folded segment of the sweep of a generated DT-TMM scheme of ``model`` (0: straight-line code):
    folded where its tangent is ``"mapped"`` or ``"sweep"``, it has no ``loops`` (``None``), it folds (:func:`fold_period`) and
    has at least :data:`SCHEME_FOLD_MIN_BODIES` bodies."""
    if tangent not in ("mapped", "sweep") or loops is not None or model.n_bodies < SCHEME_FOLD_MIN_BODIES:
        return 0
    return fold_period(model)


def segment_numbers(model: PlanarModel, numbers: SceneNumbers, inputs: ActuatorInputs | None, period: int) -> Any:
    """The numbers of each segment: casadi SX ``(SEGMENT_ENTRIES period, N / period)``, column ``k`` those of
    segment ``k``; per body ``[mass, inertia, com_x, com_y, point_x, point_y, g_x, g_y, stiffness, damping,
    reference, reference_rate, torque, force_x, force_y, moment]`` (SI; ``point`` the body-frame point
    carrying the next body, (0, 0) on the last body; ``torque`` the hinge law's and the actuators' at the
    hinge; ``force``, ``moment`` the actuators' at the centre of mass), entries of ``numbers`` and ``inputs``
    (numbers or symbols)."""
    import casadi as ca

    n = model.n_bodies
    zero = (0.0, 0.0, 0.0)

    def body(j: int) -> list:
        point = numbers.ends[j][model.parent_end[j + 1]] if j + 1 < n else (0.0, 0.0)
        torque = numbers.torque[j] + (0.0 if inputs is None else inputs.hinge_torque[j])
        force = zero if inputs is None else tuple(inputs.body_force[j])
        return [numbers.mass[j], numbers.inertia[j], *numbers.center_of_mass[j], *point, *numbers.gravity,
                numbers.stiffness[j], numbers.damping[j], numbers.reference[j], numbers.reference_rate[j], torque,
                *force]

    columns = [ca.vertcat(*[ca.SX(entry) if not isinstance(entry, ca.SX) else entry
                            for j in range(k, k + period) for entry in body(j)]) for k in range(0, n, period)]
    return ca.horzcat(*columns)


def folded_acceleration(model: PlanarModel, numbers: SceneNumbers, inputs: ActuatorInputs | None,
                        symbols: tuple[Any, Any, Any], period: int = 1, implicit: bool = False) -> Any:
    """``acceleration(q, v, u, p, t) -> qddot`` (casadi.Function on MX) of a foldable chain
    (:func:`planar_fold_refusal`) swept in segments of ``period`` bodies (:func:`ctmm.segment_fold.fold_segments`).

    Parameters
    ----------
    model : PlanarModel
    numbers : SceneNumbers
        The model's numbers on the SX symbols ``symbols = (u, p, t)`` (actuator inputs, parameters, time
        [s]; :func:`ctmm.compiled_parameters.symbolic_numbers`), or numbers.
    inputs : ActuatorInputs or None
        The actuators' loads as expressions of ``u``.
    period : int
        Bodies per segment [-].
    implicit : bool
        ``implicit(q, v, q_hat, v_hat, w, g, u, p, t) -> qddot`` instead: the hinge laws at ``(q_hat, v_hat)`` made
        implicit by the joint tangents ``kappa = k w + c g`` (the sweep of :mod:`ctmm.compiled_sweep_newton`).

    Raises
    ------
    ModelError
        A model that does not fold (:func:`planar_fold_refusal`).
    """
    import casadi as ca

    reason = planar_fold_refusal(model, period)
    if reason:
        raise ModelError(f"folded planar accelerations: {reason}")
    n = model.n_bodies
    count = n // period
    u_sx, p_sx, t_sx = symbols
    entries = segment_numbers(model, numbers, inputs, period)
    per_segment = _numbers_map(entries, u_sx, p_sx, t_sx)
    common = _common_constants(entries)
    parent, q, v = ca.SX.sym("parent", 2), ca.SX.sym("q", period), ca.SX.sym("v", period)
    law = (ca.SX.sym("parent_hat", 2), ca.SX.sym("q_hat", period), ca.SX.sym("v_hat", period)) if implicit else \
        (parent, q, v)                                  # where the hinge laws are evaluated
    weights = ca.SX.sym("weights", 2)                   # (w, g) of the implicit laws
    s = ca.SX.sym("s", SEGMENT_ENTRIES * period)
    bodies, joints, kappa = [], [], []
    for i in range(period):
        e = [common.get(SEGMENT_ENTRIES * i + k, s[SEGMENT_ENTRIES * i + k]) for k in range(SEGMENT_ENTRIES)]
        th_end, om_end = (law[0][0], law[0][1]) if i == 0 else (law[1][i - 1], law[2][i - 1])
        bodies.append(rigid_body_terms(CASADI, mass=e[0], inertia=e[1], center_of_mass=(e[2], e[3]),
                                       points={"out": (e[4], e[5])}, gravity=(e[6], e[7]), theta=q[i], omega=v[i],
                                       body_force=(e[13], e[14], e[15])))
        joints.append(revolute_terms(CASADI, angle=law[1][i] - th_end, rate=law[2][i] - om_end, stiffness=e[8],
                                     damping=e[9], reference=e[10], reference_rate=e[11], torque=e[12]))
        kappa.append(weights[0] * e[8] + weights[1] * e[9])
    q_all, v_all = ca.MX.sym("q", n), ca.MX.sym("v", n)
    u, p, t = ca.MX.sym("u", u_sx.numel()), ca.MX.sym("p", p_sx.numel()), ca.MX.sym("t")
    columns = ca.reshape(per_segment(u, p, t), SEGMENT_ENTRIES * period, count)
    ground = ca.DM([float(model.ground_angle[0]), 0.0])

    def segments(q_in: Any, v_in: Any) -> tuple[Any, Any, Any]:
        """Each segment's inboard (angle, rate), angles and rates (columns)."""
        Q, V = ca.reshape(q_in, period, count), ca.reshape(v_in, period, count)
        return ground if count == 1 else ca.horzcat(ground, ca.vertcat(Q[period - 1, :count - 1],
                                                                       V[period - 1, :count - 1])), Q, V

    inputs_in, symbols_in = [q_all, v_all], [parent, q, v, s]
    values = [*segments(q_all, v_all), columns]
    if implicit:
        q_hat, v_hat, w, g = ca.MX.sym("q_hat", n), ca.MX.sym("v_hat", n), ca.MX.sym("w"), ca.MX.sym("g")
        inputs_in += [q_hat, v_hat, w, g]
        symbols_in += [*law, weights]
        values += [*segments(q_hat, v_hat), ca.repmat(ca.vertcat(w, g), 1, count)]
    accelerations = fold_segments(bodies, joints, ["out"] * period, symbols_in, values,
                                  lambda solution: ca.vertcat(*[solution.x[i][2] for i in range(1, period + 1)]),
                                  kappa if implicit else None)
    return ca.Function("implicit_acceleration" if implicit else "acceleration", [*inputs_in, u, p, t],
                       [ca.reshape(accelerations, n, 1)])


def folded_accelerations_with_inputs(model: PlanarModel, actuators: Sequence[str],
                                     channels: Sequence[ActuatorInputs] = (), period: int = 0,
                                     implicit: bool = False) -> Any:
    """:func:`ctmm.compiled_scene.symbolic_accelerations_with_inputs` folded over segments of ``period`` bodies
    (default :func:`fold_period`): ``acceleration(q, v, u, p, t)`` (casadi.Function on MX) with the inputs ``u``
    of the ports ``actuators`` then of ``channels`` (loads per unit value); ``implicit``: the implicit sweep of
    :func:`folded_acceleration` ``(q, v, q_hat, v_hat, w, g, u, p, t)``.

    Raises
    ------
    ModelError
        A model that does not fold (:func:`planar_fold_refusal`).
    """
    import casadi as ca

    ports = PlanarPorts(model)
    units = [ports.inputs({name: 1.0}) for name in actuators] + list(channels)
    u, p, t = ca.SX.sym("u", len(units)), ca.SX.sym("p", parameter_vector(model).size), ca.SX.sym("t")
    return folded_acceleration(model, symbolic_numbers(model, p, t), symbolic_inputs(model, units, u), (u, p, t),
                               period or fold_period(model) or 1, implicit)


def _common_constants(entries: Any) -> dict[int, float]:
    """``{row: value}`` of the rows of the segments' numbers ``entries`` (SX, one column per segment) that
    hold the same constant in every segment (zero forces, moments and laws; with ``numbers="constants"``
    every equal number): the segment's code takes them as constants, as the straight-line code does, so
    the operations on them fold away (the code stays the same for every segment)."""
    import casadi as ca

    common = {}
    for row in range(int(entries.size1())):
        values = [entries[row, column] for column in range(int(entries.size2()))]
        if all(value.is_constant() for value in values):
            numbers = {float(ca.evalf(value)) for value in values}
            if len(numbers) == 1:
                common[row] = numbers.pop()
    return common


def _numbers_map(entries: Any, u: Any, p: Any, t: Any) -> Any:
    """``(u, p, t) -> entries`` (flattened column) as a casadi.Function whose code does not grow with the
    entries: those affine in ``(p, u)`` (the numbers and actuators) as one product by a constant sparse
    matrix, the others (time signals) from an SX function of their own, placed by a second one."""
    import casadi as ca

    flat = ca.reshape(entries, entries.numel(), 1)
    x = ca.vertcat(p, u)
    jacobian = ca.jacobian(flat, x)
    nonlinear = np.asarray(ca.which_depends(flat, x, 2, True), dtype=bool)       # entries nonlinear in x
    on_time = np.asarray(ca.which_depends(flat, t, 1, True), dtype=bool) if flat.numel() else nonlinear
    timed = [int(i) for i in np.flatnonzero(nonlinear | on_time)]
    affine = ca.Function("affine", [x, t], [jacobian, flat])      # at x = 0: the rows without t are exact
    slope, offset = (ca.DM(value) for value in affine(ca.DM.zeros(x.numel()), 0.0))
    for i in timed:
        slope[i, :], offset[i] = 0.0, 0.0
    u_mx, p_mx, t_mx = ca.MX.sym("u", u.numel()), ca.MX.sym("p", p.numel()), ca.MX.sym("t")
    result = ca.mtimes(ca.sparsify(slope), ca.vertcat(p_mx, u_mx)) + ca.sparsify(offset)
    if timed:
        signals = ca.Function("timed_numbers", [u, p, t], [ca.vertcat(*[flat[i] for i in timed])])
        place = ca.DM(ca.Sparsity.triplet(flat.numel(), len(timed), timed, list(range(len(timed)))), [1.0] * len(timed))
        result = result + ca.mtimes(place, signals(u_mx, p_mx, t_mx))
    return ca.Function("segment_numbers", [u_mx, p_mx, t_mx], [result])
