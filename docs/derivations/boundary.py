"""Derivation of the boundary relations (docs/elements/boundary.md).

A chain ``[start, e_1 .. e_N, end]`` has state vectors ``z_0 .. z_N``; ``f`` is the force exerted
by the inboard part on the outboard part.  At the start the inboard part is the support, at the
end the outboard part is.  The boundary relations are derived with sympy from the support's
physics and compared with :mod:`ctmm.elements.boundary`:

* start: the known half as an affine function of the unknown half, ``z_f = S0 z_e + P0``;
* end: linear conditions ``Bm z_N = b``.

Frequency domain: deviations from equilibrium, Laplace variable ``s``.  Time domain (DT-TMM):
absolute values at the step's evaluation level, ``x_eval = cx x + dx``, ``v_eval = A x + B``.

Run ``python docs/derivations/boundary.py``; ``tests/test_derivations.py`` runs every ``check_*``.
"""
from __future__ import annotations

import numpy as np
import sympy as sp

from ctmm.elements.base import Linearisation
from ctmm.elements.boundary import Elastic, Fixed, Free, PrescribedDisplacement, PrescribedForce
from ctmm.layouts import AXIAL, BENDING


def solve_linear(equations, unknowns) -> dict:
    """Solve equations that are linear in ``unknowns`` (a unique solution is asserted)."""
    if isinstance(equations, sp.Eq):
        equations = [equations]
    unknowns = list(unknowns) if isinstance(unknowns, (list, tuple)) else [unknowns]
    matrix, rhs = sp.linear_eq_to_matrix([e.lhs - e.rhs for e in equations], unknowns)
    assert matrix.shape[0] == matrix.shape[1] and sp.cancel(matrix.det()) != 0, \
        f"equations do not determine {unknowns} uniquely"
    sol = matrix.LUsolve(rhs)
    return {q: sp.cancel(v) for q, v in zip(unknowns, sol)}


x, f = sp.symbols("x f")
k, c, s, X, F, anchor = sp.symbols("k c s X F anchor")
cx, A, dx, B, xp = sp.symbols("c_x A dx B x_p")
position = sp.Symbol("position")

S_VALUES = np.array([0.5j, 7.0j, -0.2 + 1.5j])


# -- physics ----------------------------------------------------------------------------------
# Force exerted ON the chain's end point by the support (+x), as a function of the end point's
# displacement x and velocity v, for each support type.
def support_force(kind, disp, vel):
    return {"fixed": None, "free": sp.Integer(0), "elastic": -k * (disp - anchor) - c * vel,
            "prescribed_force": F, "prescribed_displacement": None}[kind]


def _known_position(kind, predictor):
    """Displacement-type support: the displacement at the unknown's time, predictor + x, is given."""
    return sp.Eq(predictor + x, X if kind == "prescribed_displacement" else position)


def start_relation(kind, disp, vel, predictor=0):
    """Start: the support is the inboard part, so f_0 = (force by the support on the chain)."""
    force = support_force(kind, disp, vel)
    if force is None:                       # displacement known, f_0 unknown
        return _known_position(kind, predictor)
    return sp.Eq(f, force)


def end_relation(kind, disp, vel, predictor=0):
    """End: the support is the outboard part, f_N = force by the chain ON the support
    = -(force by the support on the chain) (Newton's third law)."""
    force = support_force(kind, disp, vel)
    if force is None:
        return _known_position(kind, predictor)
    return sp.Eq(f, -force)


def start_coefficients(eq):
    """(S0, P0) of z_f = S0 z_e + P0 from a start relation (known half solved for)."""
    if eq.lhs.has(x):                       # displacement known: x = P0, independent of f
        return sp.Integer(0), solve_linear(eq, x)[x]
    rhs = sp.expand(eq.rhs)
    return rhs.coeff(x), rhs.subs(x, 0)


def end_coefficients(eq):
    """(Bm = [b_x, b_f], b) of b_x x + b_f f = b."""
    expr = sp.expand(eq.lhs - eq.rhs)
    bx, bf = expr.coeff(x), expr.coeff(f)
    return [bx, bf], -expr.subs({x: 0, f: 0})


def _frequency(kind):
    # deviations: anchor and constant loads vanish; v = s x; X, F are input phasors
    start = start_relation(kind, x, s * x).subs({anchor: 0, position: 0})
    end = end_relation(kind, x, s * x).subs({anchor: 0, position: 0})
    return start_coefficients(start), end_coefficients(end)


def _discrete(kind):
    start = start_relation(kind, cx * x + dx, A * x + B, xp)
    end = end_relation(kind, cx * x + dx, A * x + B, xp)
    return start_coefficients(start), end_coefficients(end)


