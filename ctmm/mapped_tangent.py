"""Jacobians of a generated sweep by mapped forward derivatives: code O(sweep) (issue 13, compile time).

A generated Newton step needs the tangent of the sweep's accelerations, ``w d qddot/dq + g d qddot/dv`` and, for
the mass-weighted residual (:mod:`ctmm.compiled_newton_weighting`), ``G = d qddot/du`` and ``d(G s)/dq``.
``casadi.jacobian`` of the straight-line SX sweep forms these as expressions: their size and the C compiler's
time grow as ``N^2 .. N^3`` with the bodies (pendulum chain, Newmark: 2 / 19 / 127 s at N = 10 / 20 / 30).
Here the sweep stays one ``casadi.Function`` and each column is its forward (directional) derivative along a
unit seed: :meth:`casadi.Function.forward` of the sweep mapped serially over the ``n`` seeds
(:meth:`casadi.Function.map`), so the code holds the sweep's derivative once (O(sweep), a loop in C) and each
evaluation costs ``n`` directional derivatives (each a small multiple of one sweep).  The columns are the
same derivatives as the symbolic Jacobian's (algorithmic differentiation of the same operations), equal to
round-off.  Used by :mod:`ctmm.compiled_scene_schemes`, :mod:`ctmm.compiled_newton_weighting` and the spatial
schemes (:func:`value_and_jacobian`: the directional derivative along the iterate alone, :func:`casadi.jtimes`, from
:data:`SPATIAL_MAPPED_MIN_VELOCITIES`).  The price is the evaluation, O(N^2) per Newton iteration: on a folded 100-body pendulum chain (Newmark)
the first compile is 4.1 s but a step costs 37 ms of CPU (``benchmarks/compiled_schemes_planar.py --chain-sizes``);
against the Python stepper's transfer-form Newton (one linearised sweep per iteration, O(N)) in the same run the
generated step is 0.27 of it at 15 coordinates, 1.5 times it at 20 and 10 times at 80 (20.3 against 2.0 ms,
``benchmarks/compiled_schemes_default.py``; the 23 ms per Python step at N = 100 recorded earlier were its first
steps, which trace its sweep once), so :mod:`ctmm.compiled_default` generates planar schemes by default up to 15
coordinates (30 with loops, whose Python path costs more).  Planar models with linear hinge laws and no modal bodies
or loops iterate from 8 coordinates with one implicit articulated sweep per iteration instead
(:mod:`ctmm.compiled_sweep_newton`, O(N)); the tangents here serve the others.
"""
from __future__ import annotations

from typing import Any, Sequence

from .errors import ModelError

__all__ = ["MAPPED_MIN_COORDINATES", "SPATIAL_MAPPED_MIN_VELOCITIES", "mapped_columns", "residual_terms",
           "tangent_construction", "value_and_jacobian", "weighted_residual_terms"]

MAPPED_MIN_COORDINATES = 8
"""Generated planar scheme steps of at least this many coordinates form their Newton tangent by mapped forward
derivatives by default (``tangent=None``); smaller ones by the symbolic Jacobian (spatial steps:
:data:`SPATIAL_MAPPED_MIN_VELOCITIES`).
Measured (pendulum chain, Newmark, CPU incl. gcc, fresh cache, load 10-14 on 2 cores, 2026-11-25): first compile
symbolic / mapped 2.0 / 1.7 s at N = 5, 5.4 / 3.6 s at 10, 52 / 6.9 s at 20, > 600 s of gcc / (folded) ~3 s at 30;
per step 31 / 31 us at 5, 58 / 131 us at 10, 161 / 419 us at 20 (the symbolic Jacobian shares its terms; the
mapped one takes ``2 n`` directional derivatives per Newton iteration).  The symbolic compile passes ~3 s between
N = 5 and 10, so the mapped one takes over there."""

SPATIAL_MAPPED_MIN_VELOCITIES = 3
"""Generated spatial scheme steps (:mod:`ctmm.compiled_spatial_schemes`, with loops, kinematic loops) of at least
this many velocities form their Newton tangent by the directional derivatives of :func:`value_and_jacobian` by
default; smaller ones by the symbolic Jacobian.  The symbolic Jacobian of the step's residual repeats the retraction
and the sweep in every entry: measured (``benchmarks/spatial_scheme_tangent.py`` and single runs, Newmark, gcc
``-O1`` CPU, load 5 on 2 cores, 2026-11-26; symbolic -> mapped) one revolute link (1 velocity) 80 -> 83 kB of C,
0.65 -> 0.52 s, 1.9 -> 3.1 us per step; two (2) 119 -> 118 kB, 1.0 -> 1.0 s, 3.7 -> 4.2 us; three (3) 217 -> 175 kB,
2.2 -> 1.9 s, 7.4 -> 9.2 us; a ball joint (3) 164 -> 134 kB, 1.6 -> 1.1 s, 8.9 -> 8.2 us; revolute + ball (4) 262 ->
173 kB, 2.7 -> 1.7 s, 17 -> 19 us; a free body (6) 458 -> 232 kB, 6.6 -> 2.4 s, 21 -> 36 us; a free body held by
a revolute cut (kinematic loop scheme, 6) 1206 -> 530 kB, 19.0 -> 5.4 s, 45 -> 57-83 us; the same Newton
iterations.  Below 3 velocities both compile alike and the symbolic one runs faster."""


