"""Derivation of the DT-TMM integrator linearisations and their orders (docs/schemes.md).

Every scheme of :mod:`ctmm.schemes` expresses the kinematics at its *evaluation level* as
affine functions of the step's unknown displacement ``x``:

    x_eval = cx x + dx,   v_eval = A x + B,   a_eval = C x + D          (seed 002 Eq. 7.27-7.28)

Here each scheme's defining assumption (difference quotients, Newmark's Taylor relations,
linear acceleration over theta h, cubic interpolation through four points, the generalized-alpha
levels) is written down and solved with sympy for ``(cx, dx, A, B, C, D)``; the result is compared
with ``Scheme.coefficients`` / ``Scheme.update`` at random histories.  The order of accuracy is
derived from the one-step map ``Phi(h)`` of the undamped oscillator ``x'' = -x``: with
``p(z) = det(z I - Phi)`` and the principal roots a simple conjugate pair near ``e^{+-ih}``,
``p(e^{ih}) = O(h^(order + 2))``.  The symbolic ``Phi`` is also compared with the map that the
ctmm code produces.

Run ``python docs/derivations/schemes.py``; ``tests/test_derivations.py`` runs every ``check_*``.
"""
from __future__ import annotations

from functools import lru_cache

import numpy as np
import sympy as sp

from ctmm.schemes import ForwardEuler, GeneralizedAlpha, History, Houbolt, Newmark, WilsonTheta


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


h = sp.Symbol("h", positive=True)
x1 = sp.Symbol("x1")                       # the step's unknown displacement
x0, v0, a0 = sp.symbols("x0 v0 a0")        # history at t_n
xm1, xm2 = sp.symbols("x_m1 x_m2")         # x_{n-1}, x_{n-2} (Houbolt)
beta, gamma, theta, rho = sp.symbols("beta gamma theta rho_inf", positive=True)
v1, a1 = sp.symbols("v1 a1")


def _affine(expr, var=x1):
    expr = sp.expand(expr)
    return sp.cancel(expr.coeff(var)), sp.cancel(expr.subs(var, 0))


# -- derivations of (cx, dx, A, B, C, D) --------------------------------------------------------
@lru_cache(maxsize=None)
def forward_euler():
    """Seed 002 §7.3.2.1: v_{n+1} = (x_{n+1} - x_n)/h, a_{n+1} = (v_{n+1} - v_n)/h."""
    v = (x1 - x0) / h
    a = (v - v0) / h
    return dict(cx=1, dx=0, **dict(zip("AB", _affine(v))), **dict(zip("CD", _affine(a))))


@lru_cache(maxsize=None)
def newmark():
    """Newmark (1959): x_{n+1} = x_n + h v_n + h^2 [(1/2 - beta) a_n + beta a_{n+1}],
    v_{n+1} = v_n + h [(1 - gamma) a_n + gamma a_{n+1}]; solved for a_{n+1}, v_{n+1}."""
    sol = solve_linear([sp.Eq(x1, x0 + h * v0 + h ** 2 * ((sp.Rational(1, 2) - beta) * a0 + beta * a1)),
                        sp.Eq(v1, v0 + h * ((1 - gamma) * a0 + gamma * a1))], [a1, v1])
    return dict(cx=1, dx=0, **dict(zip("AB", _affine(sol[v1]))), **dict(zip("CD", _affine(sol[a1]))))


@lru_cache(maxsize=None)
def wilson_theta():
    """Linear acceleration over tau = theta h; the unknown is x(t_n + tau)."""
    tau = theta * h
    a_tau = sp.Symbol("a_tau")
    # integrate a(t_n + r) = a_n + (a_tau - a_n) r / tau twice from 0 to tau
    r = sp.Symbol("r")
    acc = a0 + (a_tau - a0) * r / tau
    vel = v0 + sp.integrate(acc, (r, 0, r))
    pos = x0 + sp.integrate(vel, (r, 0, r))
    sol = solve_linear([sp.Eq(x1, pos.subs(r, tau))], [a_tau])
    a_expr = sol[a_tau]
    v_expr = vel.subs(r, tau).subs(a_tau, a_expr)
    return dict(cx=1, dx=0, **dict(zip("AB", _affine(v_expr))), **dict(zip("CD", _affine(a_expr))),
                acc=acc, vel=vel, pos=pos, a_tau=a_tau, r=r)


