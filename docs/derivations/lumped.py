"""Derivation of the lumped 1-D element transfer matrices (docs/elements/lumped.md).

Each element's transfer relation ``z_out = U z_in + u`` (``z = [x, f]``, ``f`` = force exerted
by the inboard part on the outboard part, +x) is *derived* here with sympy from the element's
physical equations -- Newton's law for a point, the constitutive law of a massless connector --
and then compared with the matrices that :mod:`ctmm.elements.lumped` returns, in the frequency
domain (Laplace variable ``s``) and in the DT-TMM form (integrator linearisation
``x_eval = cx x + dx``, ``v_eval = A x + B``, ``a_eval = C x + D``).  The relation to the
tension convention ``q = -f`` of FORMULAS §2.1 / §3.2 is checked as well.

Run ``python docs/derivations/lumped.py``; ``tests/test_derivations.py`` runs every ``check_*``.
"""
from __future__ import annotations

import numpy as np
import sympy as sp

from ctmm.elements.base import Linearisation
from ctmm.elements.lumped import Damper, GroundedSpring, Mass, PointElement, Spring, SpringDamper


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


# symbols: inboard state, outboard state, parameters
x_in, f_in, x_out, f_out = sp.symbols("x_in f_in x_out f_out")
m, c, k, l, F, s = sp.symbols("m c k l F s")
cx, A, C = sp.symbols("c_x A C")                       # scheme constants of the step
dx_in, dx_out, B_in, B_out, D_in = sp.symbols("dx_in dx_out B_in B_out D_in")

RNG = np.random.default_rng(20240611)
S_VALUES = np.array([0.3j, 2.0j, 17.0j, -0.4 + 3.0j, 1.5 + 0.0j])


def transfer_from_equations(equations, unknowns=(x_out, f_out), inputs=(x_in, f_in)):
    """Solve the element equations for the outboard state: returns (U, u) as sympy matrices."""
    sol = solve_linear(equations, unknowns)
    out = sp.Matrix([sp.expand(sol[q]) for q in unknowns])
    U = out.jacobian(sp.Matrix(inputs))
    u = (out - U * sp.Matrix(inputs)).applyfunc(sp.cancel)
    return U.applyfunc(sp.cancel), u


def _is_zero(expr) -> bool:
    """True if every entry of a sympy matrix (or an expression) cancels to zero."""
    if isinstance(expr, sp.MatrixBase):
        return all(sp.cancel(e) == 0 for e in expr)
    return sp.cancel(expr) == 0


# -- the element equations ----------------------------------------------------------------
def point_equations(mass, damping, stiffness, force, acc, vel, disp):
    """Point of the chain: kinematics continuous, Newton's law for the point.

    Forces on the point: ``+f_in`` (by the inboard part), ``-f_out`` (reaction of the outboard
    part, on which the point exerts ``f_out``), the external force ``F`` and the grounded
    spring/damper ``-c_g v - k_g x``.
    """
    return [sp.Eq(x_out, x_in),
            sp.Eq(mass * acc, f_in - f_out + force - damping * vel - stiffness * disp)]


def connector_equations(stiffness, damping, free_length, force, dx_rel, dv_rel):
    """Massless connector: equal end forces, constitutive law of the force on the outboard point.

    ``f = -k (x_out - x_in - l) - c (v_out - v_in) + F`` (a stretched connector pulls its outboard
    point back; ``F`` is an actuator acting +F on the outboard and -F on the inboard point).
    """
    return [sp.Eq(f_out, f_in),
            sp.Eq(f_out, -stiffness * (dx_rel - free_length) - damping * dv_rel + force)]


# frequency domain: deviations from the static configuration, e^{st}; x_eval = x, v = s x, a = s^2 x
POINT_FREQ = transfer_from_equations(point_equations(m, c, k, F, s ** 2 * x_in, s * x_in, x_in))
CONNECTOR_FREQ = transfer_from_equations(connector_equations(k, c, 0, F, x_out - x_in, s * (x_out - x_in)))

# DT-TMM: evaluation-level kinematics affine in the step's unknown displacement
POINT_DT = transfer_from_equations(point_equations(
    m, c, k, F, C * x_in + D_in, A * x_in + B_in, cx * x_in + dx_in))
CONNECTOR_DT = transfer_from_equations(connector_equations(
    k, c, l, F, (cx * x_out + dx_out) - (cx * x_in + dx_in), (A * x_out + B_out) - (A * x_in + B_in)))


