"""SpatialBeam(static_shapes=True): the static tip-load shapes are orthonormalised against the modes, so the
modal mass is well conditioned (the raw shapes lie nearly in the modes' span: Gram condition 2.5e9 with four
modes, and the numpy and generated RK4 runs differed by 3e-4 in the modal coordinates), and the physics is
that of the raw basis: an independent assumed-modes Lagrange model of a hub and beam with the raw static
shapes (written here, casadi AD of T and V, no ctmm code) gives the same hub and deflection accelerations."""
from __future__ import annotations

import math

import casadi as ca
import numpy as np

import ctmm
from ctmm.reference.beams import beta_roots, clamped_free_mode
from ctmm.spatial.beam import SpatialBeam
from ctmm.spatial.dynamics import accelerations
from ctmm.spatial.elements import Revolute, SpatialBody, Weld
from ctmm.spatial.model import SpatialModel

L, RHOA, EI, MOUNT, HUB, TIP_MASS, TIP_INERTIA = 1.0, 1.0, 3.0, 0.2, 0.15, 0.2, 0.004


def hub_beam(n_modes: int, *, axial: bool = False, mass_per_length: float = RHOA) -> SpatialModel:
    """Hub on a revolute joint about ``z``, a beam with static shapes bending in ``x-y`` (and ``x-z`` with one
    mode, and an axial mode when ``axial``), a tip body."""
    extra = dict(n_modes_z=1, n_axial_modes=1, axial_stiffness=200.0) if axial else dict(n_modes_z=0)
    beam = SpatialBeam("b", length=L, mass_per_length=mass_per_length, bending_stiffness_y=EI,
                       bending_stiffness_z=4.0, n_modes_y=n_modes, geometric_stiffening=axial, static_shapes=True,
                       **extra)
    return SpatialModel("h", [
        SpatialBody("hub", 2.0, np.diag([0.1, 0.1, HUB]), points={"out": (MOUNT, 0, 0)}),
        Revolute(name="hinge", parent=None, child="hub", axis=(0, 0, 1)),
        beam, Weld(name="mount", parent="hub", child="b", point="out"),
        SpatialBody("tip", mass=TIP_MASS, inertia=np.diag([0.002, 0.003, TIP_INERTIA])),
        Weld(name="w", parent="b", child="tip", point="tip")], gravity=(0, 0, -9.81) if axial else (0, 0, 0))


def raw_shapes(n_modes: int, x: np.ndarray, derivative: int = 0) -> np.ndarray:
    """Clamped-free modes and the raw tip-force and tip-moment shapes ``(3 xi^2 - xi^3)/2``, ``xi^2``."""
    xi = x / L
    modes = [clamped_free_mode(b, xi, derivative) / L ** derivative for b in beta_roots("clamped-free", n_modes)]
    static = [((3 * xi ** 2 - xi ** 3) / 2, (3 * xi - 1.5 * xi ** 2) / L, (3 - 3 * xi) / L ** 2)[derivative],
              (xi ** 2, 2 * xi / L, 2 * np.ones_like(xi) / L ** 2)[derivative]]
    return np.array(modes + static)


def reference_accelerations(n_modes: int, theta_rate: float, c: np.ndarray, c_rate: np.ndarray) -> np.ndarray:
    """``[theta'', c'']`` of the planar hub + beam + tip body in the raw basis (Lagrange, casadi AD)."""
    n = n_modes + 2
    q, u = ca.SX.sym("q", n + 1), ca.SX.sym("u", n + 1)
    xg, wg = np.polynomial.legendre.leggauss(40)
    x, w = (xg + 1) / 2 * L, wg / 2 * L
    shapes, curvature = raw_shapes(n_modes, x), raw_shapes(n_modes, x, 2)
    R = ca.vertcat(ca.horzcat(ca.cos(q[0]), -ca.sin(q[0])), ca.horzcat(ca.sin(q[0]), ca.cos(q[0])))

    def velocity(point):
        return ca.mtimes(ca.jacobian(point, q), u)

    T = 0.5 * HUB * u[0] ** 2
    for k in range(len(x)):
        v = velocity(ca.mtimes(R, ca.vertcat(MOUNT + x[k], ca.dot(ca.DM(shapes[:, k]), q[1:]))))
        T += 0.5 * RHOA * w[k] * ca.dot(v, v)
    tip = raw_shapes(n_modes, np.array([L]))[:, 0]
    slope = raw_shapes(n_modes, np.array([L]), 1)[:, 0]
    v = velocity(ca.mtimes(R, ca.vertcat(MOUNT + L, ca.dot(ca.DM(tip), q[1:]))))
    T += 0.5 * TIP_MASS * ca.dot(v, v) + 0.5 * TIP_INERTIA * (u[0] + ca.dot(ca.DM(slope), u[1:])) ** 2
    K = EI * (curvature * w) @ curvature.T
    V = 0.5 * ca.mtimes(ca.mtimes(q[1:].T, ca.DM(K)), q[1:])
    M = ca.jacobian(ca.jacobian(T, u), u)
    rhs = ca.jacobian(T - V, q).T - ca.mtimes(ca.jacobian(ca.jacobian(T, u).T, q), u)
    f = ca.Function("f", [q, u], [M, rhs])
    Mn, rn = f(np.concatenate([[0.3], c]), np.concatenate([[theta_rate], c_rate]))
    return np.linalg.solve(np.array(Mn), np.array(rn)).ravel()