@lru_cache(maxsize=None)
def wilson_update():
    """x, v, a at t_n + h from the same linear acceleration, with a_tau = C x_tau + D."""
    w = wilson_theta()
    a_tau = w["C"] * x1 + w["D"]
    sub = {w["a_tau"]: a_tau, w["r"]: h}
    return w["pos"].subs(sub), w["vel"].subs(sub), w["acc"].subs(sub)


@lru_cache(maxsize=None)
def houbolt():
    """Cubic Lagrange interpolation through x_{n-2}, x_{n-1}, x_n, x_{n+1}; derivatives at t_{n+1}."""
    t = sp.Symbol("t")
    poly = sp.interpolate([(-2 * h, xm2), (-h, xm1), (0, x0), (h, x1)], t)
    v = sp.diff(poly, t).subs(t, h)
    a = sp.diff(poly, t, 2).subs(t, h)
    return dict(cx=1, dx=0, **dict(zip("AB", _affine(v))), **dict(zip("CD", _affine(a))))


alpha_m, alpha_f = sp.symbols("alpha_m alpha_f")


def generalized_alpha_parameters():
    """Chung & Hulbert (1993) in terms of rho_inf: (alpha_m, alpha_f, gamma, beta)."""
    am = (2 * rho - 1) / (rho + 1)
    af = rho / (rho + 1)
    return am, af, sp.Rational(1, 2) - am + af, (1 - am + af) ** 2 / 4


def generalized_alpha_values(rho_value):
    """Substitution {alpha_m, alpha_f, gamma, beta} for a given rho_inf."""
    return {sym: val.subs(rho, rho_value) for sym, val in zip((alpha_m, alpha_f, gamma, beta),
                                                              generalized_alpha_parameters())}


@lru_cache(maxsize=None)
def generalized_alpha():
    """Newmark relations (beta, gamma) for (x_{n+1}, v_{n+1}, a_{n+1}); inertia evaluated at
    t_{n+1-alpha_m}, all other forces at t_{n+1-alpha_f} (symbols alpha_m, alpha_f)."""
    nm = newmark()
    x_eval = (1 - alpha_f) * x1 + alpha_f * x0
    v_eval = (1 - alpha_f) * (nm["A"] * x1 + nm["B"]) + alpha_f * v0
    a_eval = (1 - alpha_m) * (nm["C"] * x1 + nm["D"]) + alpha_m * a0
    return dict(**dict(zip(("cx", "dx"), _affine(x_eval))), **dict(zip("AB", _affine(v_eval))),
                **dict(zip("CD", _affine(a_eval))))


# -- comparison with the code ----------------------------------------------------------------
RNG = np.random.default_rng(11)
PARAMS = {"newmark": (Newmark(0.3, 0.6), {beta: 0.3, gamma: 0.6}),
          "wilson": (WilsonTheta(1.4), {theta: 1.4}),
          "genalpha": (GeneralizedAlpha(0.8), generalized_alpha_values(sp.Rational(4, 5))),
          "euler": (ForwardEuler(), {}),
          "houbolt": (Houbolt(), {})}
DERIVED = {"newmark": newmark, "wilson": wilson_theta, "genalpha": generalized_alpha,
           "euler": forward_euler, "houbolt": houbolt}