def _num(expr, values):
    return complex(expr.xreplace({k: sp.sympify(v) for k, v in values.items()}))


def _compare(name, U_sym, u_sym, U_num, u_num, values, rtol=1e-13):
    U_ref = np.array([[_num(U_sym[i, j], values) for j in range(2)] for i in range(2)])
    u_ref = np.array([_num(u_sym[i], values) for i in range(2)])
    scale = max(1.0, np.max(np.abs(U_ref)), np.max(np.abs(u_ref)))
    assert np.allclose(U_num, U_ref, rtol=rtol, atol=rtol * scale), f"{name}: U {U_num} != derived {U_ref}"
    assert np.allclose(u_num, u_ref, rtol=rtol, atol=rtol * scale), f"{name}: u {u_num} != derived {u_ref}"


# -- checks ---------------------------------------------------------------------------------
def check_frequency_domain_closed_forms():
    """The derived matrices have the documented closed forms."""
    U, u = POINT_FREQ
    assert U == sp.Matrix([[1, 0], [-(m * s ** 2 + c * s + k), 1]]), U
    assert u == sp.Matrix([0, F]), u
    U, u = CONNECTOR_FREQ
    assert _is_zero(U - sp.Matrix([[1, -1 / (k + c * s)], [0, 1]])), U
    assert _is_zero(u - sp.Matrix([F / (k + c * s), 0])), u


def check_point_elements_frequency_domain():
    """Mass, GroundedSpring and a general PointElement equal the derivation for several s."""
    cases = [
        (Mass("m", 0.7), {m: 0.7, c: 0, k: 0}),
        (GroundedSpring("g", 250.0, damping=1.3), {m: 0, c: 1.3, k: 250.0}),
        (PointElement("p", mass=0.2, damping=0.05, stiffness=40.0), {m: 0.2, c: 0.05, k: 40.0}),
    ]
    for element, params in cases:
        U_all = element.transfer_matrix(S_VALUES)
        u_all = element.load_vector(S_VALUES, {"force": 2.5 - 1.0j})
        assert U_all.shape == S_VALUES.shape + (2, 2) and u_all.shape == S_VALUES.shape + (2,)
        for idx, sv in enumerate(S_VALUES):
            values = {**params, s: sv, F: 2.5 - 1.0j}
            _compare(element.name, *POINT_FREQ, U_all[idx], u_all[idx], values)


def check_connectors_frequency_domain():
    """Spring, Damper and SpringDamper (incl. the across-connector force) equal the derivation."""
    cases = [
        (Spring("k", 1000.0, free_length=0.1), {k: 1000.0, c: 0}),
        (Damper("c", 3.0), {k: 0, c: 3.0}),
        (SpringDamper("kc", 500.0, 0.8, free_length=0.2), {k: 500.0, c: 0.8}),
    ]
    for element, params in cases:
        U_all = element.transfer_matrix(S_VALUES)
        u_all = element.load_vector(S_VALUES, {"force": 4.0 + 0.5j})
        for idx, sv in enumerate(S_VALUES):
            values = {**params, s: sv, F: 4.0 + 0.5j}
            _compare(element.name, *CONNECTOR_FREQ, U_all[idx], u_all[idx], values)


def check_discrete_closed_forms():
    """The DT-TMM matrices have the documented closed forms."""
    U, u = POINT_DT
    assert _is_zero(U - sp.Matrix([[1, 0], [-(m * C + c * A + k * cx), 1]])), U
    assert _is_zero(u - sp.Matrix([0, F - m * D_in - c * B_in - k * dx_in])), u
    U, u = CONNECTOR_DT
    keff = k * cx + c * A
    assert _is_zero(U - sp.Matrix([[1, -1 / keff], [0, 1]])), U
    expected = (k * l - k * (dx_out - dx_in) - c * (B_out - B_in) + F) / keff
    assert _is_zero(u - sp.Matrix([expected, 0])), u