def test_static_shapes_are_orthonormal_and_the_modal_mass_well_conditioned():
    beam = hub_beam(6).bodies[1]
    data = beam.data
    x, w = np.polynomial.legendre.leggauss(80)
    x, w = (x + 1) / 2 * L, w / 2 * L
    shapes = data.direction_shapes("y", x)
    assert np.abs((shapes * w) @ shapes.T / L - np.eye(8)).max() < 1e-9
    assert np.linalg.cond(data.modal_mass) < 1.01                    # 4e10 with the raw shapes
    raw = raw_shapes(6, x)
    assert np.abs(shapes[:6] - raw[:6]).max() < 1e-12                 # the modes are unchanged
    fit = np.linalg.lstsq(shapes.T, raw[6:].T, rcond=None)[0]           # the span is the raw shapes'
    assert np.abs(shapes.T @ fit - raw[6:].T).max() < 1e-9


def test_hub_beam_with_static_shapes_equals_the_raw_basis_lagrange_model():
    n = 3
    model = hub_beam(n)
    rng = np.random.default_rng(7)
    c, c_rate = rng.normal(size=n + 2) * 0.05, rng.normal(size=n + 2)
    x = np.linspace(0.0, L, 23)
    shapes = model.bodies[1].data.direction_shapes("y", x)
    raw = raw_shapes(n, x)
    eta, eta_rate = (np.linalg.lstsq(shapes.T, raw.T @ vector, rcond=None)[0] for vector in (c, c_rate))
    found = accelerations(model, np.concatenate([[0.3], eta]), np.concatenate([[1.7], eta_rate]))
    expected = reference_accelerations(n, 1.7, c, c_rate)
    assert abs(found[0] - expected[0]) <= 1e-9 * abs(expected[0])    # hub angular acceleration
    deflection, reference = shapes.T @ found[1:], raw.T @ expected[1:]  # w''(x) along the beam
    assert np.abs(deflection - reference).max() <= 1e-9 * np.abs(reference).max()


def test_accelerations_do_not_amplify_a_round_off_change_of_the_numbers():
    state = np.concatenate([[0.3], np.linspace(0.4, -0.3, 11)]), np.concatenate([[2.0], np.linspace(-1, 1, 11)])
    first = accelerations(hub_beam(4, axial=True), *state)
    second = accelerations(hub_beam(4, axial=True, mass_per_length=RHOA * (1 + 4e-16)), *state)
    assert np.abs(first - second).max() <= 1e-12 * np.abs(first).max()


def test_numpy_and_generated_rk4_agree_with_static_shapes_and_an_axial_mode():
    model = hub_beam(4, axial=True)
    options = dict(method="rk4", v0={"hinge.angle_rate": 3.0}, x0={"b.qy1": 0.01})
    numpy_run = ctmm.simulate(model, 2e-3, 1e-5, **options)
    compiled_run = ctmm.simulate(model, 2e-3, 1e-5, compiled=True, **options)
    for name in model.coordinates:
        a, b = np.asarray(numpy_run[name]), np.asarray(compiled_run[name])
        assert np.abs(a - b).max() <= 1e-11 * max(np.abs(a).max(), 1e-6), name
    assert math.isfinite(float(numpy_run["b.qy_force"][-1]))