def _history(steps=5):
    n = 3
    hist = History(RNG.normal(size=(n, 1)), RNG.normal(size=(n, 1)), RNG.normal(size=(n, 1)),
                   [RNG.normal(size=(n, 1)), RNG.normal(size=(n, 1))], steps)
    return hist


def _evaluation_level(key, params, values, x_new):
    """Derived (x_eval, v_eval, a_eval) and new history (x, v, a) for the unknown-level displacement.

    ``x_new`` is the displacement at the scheme's unknown level: x_{n+1}, or x(t_n + theta h)
    for Wilson-theta.
    """
    d = {k: sp.sympify(v).subs(params) for k, v in DERIVED[key]().items() if k in ("A", "B", "C", "D")}
    sub = {**values, x1: x_new}
    if key == "wilson":
        pos, vel, acc = (e.subs(params).subs(sub) for e in wilson_update())
        ev = (x_new, (d["A"] * x1 + d["B"]).subs(sub), (d["C"] * x1 + d["D"]).subs(sub))
        return ev, (pos, vel, acc)
    if key == "genalpha":
        am, af = params[alpha_m], params[alpha_f]
        nm = {k: sp.sympify(v).subs(params) for k, v in newmark().items()}
        v_new, a_new = (nm["A"] * x1 + nm["B"]).subs(sub), (nm["C"] * x1 + nm["D"]).subs(sub)
        ev = ((1 - af) * x_new + af * values[x0], (1 - af) * v_new + af * values[v0],
              (1 - am) * a_new + am * values[a0])
        return ev, (x_new, v_new, a_new)
    v_new, a_new = (d["A"] * x1 + d["B"]).subs(sub), (d["C"] * x1 + d["D"]).subs(sub)
    return (x_new, v_new, a_new), (x_new, v_new, a_new)


def check_coefficients_equal_code():
    """Scheme.coefficients / update have the derived meaning (random histories, h = 1e-3).

    Formulation-independent: for a random value ``u`` of the code's unknown, the code's
    ``x_eval = cx u + dx``, ``v_eval = A u + B``, ``a_eval = C u + D`` and its updated history must
    equal the derived evaluation-level kinematics and history for the displacement that ``u``
    stands for (whether the code solves for ``x`` itself or for a correction to a predictor).
    """
    hv = 1.0e-3
    for key, (scheme, params) in PARAMS.items():
        hist = _history()
        coeffs = scheme.coefficients(hist, hv)
        u = RNG.normal(size=hist.x.shape) * 1e-3 + (hist.x if not hasattr(coeffs, "x_pred") else 0.0)
        new = scheme.update(hist, u, hv, coeffs)
        for p in range(hist.x.shape[0]):
            pick = lambda q: float(q[p, 0]) if np.ndim(q) else float(q)  # noqa: E731
            code_eval = [pick(coeffs.cx) * u[p, 0] + pick(coeffs.dx), pick(coeffs.A) * u[p, 0] + pick(coeffs.B),
                         pick(coeffs.C) * u[p, 0] + pick(coeffs.D)]
            values = {**params, h: hv, x0: hist.x[p, 0], v0: hist.v[p, 0], a0: hist.a[p, 0],
                      xm1: hist.x_old[0][p, 0], xm2: hist.x_old[1][p, 0]}
            if key == "genalpha":  # x_eval = (1 - af) x_{n+1} + af x_n
                af = float(params[alpha_f])
                x_level = (code_eval[0] - af * hist.x[p, 0]) / (1 - af)
            else:
                x_level = code_eval[0]
            ev, hist_new = _evaluation_level(key, params, values, x_level)
            for have, want, what in zip(code_eval + [new.x[p, 0], new.v[p, 0], new.a[p, 0]],
                                        list(ev) + list(hist_new),
                                        ("x_eval", "v_eval", "a_eval", "x_new", "v_new", "a_new")):
                want = float(sp.N(want, 20))
                assert np.isclose(have, want, rtol=1e-9, atol=1e-9 * max(1.0, abs(want))), \
                    f"{key}.{what}: code {have!r} != derived {want!r}"


