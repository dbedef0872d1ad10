"""Time integration of models with modal beams (RK4 order 4, implicit DT-TMM order 2, Newton
convergence) and the finite-segment beam (second-order convergence with the 2EI/l root spring)."""
from __future__ import annotations

import math

import numpy as np
import pytest

import ctmm
from ctmm.errors import ModelError
from ctmm.flexible import ModalBeam
from ctmm.flexible.segments import finite_segment_beam
from ctmm.planar import (Fixed, Load, Pinned, PlanarModel, RigidBody, simulate_implicit,
                         simulate_rk4, simulate_scipy)
from ctmm.planar.elements import FixedMounting
from ctmm.reference.beams import beta_roots
from ctmm.schemes import GeneralizedAlpha, Newmark


@pytest.fixture(scope="module")
def hub_beam_tip():
    beam = ModalBeam("b", length=1.3, bending_stiffness=5.0, mass_per_length=0.7, n_modes=3,
                     n_axial_modes=1, axial_stiffness=300.0, damping_ratio=0.02,
                     loads=(Load(point=(0.7, 0.0), force_x=0.3, force_y=lambda t: math.sin(t),
                                 moment=0.2),))
    model = PlanarModel.chain("m", [
        Pinned("o"), RigidBody("hub", mass=2.0, inertia=0.1, center_of_mass=(0.05, 0.02),
                               outboard=(0.2, 0.0)),
        FixedMounting("mount", angle=0.3), beam, FixedMounting("m2"),
        RigidBody("tip", mass=0.2, inertia=0.01, center_of_mass=(0.03, 0.01),
                  outboard=(0.1, 0.0))])
    n = model.n_coordinates
    q0, v0 = np.zeros(n), np.zeros(n)
    q0[:2], v0[0] = (0.3, 0.02), 2.0
    T = 0.3
    # the ODE itself equals the Lagrange model (test_flexible_beam); the order reference is its
    # DOP853 solution at tight tolerance (the Lagrange model's own solve_ivp takes ~40 s here)
    ref = simulate_scipy(model, q0, v0, t_final=T, method="DOP853", rtol=1e-12,
                         atol=1e-13).q[-1]
    return model, q0, v0, T, ref


def test_rk4_is_fourth_order(hub_beam_tip):
    model, q0, v0, T, ref = hub_beam_tip
    err = [np.max(np.abs(simulate_rk4(model, q0, v0, t_final=T, dt=h).q[-1] - ref))
           for h in (2e-3, 1e-3)]
    assert 3.5 < math.log2(err[0] / err[1]) < 4.5


def test_implicit_newmark_is_second_order_with_quadratic_newton(hub_beam_tip):
    model, q0, v0, T, ref = hub_beam_tip
    err, its = [], []
    for h in (3e-3, 1.5e-3):
        sim = simulate_implicit(model, q0, v0, t_final=T, dt=h, scheme=Newmark())
        err.append(np.max(np.abs(sim.q[-1] - ref)))
        its.append(sim.iterations.mean())
    assert 1.75 < math.log2(err[0] / err[1]) < 2.25
    assert max(its) <= 3.05                       # quadratic: 3 sweeps to 1e-10


def test_generalized_alpha_converges(hub_beam_tip):
    model, q0, v0, T, ref = hub_beam_tip
    sim = simulate_implicit(model, q0, v0, t_final=T, dt=3e-3, scheme=GeneralizedAlpha(0.8))
    assert np.max(np.abs(sim.q[-1] - ref)) < 1e-3
    assert sim.iterations.max() <= 4


def _fs_frequencies(n, factor):
    model = PlanarModel.chain("fs", [Fixed("g")] + finite_segment_beam(
        "s", length=1.0, bending_stiffness=2.0, mass_per_length=0.5, n_segments=n,
        root_spring_factor=factor), gravity=(0.0, 0.0))
    return ctmm.natural_frequencies(model, n_modes=3, operating_point=(np.zeros(n),) * 2)


def test_finite_segments_converge_at_second_order_with_the_2EI_over_l_root_spring():
    exact = beta_roots("clamped-free", 3) ** 2 * math.sqrt(2.0 / 0.5)
    e10 = _fs_frequencies(10, 2.0) / exact - 1
    e20 = _fs_frequencies(20, 2.0) / exact - 1
    # FORMULAS 3.7 (check c08): N = 20: -0.115 %, -0.397 %, -0.650 %
    assert np.allclose(100 * e20, [-0.115, -0.397, -0.650], atol=0.001)
    assert np.all(np.abs(np.log2(e10 / e20) - 2.0) < 0.05)
    f10 = _fs_frequencies(10, 1.0) / exact - 1
    f20 = _fs_frequencies(20, 1.0) / exact - 1
    assert np.all(np.abs(np.log2(f10 / f20) - 1.0) < 0.15)         # EI/l root: first order


@pytest.mark.parametrize("kwargs, match", [
    (dict(n_segments=0), "n_segments must be an integer >= 1"),
    (dict(bending_stiffness=0.0), "bending_stiffness must be > 0"),
    (dict(mass_per_length=-1.0), "mass_per_length must be > 0"),
    (dict(root="free"), "root must be one of"),
])
def test_finite_segment_bad_input(kwargs, match):
    params = dict(length=1.0, bending_stiffness=1.0, mass_per_length=1.0, n_segments=4)
    params.update(kwargs)
    with pytest.raises(ModelError, match=match):
        finite_segment_beam("s", **params)


def test_implicit_with_hinges_at_beam_ends_matches_the_ode():
    """Motor -> beam -> fixed mounting -> beam -> elastic/damper hinge at the tip -> link: the
    implicit hinge law (kappa on the relative acceleration to the beam end's slope rate) and the
    complex-step tangent give Newmark's second order against the ODE solution."""
    from ctmm.planar import DrivenHinge, RigidBody, SpringDamperHinge
    beam = lambda name, **kw: ModalBeam(name, length=0.8, bending_stiffness=4.0,  # noqa: E731
                                        mass_per_length=0.6, n_modes=2, **kw)
    model = PlanarModel.chain("m", [
        Fixed("g"), DrivenHinge("motor", angle=lambda t: 0.5 * t * t, rate=lambda t: t,
                                acceleration=lambda t: 1.0),
        beam("b1"), FixedMounting("w", angle=0.2), beam("b2", damping_ratio=0.01),
        SpringDamperHinge("e", stiffness=3.0, damping=0.05, rest_angle=0.1),
        RigidBody.uniform_link("l", mass=0.3, length=0.4)])
    n = model.n_coordinates
    q0, v0 = np.zeros(n), np.zeros(n)
    q0[-1] = 0.4
    T = 0.2
    ref = simulate_scipy(model, q0, v0, t_final=T, method="DOP853", rtol=1e-12,
                         atol=1e-13).q[-1]
    err = [np.max(np.abs(simulate_implicit(model, q0, v0, t_final=T, dt=h).q[-1] - ref))
           for h in (4e-3, 2e-3)]
    assert 1.7 < math.log2(err[0] / err[1]) < 2.3