def check_discrete_elements():
    """The DT-TMM step matrices (derived from the terms, ctmm/elements/axial.py) equal the derivation (random data)."""
    for trial in range(5):
        cxv, Av, Cv = RNG.uniform(0.5, 1.0), RNG.uniform(10, 1e3), RNG.uniform(1e3, 1e6)
        lin_in = Linearisation(cxv, RNG.normal(), Av, RNG.normal(), Cv, RNG.normal())
        lin_out = Linearisation(cxv, RNG.normal(), Av, RNG.normal(), Cv, RNG.normal())
        force = RNG.normal() * 10
        common = {cx: cxv, A: Av, C: Cv, dx_in: lin_in.dx, dx_out: lin_out.dx, B_in: lin_in.B,
                  B_out: lin_out.B, D_in: lin_in.D, F: force}
        point = PointElement("p", mass=0.3, damping=0.7, stiffness=90.0)
        U, u = point.discretize(None).step_matrices(0.0, lin_in, lin_out, force)
        _compare("point", *POINT_DT, U, u, {**common, m: 0.3, c: 0.7, k: 90.0}, rtol=1e-12)
        for element, params in ((Spring("k", 1000.0, free_length=0.1), {k: 1000.0, c: 0, l: 0.1}),
                                (Damper("c", 2.0), {k: 0, c: 2.0, l: 0}),
                                (SpringDamper("kc", 400.0, 0.6, free_length=-0.05), {k: 400.0, c: 0.6, l: -0.05})):
            U, u = element.discretize(None).step_matrices(0.0, lin_in, lin_out, force)
            _compare(element.name, *CONNECTOR_DT, U, u, {**common, **params}, rtol=1e-12)


def check_tension_convention():
    """With q = -f (tension): U_q = T U_f T, T = diag(1, -1), gives FORMULAS §2.1 and §3.2."""
    T = sp.diag(1, -1)
    U, _ = POINT_FREQ
    Uq = T * U.subs({c: 0, k: 0}) * T
    w = sp.symbols("omega", positive=True)
    assert _is_zero(Uq.subs(s, sp.I * w) - sp.Matrix([[1, 0], [-m * w ** 2, 1]]))
    U, _ = CONNECTOR_FREQ
    assert _is_zero(T * U.subs(c, 0) * T - sp.Matrix([[1, 1 / k], [0, 1]]))
    # DT-TMM, affine 3x3 form [x, q, 1] of FORMULAS §3.2 (spring with free length, mass with force)
    T3 = sp.diag(1, -1, 1)

    def affine(Uu):
        U2, u2 = Uu
        return sp.Matrix([[U2[0, 0], U2[0, 1], u2[0]], [U2[1, 0], U2[1, 1], u2[1]], [0, 0, 1]])
    spring = T3 * affine(CONNECTOR_DT).subs({c: 0, cx: 1, dx_in: 0, dx_out: 0, F: 0}) * T3
    assert _is_zero(spring - sp.Matrix([[1, 1 / k, l], [0, 1, 0], [0, 0, 1]])), spring
    mass = T3 * affine(POINT_DT).subs({c: 0, k: 0}) * T3
    assert _is_zero(mass - sp.Matrix([[1, 0, 0], [m * C, 1, m * D_in - F], [0, 0, 1]])), mass


def check_table_7_1_subsystem():
    """Spring + mass subsystem (seed 002 Eq. 7.15-7.17 structure) in the tension convention."""
    T3 = sp.diag(1, -1, 1)

    def affine(Uu):
        U2, u2 = Uu
        return sp.Matrix([[U2[0, 0], U2[0, 1], u2[0]], [U2[1, 0], U2[1, 1], u2[1]], [0, 0, 1]])
    spring = affine(CONNECTOR_DT).subs({c: 0, cx: 1, dx_in: 0, dx_out: 0, F: 0})
    mass = affine(POINT_DT).subs({c: 0, k: 0})
    sub = sp.cancel(T3 * mass.subs(k, 0) * spring * T3)
    # spring stiffness symbol k survives in the spring; the mass has none
    expected = sp.Matrix([[1, 1 / k, l], [m * C, 1 + m * C / k, m * C * l + m * D_in - F], [0, 0, 1]])
    assert _is_zero(sub - expected), sub


CHECKS = [check_frequency_domain_closed_forms, check_point_elements_frequency_domain,
          check_connectors_frequency_domain, check_discrete_closed_forms, check_discrete_elements,
          check_tension_convention, check_table_7_1_subsystem]


if __name__ == "__main__":
    sp.init_printing()
    print("point, frequency domain:  U =", POINT_FREQ[0].tolist(), " u =", list(POINT_FREQ[1]))
    print("connector, frequency:     U =", CONNECTOR_FREQ[0].tolist(), " u =", list(CONNECTOR_FREQ[1]))
    print("point, DT-TMM:            U =", POINT_DT[0].tolist(), " u =", list(POINT_DT[1]))
    print("connector, DT-TMM:        U =", CONNECTOR_DT[0].tolist(), " u =", list(CONNECTOR_DT[1]))
    for check in CHECKS:
        check()
        print("ok", check.__name__)