def check_closed_forms():
    """The coefficients quoted in docs/schemes.md (and FORMULAS §3.1)."""
    nm = newmark()
    assert sp.cancel(nm["C"] - 1 / (beta * h ** 2)) == 0
    assert sp.cancel(nm["D"] + (x0 + h * v0 + (sp.Rational(1, 2) - beta) * h ** 2 * a0) / (beta * h ** 2)) == 0
    assert sp.cancel(nm["A"] - gamma / (beta * h)) == 0
    assert sp.cancel(nm["B"] - (-gamma / (beta * h) * x0 + (1 - gamma / beta) * v0
                                  + (1 - gamma / (2 * beta)) * h * a0)) == 0
    w = wilson_theta()
    tau = theta * h
    assert sp.cancel(w["C"] - 6 / tau ** 2) == 0 and sp.cancel(w["A"] - 3 / tau) == 0
    assert sp.cancel(w["D"] - (-6 / tau ** 2 * (x0 + tau * v0) - 2 * a0)) == 0
    assert sp.cancel(w["B"] - (-3 / tau * x0 - 2 * v0 - tau / 2 * a0)) == 0
    hb = houbolt()
    assert sp.cancel(hb["C"] - 2 / h ** 2) == 0 and sp.cancel(hb["A"] - sp.Rational(11, 6) / h) == 0
    assert sp.cancel(hb["D"] + (5 * x0 - 4 * xm1 + xm2) / h ** 2) == 0
    assert sp.cancel(hb["B"] + (18 * x0 - 9 * xm1 + 2 * xm2) / (6 * h)) == 0
    fe = forward_euler()
    assert (fe["A"], fe["C"]) == (1 / h, h ** -2)
    assert sp.cancel(fe["D"] + x0 / h ** 2 + v0 / h) == 0
    am, af, g, b = generalized_alpha_parameters()
    assert sp.cancel(g - (sp.Rational(1, 2) - am + af)) == 0
    # rho_inf = 1 gives the trapezoidal rule (alpha_m = alpha_f = 1/2, beta = 1/4, gamma = 1/2)
    assert [sp.cancel(q.subs(rho, 1)) for q in (am, af, g, b)] == [sp.Rational(1, 2)] * 3 + [sp.Rational(1, 4)]


def check_wilson_update_and_loads():
    """WilsonTheta.update and the force interpolation of Wilson-theta / generalized-alpha."""
    hv, th = 2e-3, 1.4
    scheme = WilsonTheta(th)
    hist = _history()
    coeffs = scheme.coefficients(hist, hv)
    u = RNG.normal(size=hist.x.shape)                 # the code's unknown (x_tau or a correction)
    x_tau = coeffs.cx * u + coeffs.dx                 # displacement at the evaluation level t_n + tau
    new = scheme.update(hist, u, hv, coeffs)
    pos, vel, acc = wilson_update()
    for p in range(hist.x.shape[0]):
        values = {theta: th, h: hv, x0: hist.x[p, 0], v0: hist.v[p, 0], a0: hist.a[p, 0], x1: x_tau[p, 0]}
        for expr, have in ((pos, new.x), (vel, new.v), (acc, new.a)):
            want = float(expr.xreplace({k: sp.sympify(v) for k, v in values.items()}))
            assert np.isclose(have[p, 0], want, rtol=1e-10, atol=1e-8 * max(1.0, abs(want))), (have[p, 0], want)
    # internal forces: linear in time between t_n and the evaluation level
    f_n, f_1 = sp.symbols("f_n f_1")
    f_tau = f_n + theta * (f_1 - f_n)                               # Wilson: level t_n + theta h
    inv = solve_linear(sp.Eq(sp.Symbol("fe"), f_tau), f_1)[f_1]
    fe_num, fn_num = 3.2, -1.1
    assert np.isclose(scheme.interpolate_force(np.array(fe_num), np.array(fn_num)),
                      float(inv.subs({sp.Symbol("fe"): fe_num, f_n: fn_num, theta: th})))
    ga = GeneralizedAlpha(0.8)
    am, af, _, _ = generalized_alpha_parameters()
    f_af = (1 - af) * f_1 + af * f_n                                 # generalized-alpha: level n+1-alpha_f
    inv = solve_linear(sp.Eq(sp.Symbol("fe"), f_af), f_1)[f_1]
    assert np.isclose(ga.interpolate_force(np.array(fe_num), np.array(fn_num)),
                      float(inv.subs({sp.Symbol("fe"): fe_num, f_n: fn_num, rho: 0.8})))
    # load weights: F_eval = (1 - w) F_n + w F_{n+1}
    assert np.isclose(scheme.coefficients(hist, hv).load_weight, th)
    assert np.isclose(ga.coefficients(hist, hv).load_weight, float((1 - af).subs(rho, 0.8)))