def mapped_columns(function: Any, seeded: Sequence[int], count: int, name: str = "columns") -> Any:
    """``columns(*inputs, *seeds) -> D`` (casadi ``Function``): ``count`` forward derivatives of ``function``'s
    first output, one per column of the seeds, evaluated by one serial map of its forward derivative.

    Parameters
    ----------
    function : casadi.Function
        The sweep (SX or MX), inputs column vectors; its first output a column of ``m`` entries.
    seeded : sequence of int
        The inputs that get seeds (the others are held: zero direction).
    count : int
        Directions (columns) [-].
    name : str
        Of the returned Function.

    Returns
    -------
    casadi.Function
        Inputs: ``function``'s inputs, then one ``(rows of that input, count)`` seed matrix per entry of
        ``seeded``; output ``(m, count)``, column ``i`` the derivative of the first output along column ``i`` of
        the seeds.
    """
    import casadi as ca

    n_in, n_out = function.n_in(), function.n_out()
    forward = function.forward(1)          # inputs: nominal inputs, nominal outputs, one seed per input
    shared = list(range(n_in + n_out)) + [n_in + n_out + i for i in range(n_in) if i not in seeded]
    mapped = forward.map(f"{name}_map", "serial", int(count), shared, [])
    inputs = [ca.MX.sym(function.name_in(i), function.sparsity_in(i)) for i in range(n_in)]
    seeds = [ca.MX.sym(f"seed_{function.name_in(i)}", function.size1_in(i), int(count)) for i in seeded]
    nominal = function.call(inputs)
    directions = [seeds[list(seeded).index(i)] if i in seeded else ca.MX.zeros(function.sparsity_in(i))
                  for i in range(n_in)]
    out = mapped.call([*inputs, *nominal, *directions])
    return ca.Function(name, [*inputs, *seeds], [out[0]])


def value_and_jacobian(function: Any, index: int, name: str) -> Any:
    """``name(*inputs) -> (output_0, d output_0 / d input_index)`` (casadi ``Function`` on MX), the columns of
    the Jacobian by a serial map over the unit seeds of input ``index`` (a column vector) of one directional
    derivative of ``function``'s first output along that input alone (:func:`casadi.jtimes`: no derivative code for
    the held inputs); the value is the first evaluation's (the derivative's code computes it anyway), so the code
    holds the function once, inside its derivative."""
    import casadi as ca

    symbol = ca.SX if function.is_a("SXFunction") else ca.MX
    inputs = [symbol.sym(function.name_in(i), function.sparsity_in(i)) for i in range(function.n_in())]
    size, value = function.size1_in(index), function.call(inputs)[0]
    seed = symbol.sym("seed", size)
    direction = ca.Function(f"{name}_direction", [*inputs, seed], [value, ca.jtimes(value, inputs[index], seed)])
    mapped = direction.map(f"{name}_columns", "serial", size, list(range(len(inputs))), [])
    outer = [ca.MX.sym(function.name_in(i), function.sparsity_in(i)) for i in range(function.n_in())]
    values, columns = mapped(*outer, ca.DM.eye(size))
    return ca.Function(name, outer, [values[:, 0], columns])


def residual_terms(rates: Any) -> Any:
    """``residual(a, q_hat, v_hat, w, g, t, u, p, c, s) -> (a - qddot, I - w d qddot/dq - g d qddot/dv)`` at
    ``q = q_hat + w a``, ``v = v_hat + g a`` (casadi ``Function`` on MX): the plain Newton residual and tangent of a
    generated planar scheme step (:mod:`ctmm.compiled_scene_schemes`), the tangent's columns by
    :func:`mapped_columns` on the seeds ``(w e_i, g e_i)``.  ``rates(q, v, u, p, t, c, s) -> qddot`` is the sweep
    (with the loops' controller entries ``c`` and the time ``s`` [s] since the step start)."""
    import casadi as ca

    n = rates.size1_in(0)
    columns = mapped_columns(rates, [0, 1], n, "tangent_columns")
    a, q_hat, v_hat = (ca.MX.sym(label, n) for label in ("a", "q_hat", "v_hat"))
    w, g, t = ca.MX.sym("w"), ca.MX.sym("g"), ca.MX.sym("t")
    u, p, c, s = (ca.MX.sym(rates.name_in(i), rates.sparsity_in(i)) for i in (2, 3, 5, 6))
    q, v = q_hat + w * a, v_hat + g * a
    value = rates(q, v, u, p, t, c, s)
    tangent = ca.MX.eye(n) - columns(q, v, u, p, t, c, s, w * ca.DM.eye(n), g * ca.DM.eye(n))
    return ca.Function("residual", [a, q_hat, v_hat, w, g, t, u, p, c, s], [a - value, tangent])