CASES = {
    "fixed": (lambda: Fixed("b", position=0.3), {position: 0.3}, {}),
    "free": (lambda: Free("b"), {}, {}),
    "elastic": (lambda: Elastic("b", 120.0, damping=0.9, anchor=-0.2), {k: 120.0, c: 0.9, anchor: -0.2}, {}),
    "prescribed_force": (lambda: PrescribedForce("b", 7.5), {F: 7.5}, {"force": 2.0 - 0.5j}),
    "prescribed_displacement": (lambda: PrescribedDisplacement("b", 0.04), {X: 0.04},
                                {"displacement": 0.01 + 0.02j}),
}


def _c(expr, values):
    return complex(sp.sympify(expr).xreplace({sp.sympify(k): sp.sympify(v) for k, v in values.items()}))


# -- checks ---------------------------------------------------------------------------------
def check_frequency_domain():
    """start()/end() equal the derived relations, for the axial and the bending layout."""
    for kind, (make, params, phasors) in CASES.items():
        (S0, P0), (Bm, b) = _frequency(kind)
        for layout in (AXIAL, BENDING):
            boundary = make()
            e_idx, S0_num, P0_num = boundary.start(layout, S_VALUES, phasors)
            Bm_num, b_num = boundary.end(layout, S_VALUES, phasors)
            d = layout.half
            known_x = kind in ("fixed", "prescribed_displacement")
            assert e_idx == (list(range(d, 2 * d)) if known_x else list(range(d))), (kind, e_idx)
            for idx, sv in enumerate(S_VALUES):
                values = {**{p: v for p, v in params.items() if p not in (anchor, position)}, s: sv,
                          X: phasors.get("displacement", 0), F: phasors.get("force", 0)}
                for i in range(d):
                    assert np.isclose(S0_num[idx, i, i], _c(S0, values)), (kind, "S0")
                    assert np.isclose(P0_num[idx, i], _c(P0, values)), (kind, "P0", P0_num[idx, i], P0)
                    assert np.isclose(Bm_num[idx, i, i], _c(Bm[0], values)), (kind, "Bm_x")
                    assert np.isclose(Bm_num[idx, i, d + i], _c(Bm[1], values)), (kind, "Bm_f")
                    assert np.isclose(b_num[idx, i], _c(b, values)), (kind, "b", b_num[idx, i], b)
                off = Bm_num[idx].copy()
                for i in range(d):
                    off[i, i] = off[i, d + i] = 0
                assert np.all(off == 0), (kind, "pairs are independent")


def check_discrete():
    """start_discrete()/end_discrete() equal the derived DT-TMM relations."""
    rng = np.random.default_rng(7)
    for kind, (make, params, _) in CASES.items():
        (S0, P0), (Bm, b) = _discrete(kind)
        for _ in range(3):
            lin = Linearisation(rng.uniform(0.5, 1), rng.normal(), rng.uniform(10, 1e3), rng.normal(),
                                rng.uniform(1e3, 1e6), rng.normal(), rng.normal())
            boundary = make()
            t = 0.37
            _, S0_num, P0_num = boundary.start_discrete(AXIAL, t, lin)
            Bm_num, b_num = boundary.end_discrete(AXIAL, t, lin)
            values = {**params, cx: lin.cx, dx: lin.dx, A: lin.A, B: lin.B, xp: lin.xp}
            assert np.isclose(S0_num[0, 0], _c(S0, values)), (kind, "S0")
            assert np.isclose(P0_num[0], _c(P0, values)), (kind, "P0", P0_num[0], P0)
            assert np.isclose(Bm_num[0, 0], _c(Bm[0], values)), (kind, "Bm_x")
            assert np.isclose(Bm_num[0, 1], _c(Bm[1], values)), (kind, "Bm_f")
            assert np.isclose(b_num[0], _c(b, values)), (kind, "b", b_num[0], b)


def check_closed_forms():
    """The table of docs/elements/boundary.md."""
    (S0, P0), (Bm, b) = _frequency("elastic")
    assert (sp.cancel(S0 + k + c * s), P0) == (0, 0)
    assert sp.cancel(Bm[0] + k + c * s) == 0 and Bm[1] == 1 and b == 0
    (S0, P0), (Bm, b) = _frequency("prescribed_force")
    assert (S0, P0, Bm, b) == (0, F, [0, 1], -F)
    (S0, P0), (Bm, b) = _discrete("elastic")
    assert sp.cancel(S0 + k * cx + c * A) == 0
    assert sp.cancel(P0 + k * (dx - anchor) + c * B) == 0
    assert sp.cancel(Bm[0] + k * cx + c * A) == 0 and Bm[1] == 1
    assert sp.cancel(b - k * (dx - anchor) - c * B) == 0


CHECKS = [check_closed_forms, check_frequency_domain, check_discrete]


if __name__ == "__main__":
    for kind in CASES:
        print(f"{kind:24s} frequency: start (S0, P0) = {_frequency(kind)[0]}, end (Bm, b) = {_frequency(kind)[1]}")
        print(f"{'':24s} DT-TMM:    start (S0, P0) = {_discrete(kind)[0]}, end (Bm, b) = {_discrete(kind)[1]}")
    for check in CHECKS:
        check()
        print("ok", check.__name__)