# -- one-step maps and orders -----------------------------------------------------------------
_MAPS: dict = {}


def symbolic_map(key, params, h_value=None):
    """Phi(h) for x'' = -x: state (x, v, a) (Houbolt: (x_n, x_{n-1}, x_{n-2})); cached.

    With ``h_value`` (a sympy Rational) the map is evaluated exactly at that step.
    """
    cache_key = (key, tuple(sorted((str(k), v) for k, v in params.items())), h_value)
    if cache_key not in _MAPS:
        _MAPS[cache_key] = _symbolic_map(key, params, h_value)
    return _MAPS[cache_key]


def _symbolic_map(key, params, h_value=None):
    sub = dict(params)
    if h_value is not None:
        sub[h] = h_value
    d = {k: sp.sympify(v).subs(sub) for k, v in DERIVED[key]().items() if k in ("cx", "dx", "A", "B", "C", "D")}
    # equation of motion at the evaluation level: a_eval + x_eval = 0, linear in x1
    x_new = -(d["D"] + d["dx"]) / (d["C"] + d["cx"])
    if key == "houbolt":
        state, new = [x0, xm1, xm2], [x_new, x0, xm1]
    elif key == "wilson":
        pos, vel, acc = (e.subs(sub) for e in wilson_update())
        state, new = [x0, v0, a0], [q.subs(x1, x_new) for q in (pos, vel, acc)]
    elif key == "genalpha":
        nm = {k: sp.sympify(v).subs(sub) for k, v in newmark().items()}
        state, new = [x0, v0, a0], [x_new, nm["A"] * x_new + nm["B"], nm["C"] * x_new + nm["D"]]
    else:
        state, new = [x0, v0, a0], [x_new, d["A"] * x_new + d["B"], d["C"] * x_new + d["D"]]
    return sp.Matrix(new).jacobian(sp.Matrix(state))


def code_map(scheme, hv: float, multistep: bool = False) -> np.ndarray:
    """Phi(h) produced by the ctmm scheme for x'' = -x (columns: unit initial states)."""
    cols = []
    for j in range(3):
        e = np.zeros(3)
        e[j] = 1.0
        col = lambda arr: np.array([[arr]])  # noqa: E731
        if multistep:
            hist = History(col(e[0]), col(0.0), col(0.0), [col(e[1]), col(e[2])], 5)
        else:
            hist = History(col(e[0]), col(e[1]), col(e[2]), [col(0.0), col(0.0)], 5)
        c = scheme.coefficients(hist, hv)
        x_new = -(c.D + c.dx) / (c.C + c.cx)
        new = scheme.update(hist, x_new, hv, c)
        cols.append([new.x[0, 0], new.x_old[0][0, 0], new.x_old[1][0, 0]] if multistep
                    else [new.x[0, 0], new.v[0, 0], new.a[0, 0]])
    return np.array(cols).T