def tangent_construction(owner: str, tangent: str | None, coordinates: int, sweep: str | None = None,
                         minimum: int = MAPPED_MIN_COORDINATES) -> str:
    """``"mapped"``, ``"symbolic"`` or ``"sweep"``: how ``owner``'s generated Newton step forms its tangent.

    ``sweep``: ``None`` where the implicit-sweep iteration (:mod:`ctmm.compiled_sweep_newton`, planar schemes) is
    no choice, ``""`` where it applies, else why it does not (:func:`ctmm.compiled_sweep_newton.sweep_refusal`).
    ``tangent=None`` chooses by size: from ``minimum`` coordinates (:data:`MAPPED_MIN_COORDINATES`; spatial steps
    :data:`SPATIAL_MAPPED_MIN_VELOCITIES`) the sweep where it applies (O(N) per iteration) or else the mapped
    tangent; below it the symbolic Jacobian.

    Raises
    ------
    ModelError
        ``tangent`` not one of those or ``None``; ``"sweep"`` where it does not apply (naming why).
    """
    if tangent is None:
        if coordinates < minimum:
            return "symbolic"
        return "sweep" if sweep == "" else "mapped"
    if tangent == "sweep" and sweep:
        raise ModelError(f"{owner}: tangent='sweep' is not for a model with {sweep}; use tangent='mapped' or "
                         "'symbolic'")
    if tangent not in ("mapped", "symbolic") + (() if sweep is None else ("sweep",)):
        raise ModelError(f"{owner}: tangent must be 'mapped' (forward derivatives of the sweep, code O(N)), "
                         + ("" if sweep is None else "'sweep' (one implicit articulated sweep per iteration, O(N)), ")
                         + f"'symbolic' (symbolic Jacobian) or None (by size), got {tangent!r}")
    return tangent


def weighted_residual_terms(sweep: Any, n_inputs: int) -> Any:
    """``residual(a, q_hat, v_hat, w, g, t, u, p, c, s) -> (r, J)`` of the mass-weighted Newton step
    (:mod:`ctmm.compiled_newton_weighting`) from one sweep ``sweep(q, v, [u; f], p, t) -> qddot`` whose inputs are
    the ``n_inputs`` actuator values ``u`` followed by unit generalised forces ``f`` (one per coordinate).

    ``r = a - qddot(q, v, [u; 0])`` at ``q = q_hat + w a``, ``v = v_hat + g a``; ``G = d qddot/df`` (forward
    derivatives along the unit forces), ``f = G^-1 r`` (QR); since ``qddot`` is affine in ``f`` with ``G`` a
    function of ``q`` alone, the weighted tangent ``I - w d qddot/dq - g d qddot/dv - w d(G f)/dq`` is
    ``I - w d qddot(q, v, [u; f])/dq - g d qddot(q, v, [u; f])/dv``: one mapped forward derivative of the sweep at
    the shifted forces.  ``c``, ``s`` (loop controller entries, time since the step start) are not read.
    """
    import casadi as ca

    n = sweep.size1_in(0)
    along_inputs = mapped_columns(sweep, [2], n, "inverse_mass_columns")
    along_state = mapped_columns(sweep, [0, 1], n, "tangent_columns")
    a, q_hat, v_hat = (ca.MX.sym(label, n) for label in ("a", "q_hat", "v_hat"))
    w, g, t = ca.MX.sym("w"), ca.MX.sym("g"), ca.MX.sym("t")
    u, p = ca.MX.sym("u", n_inputs), ca.MX.sym("p", sweep.sparsity_in(3))
    c, s = ca.MX.sym("c", 0), ca.MX.sym("s")
    q, v = q_hat + w * a, v_hat + g * a
    plain = ca.vertcat(u, ca.MX.zeros(n))
    residual = a - sweep(q, v, plain, p, t)
    unit_forces = ca.DM(ca.vertcat(ca.DM.zeros(n_inputs, n), ca.DM.eye(n)))
    forces = ca.solve(along_inputs(q, v, plain, p, t, unit_forces), residual, "qr")
    tangent = ca.MX.eye(n) - along_state(q, v, ca.vertcat(u, forces), p, t, w * ca.DM.eye(n), g * ca.DM.eye(n))
    return ca.Function("weighted_residual", [a, q_hat, v_hat, w, g, t, u, p, c, s], [residual, tangent])