def order_of(key, params, steps=(sp.Rational(1, 1000), sp.Rational(1, 10000)), digits: int = 60) -> int:
    """Order p such that p(e^{ih}) = det(e^{ih} I - Phi(h)) = O(h^(p+2)), from two step sizes
    (maps exact in rational arithmetic, determinant with ``digits`` significant digits)."""
    import mpmath as mp

    mp.mp.dps = digits
    res = []
    for hv in steps:
        phi = symbolic_map(key, params, hv)
        mat = mp.matrix([[mp.mpf(int(sp.fraction(e)[0])) / int(sp.fraction(e)[1]) for e in row]
                         for row in phi.tolist()])
        hm = mp.mpf(int(hv.p)) / int(hv.q)
        z = mp.exp(mp.mpc(0, 1) * hm)
        res.append(abs(mp.det(z * mp.eye(mat.rows) - mat)))
    slope = float(mp.log(res[0] / res[1]) / mp.log(mp.mpf(int(steps[0].p)) * int(steps[1].q)
                                                     / (int(steps[0].q) * mp.mpf(int(steps[1].p)))))
    assert abs(slope - round(slope)) < 0.05, f"no clean power law: slope {slope}"
    return int(round(slope)) - 2


ORDER_CASES = [
    ("euler", ForwardEuler(), {}, 1),
    ("newmark", Newmark(0.25, 0.5), {beta: sp.Rational(1, 4), gamma: sp.Rational(1, 2)}, 2),
    ("newmark", Newmark(sp.Rational(3025, 10000), 0.6), {beta: sp.Rational(3025, 10000), gamma: sp.Rational(3, 5)}, 1),
    ("wilson", WilsonTheta(1.4), {theta: sp.Rational(7, 5)}, 2),
    ("genalpha", GeneralizedAlpha(0.8), generalized_alpha_values(sp.Rational(4, 5)), 2),
    ("genalpha", GeneralizedAlpha(0.5), generalized_alpha_values(sp.Rational(1, 2)), 2),
    ("genalpha", GeneralizedAlpha(0.0), generalized_alpha_values(0), 2),
    ("houbolt", Houbolt(), {}, 2),
]


def check_maps_equal_code():
    """The symbolic one-step maps equal the maps the ctmm schemes produce."""
    hv = 0.05  # = 1/20 in the exact map
    for key, scheme, params, _ in ORDER_CASES:
        if isinstance(scheme, Newmark) and not isinstance(scheme.beta, float):
            scheme = Newmark(float(scheme.beta), scheme.gamma)
        phi = np.array(symbolic_map(key, params, sp.Rational(1, 20)).evalf(), dtype=float)
        have = code_map(scheme, hv, multistep=(key == "houbolt"))
        assert np.allclose(have, phi, rtol=1e-10, atol=1e-12), (key, have, phi)


def check_orders():
    """Orders: Forward-Euler 1, Newmark(gamma=1/2) 2 (gamma != 1/2: 1), Wilson-theta 2,
    generalized-alpha 2, Houbolt 2; every scheme reports the same order."""
    for key, scheme, params, expected in ORDER_CASES:
        got = order_of(key, params)
        assert got == expected, f"{key} {params}: order {got}, expected {expected}"
        if key != "newmark" or expected == 2:
            assert scheme.order == expected, (key, scheme.order)


def check_houbolt_startup():
    """Houbolt's first two steps are average-acceleration Newmark steps (2nd-order starter)."""
    hist = _history(steps=0)
    a = Houbolt().coefficients(hist, 1e-3)
    b = Newmark().coefficients(hist, 1e-3)
    for name in ("cx", "A", "C"):
        assert getattr(a, name) == getattr(b, name)
    for name in ("dx", "B", "D"):
        assert np.array_equal(getattr(a, name), getattr(b, name))
    hist.steps = 2
    assert Houbolt().coefficients(hist, 1e-3).C == 2.0 / 1e-6


def check_predictor_form():
    """The code's predictor x_pred is where the book-form acceleration vanishes, x_pred = -D/C,
    and the predictor velocity is v_pred = A x_pred + B; then a = C (x - x_pred) and
    v = v_pred + A (x - x_pred) exactly (Newmark, Wilson-theta, Houbolt, Forward-Euler)."""
    hv = 1e-3
    for key in ("newmark", "wilson", "houbolt", "euler"):
        scheme, params = PARAMS[key]
        derived = {k: sp.sympify(v).subs(params) for k, v in DERIVED[key]().items()}
        x_pred = sp.cancel(-derived["D"] / derived["C"])
        v_pred = sp.cancel(derived["A"] * x_pred + derived["B"])
        hist = _history()
        coeffs = scheme.coefficients(hist, hv)
        if not hasattr(coeffs, "x_pred"):
            return  # book form in the code: nothing to compare
        for p in range(hist.x.shape[0]):
            values = {h: hv, x0: hist.x[p, 0], v0: hist.v[p, 0], a0: hist.a[p, 0],
                      xm1: hist.x_old[0][p, 0], xm2: hist.x_old[1][p, 0]}
            for have, want in ((coeffs.x_pred[p, 0], x_pred), (coeffs.B[p, 0], v_pred)):
                want = float(want.xreplace({k: sp.sympify(v) for k, v in values.items()}))
                assert np.isclose(have, want, rtol=1e-12, atol=1e-12 * max(1.0, abs(want))), (key, have, want)
            # x_eval = x_pred + delta, a_eval = C delta (no cancellation left in the known terms)
            assert coeffs.D[p, 0] == 0.0 and coeffs.dx[p, 0] == coeffs.x_pred[p, 0], key


def check_spectral_radius():
    """Stability on x'' = -x: spectral radius of the code's one-step map for h = 0.1 ... 1000.

    Newmark(1/4, 1/2): exactly 1 (no numerical damping); Wilson-theta(1.4) and Houbolt: <= 1 and
    decaying with h; generalized-alpha: <= 1 and -> rho_inf; the book's "Forward-Euler" (an
    implicit, backward-Euler step): < 1 and -> 0 (strong numerical damping).
    """
    hs = (0.1, 1.0, 10.0, 1000.0)
    radius = {}
    for name, scheme, multistep in (("newmark", Newmark(), False), ("wilson", WilsonTheta(1.4), False),
                                    ("houbolt", Houbolt(), True), ("genalpha", GeneralizedAlpha(0.8), False),
                                    ("euler", ForwardEuler(), False)):
        radius[name] = [float(np.max(np.abs(np.linalg.eigvals(code_map(scheme, hv, multistep))))) for hv in hs]
    assert np.allclose(radius["newmark"], 1.0, atol=1e-12), radius["newmark"]
    for name in ("wilson", "houbolt", "euler"):
        assert all(r <= 1.0 + 1e-12 for r in radius[name]) and radius[name][-1] < 0.95, (name, radius[name])
    assert all(r <= 1.0 + 1e-12 for r in radius["genalpha"]) and abs(radius["genalpha"][-1] - 0.8) < 0.02, radius
    assert radius["euler"][-1] < 1e-2, radius["euler"]
    return radius


CHECKS = [check_closed_forms, check_coefficients_equal_code, check_wilson_update_and_loads,
          check_maps_equal_code, check_orders, check_houbolt_startup, check_predictor_form,
          check_spectral_radius]


if __name__ == "__main__":
    for key, fn in DERIVED.items():
        d = fn()
        print(key, {k: sp.cancel(d[k]) for k in ("cx", "dx", "A", "B", "C", "D")})
    for key, _, params, _ in ORDER_CASES:
        print("order", key, params, order_of(key, params))
    for check in CHECKS:
        check()
        print("ok", check.__name__)
