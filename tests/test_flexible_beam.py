"""Modal planar beam: TMM sweep vs the independent assumed-modes Lagrange model, frequencies,
spin-up against Kane-Ryan-Banerjee, divergence without stiffening, energy, bad input."""
from __future__ import annotations

import math

import numpy as np
import pytest

from ctmm.errors import ModelError, SimulationError
from ctmm.guard import StabilityLimitWarning
from ctmm.flexible import ModalBeam, ModalForce, ModeSet, solve_flexible
from ctmm.flexible.outputs import tip_deflection
from ctmm.planar import (DrivenHinge, ElasticHinge, Fixed, FreeBase, Load, Pinned, PlanarModel,
                         RigidBody, SmoothHinge, accelerations, simulate_rk4)
from ctmm.planar.elements import FixedMounting
from ctmm.reference.beams import beta_roots, kane_spinup, spinup_angle
from ctmm.reference.flexible_lagrange import FlexibleLagrange


def _beam(name, **kw):
    return ModalBeam(name, length=1.3, bending_stiffness=5.0, mass_per_length=0.7, n_modes=3, **kw)


def _hub():
    return RigidBody("hub", mass=2.0, inertia=0.1, center_of_mass=(0.05, 0.02),
                     outboard=(0.2, 0.0))


MODELS = {
    # hub + beam (+ tip body), motor = pinned hub; loads, damping, axial modes, stiffening
    "hub_beam": lambda: PlanarModel.chain("m1", [Pinned("o"), _hub(), FixedMounting("mount"),
                                                 _beam("b")]),
    "hub_beam_tip": lambda: PlanarModel.chain("m2", [
        Pinned("o"), _hub(), FixedMounting("mount", angle=0.3),
        _beam("b", n_axial_modes=2, axial_stiffness=300.0, damping_ratio=0.02,
              stiffness_damping=1e-3, distributed_load=(0.4, -0.2),
              loads=(Load(point=(0.7, 0.0), force_x=0.3, force_y=lambda t: math.sin(t),
                          moment=0.2),)),
        FixedMounting("m2"),
        RigidBody("tip", mass=0.2, inertia=0.01, center_of_mass=(0.03, 0.01),
                  outboard=(0.1, 0.0))]),
    # motor with angle driver -> beam -> flexible/flexible mounting -> beam -> hinge -> link
    "driven_chain": lambda: PlanarModel.chain("m3", [
        Fixed("g"), DrivenHinge("motor", angle=lambda t: 0.3 * t * t, rate=lambda t: 0.6 * t,
                                acceleration=lambda t: 0.6),
        _beam("b1"), FixedMounting("w"), _beam("b2", n_axial_modes=1, axial_stiffness=100.0),
        ElasticHinge("e", stiffness=3.0, rest_angle=0.2),
        RigidBody.uniform_link("l", mass=0.3, length=0.5)]),
    "floating": lambda: PlanarModel.chain("m4", [FreeBase("f"), _beam("b1"), SmoothHinge("h"),
                                                 _beam("b2", geometric_stiffening=False)]),
    # tree: a beam with an intermediate end carrying a hinged link, tip carrying a beam
    "tree": lambda: PlanarModel("m5", [
        Pinned("o", child="b1"),
        _beam("b1", outboard={"mid": 0.6, "tip": 1.3}),
        SmoothHinge("h", parent="b1.mid", child="l"),
        RigidBody.uniform_link("l", mass=0.4, length=0.7),
        FixedMounting("w", parent="b1.tip", child="b2", angle=-0.4),
        _beam("b2")]),
}


@pytest.mark.parametrize("name", sorted(MODELS))
def test_modal_accelerations_and_end_forces_equal_lagrange(name):
    model = MODELS[name]()
    reference = FlexibleLagrange(model)
    rng = np.random.default_rng(abs(hash(name)) % 2 ** 32)
    for _ in range(3):
        q = 0.3 * rng.normal(size=model.n_coordinates)
        v = rng.normal(size=model.n_coordinates)
        t = float(rng.uniform(0.0, 2.0))
        sol = solve_flexible(model, q, v, t)
        a_ref = reference.accelerations(q, v, t)
        f_ref = reference.joint_forces(q, v, t)
        assert np.max(np.abs(sol.qddot - a_ref)) <= 1e-10 * np.max(np.abs(a_ref))
        assert np.max(np.abs(sol.joint_force - f_ref)) <= 1e-10 * np.max(np.abs(f_ref))
        assert np.allclose(accelerations(model, q, v, t), sol.qddot, rtol=0, atol=1e-12)


def _frequencies(model):
    n = model.n_coordinates
    z = np.zeros(n)
    A = np.zeros((n, n))
    for i in range(n):
        e = np.zeros(n)
        e[i] = 1e-6
        A[:, i] = (accelerations(model, e, z) - accelerations(model, -e, z)) / 2e-6
    return np.sqrt(np.clip(np.sort(np.real(np.linalg.eigvals(-A))), 0.0, None))


def test_cantilever_modal_frequencies_are_exact():
    model = PlanarModel.chain("c", [Fixed("g"), ModalBeam("b", length=2.0, bending_stiffness=3.0,
                                                           mass_per_length=0.4, n_modes=4)],
                              gravity=(0.0, 0.0))
    exact = beta_roots("clamped-free", 4) ** 2 * math.sqrt(3.0 / 0.4 / 2.0 ** 4)
    assert np.allclose(_frequencies(model), exact, rtol=1e-8)


def test_frequencies_converge_to_beta_l_with_the_number_of_modes():
    """Tip mass mu = 0.5 (FORMULAS 2.6): the exact mode has tip shear EI w''' = -M w^2 w(L) that
    no clamped-free shape has, expansion coefficients ~ beta_k^-4, so the Rayleigh-Ritz
    frequency error ~ sum_{k>N} k^-4 ~ N^-3.  Hub inertia eta = 0.1: much faster (~N^-7)."""
    L, EI, rA = 1.0, 2.0, 0.5
    scale = math.sqrt(EI / rA / L ** 4)
    tip = beta_roots("tip-mass", 1, tip_mass_ratio=0.5)[0] ** 2 * scale
    hub = beta_roots("hub-beam", 1, hub_inertia_ratio=0.1)[0] ** 2 * scale
    err_tip, err_hub = [], []
    for n in (4, 8):
        beam = ModalBeam("b", length=L, bending_stiffness=EI, mass_per_length=rA, n_modes=n)
        m = PlanarModel.chain("tm", [Fixed("g"), beam, FixedMounting("w"),
                                     RigidBody("tip", mass=0.5 * rA * L, inertia=1e-12,
                                               outboard=(0.0, 0.0))], gravity=(0.0, 0.0))
        err_tip.append(_frequencies(m)[0] / tip - 1)
        m = PlanarModel.chain("hb", [Pinned("o"), RigidBody("hub", mass=1.0, inertia=0.1 * rA,
                                                            outboard=(0.0, 0.0)),
                                     FixedMounting("w"), beam], gravity=(0.0, 0.0))
        err_hub.append(_frequencies(m)[1] / hub - 1)
    assert all(e > 0 for e in err_tip + err_hub)          # Rayleigh-Ritz: from above
    assert 2.7 < math.log2(err_tip[0] / err_tip[1]) < 3.3
    assert math.log2(err_hub[0] / err_hub[1]) > 6.0
    assert err_tip[1] < 2e-5 and err_hub[1] < 1e-8


def _spinup_model(stiffening: bool, n_modes: int = 3):
    law = lambda k: (lambda t: float(spinup_angle(t)[k]))  # noqa: E731
    beam = ModalBeam("beam", length=10.0, bending_stiffness=1.4e4, mass_per_length=1.2,
                     n_modes=n_modes, geometric_stiffening=stiffening)
    return PlanarModel.chain("spin", [Fixed("g"), DrivenHinge("motor", angle=law(0), rate=law(1),
                                                              acceleration=law(2)), beam],
                             gravity=(0.0, 0.0))


def test_spin_up_tip_deflection_matches_kane_ryan_banerjee_and_diverges_unstiffened():
    model = _spinup_model(True, n_modes=2)
    sim = simulate_rk4(model, np.zeros(2), np.zeros(2), t_final=20.0, dt=0.02)
    tip = tip_deflection(model, sim.q, "beam")
    ref = kane_spinup(n_modes=2, t_eval=sim.t)
    assert np.max(np.abs(tip - ref.tip_deflection)) < 2e-3
    assert np.max(np.abs(tip - ref.tip_deflection)) < 1e-4          # same model: RK4 error only
    assert -0.6 < tip.min() < -0.4 and np.max(np.abs(tip[sim.t > 16])) < 0.1
    with pytest.raises(SimulationError, match="model itself is unstable") as info:
        simulate_rk4(_spinup_model(False, 2), np.zeros(2), np.zeros(2), t_final=20.0, dt=0.02)
    assert info.value.time > 8.0          # after theta' passes omega_1 = 3.80 rad/s (t = 8.5 s)


def test_too_large_explicit_step_is_reported():
    model = PlanarModel.chain("c", [Fixed("g"), ModalBeam("b", length=1.0, bending_stiffness=50.0,
                                                           mass_per_length=0.5, n_modes=3)])
    q0 = np.array([0.01, 0.0, 0.0])
    # before the run: omega_max of the linearisation is the third cantilever mode,
    # beta_3^2 sqrt(EI / (rho A L^4)) = 7.8548^2 * 10 = 617.0 rad/s (FORMULAS 2.6)
    with pytest.warns(StabilityLimitWarning, match=r"highest natural frequency 61[67]\.\d+ rad/s"):
        with pytest.raises(SimulationError, match="explicit RK4 step is unstable") as info:
            simulate_rk4(model, q0, np.zeros(3), t_final=2.0, dt=0.01)
    partial = info.value.partial_result
    assert partial.t[-1] < info.value.time and np.all(np.isfinite(partial.q))
    with pytest.raises(ModelError, match="RK4 .* conditionally stable"):
        simulate_rk4(model, q0, np.zeros(3), t_final=2.0, dt=0.01, stability_check="error")


def test_energy_is_conserved_without_stiffening_and_damping():
    model = PlanarModel.chain("e", [Pinned("o"), _hub(), FixedMounting("m"),
                                    _beam("b", geometric_stiffening=False, n_axial_modes=1,
                                          axial_stiffness=100.0),
                                    FixedMounting("w"), RigidBody("tip", mass=0.2, inertia=0.01,
                                                                  outboard=(0.1, 0.0))])
    q0, v0 = np.array([0.3, 0.05, -0.02, 0.01, 0.001]), np.array([1.0, 0.1, 0.0, 0.0, 0.0])
    drift = []
    for h in (2e-3, 1e-3):
        e = simulate_rk4(model, q0, v0, t_final=0.2, dt=h).energy()
        drift.append(np.max(np.abs(e - e[0])))
    assert drift[1] < 1e-6 and drift[0] / drift[1] > 12              # RK4: order >= 4


@pytest.mark.parametrize("kwargs, match", [
    (dict(bending_stiffness=0.0), "bending_stiffness must be > 0"),
    (dict(bending_stiffness=-1.0), "bending_stiffness must be > 0"),
    (dict(mass_per_length=0.0), "mass_per_length must be > 0"),
    (dict(length=-2.0), "length must be > 0"),
    (dict(n_modes=0), "n_modes must be an integer >= 1"),
    (dict(n_axial_modes=2), "axial_stiffness .* required"),
    (dict(mode_set=ModeSet.pinned_free(3)), "does not match|boundary 'pinned-free'"),
    (dict(mode_set=ModeSet.custom([lambda xi, d: xi ** (2 - d) * (1 if d < 2 else 2),
                                   lambda xi, d: np.ones_like(xi) * (d == 0),
                                   lambda xi, d: xi ** 3])), "does not match the clamped root"),
    (dict(outboard=2.0), "must lie on the beam"),
    # one bare object where a sequence is wanted, and a scalar distributed load (were TypeErrors)
    (dict(loads=Load(point=(0.5, 0.0), force_y=1.0)), r"loads must be a list or tuple of Load .*wrap one"),
    (dict(modal_forces=ModalForce(force=lambda t: np.zeros(3))), "modal_forces must be a list or tuple of ModalForce"),
    (dict(distributed_load=1.0), r"distributed_load must be \(q_x, q_y\)"),
])
def test_bad_beam_input_is_rejected(kwargs, match):
    params = dict(length=1.0, bending_stiffness=1.0, mass_per_length=1.0, n_modes=3)
    params.update(kwargs)
    with pytest.raises(ModelError, match=match):
        ModalBeam("b", **params)


def test_one_bare_load_or_hook_is_refused_by_name_on_rigid_bodies_and_spatial_beams():
    """The same refusal for the planar RigidBody's loads and the SpatialBeam's modal_forces (were TypeErrors)."""
    from ctmm.spatial import SpatialBeam
    with pytest.raises(ModelError, match="body: loads must be a list or tuple of Load objects"):
        RigidBody("body", mass=1.0, inertia=1.0, loads=Load(point=(0.0, 0.0), force_y=1.0))
    with pytest.raises(ModelError, match="beam: modal_forces must be a list or tuple of ModalForce"):
        SpatialBeam("beam", length=1.0, bending_stiffness_y=1.0, bending_stiffness_z=1.0, mass_per_length=1.0,
                    modal_forces=ModalForce(force=lambda t: np.zeros(2)))
    assert RigidBody("body", mass=1.0, inertia=1.0, loads=[Load(point=(0.0, 0.0), force_y=1.0)]).loads[0].point == (0.0, 0.0)


def test_piezo_moment_pair_hook_gives_the_exact_static_deflection():
    """FORMULAS 5.3 (check c18): a moment pair M between x1 < x2 on a cantilever deflects the tip
    by M (x2 - x1)/EI (L - (x1 + x2)/2); the modal static solution q = K^-1 Q converges to it."""
    beam = ModalBeam("b", length=1.0, bending_stiffness=2.0, mass_per_length=0.5, n_modes=20)
    beam = beam.with_modal_forces(beam.moment_pair(0.2, 0.5, 0.3))
    model = PlanarModel.chain("c", [Fixed("g"), beam], gravity=(0.0, 0.0))
    Q = 0.3 * (beam.mode_slopes(0.5) - beam.mode_slopes(0.2))
    q_static = Q / np.diag(beam.data.K)
    assert np.max(np.abs(accelerations(model, q_static, 0 * q_static))) < 1e-12
    exact = 0.3 * 0.3 / 2.0 * (1.0 - 0.35)
    assert abs(tip_deflection(model, q_static, "b") / exact - 1) < 1e-5


def test_modal_velocity_feedback_hook_damps_and_is_exact_in_the_implicit_scheme():
    from ctmm.planar import simulate_implicit
    base = ModalBeam("b", length=1.0, bending_stiffness=2.0, mass_per_length=0.5, n_modes=3)
    fb = base.modal_velocity_feedback(0.0, 0.3, coefficient=0.5, gain=2.0, mode=1)
    assert fb.damping.shape == (3, 3) and np.count_nonzero(fb.damping[:, 1:]) == 0
    model = PlanarModel.chain("c", [Fixed("g"), base.with_modal_forces(fb)], gravity=(0.0, 0.0))
    q0 = np.array([0.01, 0.0, 0.0])
    rk4 = simulate_rk4(model, q0, np.zeros(3), t_final=0.2, dt=1e-3)
    nm = simulate_implicit(model, q0, np.zeros(3), t_final=0.2, dt=1e-3)
    assert np.max(np.abs(rk4.q - nm.q)) < 1e-4 and nm.iterations.max() <= 2
    free = PlanarModel.chain("c", [Fixed("g"), base], gravity=(0.0, 0.0))
    undamped = simulate_rk4(free, q0, np.zeros(3), t_final=0.2, dt=1e-3)
    assert model.energy(rk4.q[-1], rk4.qdot[-1]) < 0.8 * free.energy(undamped.q[-1],
                                                                       undamped.qdot[-1])


def test_gauss_points_are_numpys_rule_on_the_interval_and_fresh_arrays():
    """The quadrature of the beams' modal integrals is numpy's Gauss-Legendre rule mapped to [0, L] (bit for bit, the
    rule computed once per point count), in new arrays a caller may change without changing the next call's."""
    from ctmm.flexible.modes import gauss_points

    for count, length in ((5, 1.0), (160, 2.5), (160, 0.3)):
        x_ref, w_ref = np.polynomial.legendre.leggauss(count)
        x, w = gauss_points(count, length)
        assert np.array_equal(x, (x_ref + 1.0) * 0.5 * length) and np.array_equal(w, w_ref * 0.5 * length)
        assert x.flags.writeable and w.flags.writeable
        x[:], w[:] = 0.0, 0.0
        again = gauss_points(count, length)
        assert np.array_equal(again[0], (x_ref + 1.0) * 0.5 * length) and np.array_equal(again[1], w_ref * 0.5 * length)


def test_axial_tip_displacement_of_high_modes_and_its_shape():
    """``axial_tip_displacement`` = stretch ``psi(L).p`` - 1/2 int (phi'.q)^2 against the shortening of one
    clamped-free mode written here in a form without cancellation (``sinh z - s cosh z`` folded into
    bounded terms), integrated on 1200 Gauss points.  Its fixed 64-point rule was 8 % off for mode 40 (mode
    30: 1e-10); it now uses the beam's own quadrature.  One state gives a float (it gave shape (1,))."""
    from numpy.polynomial.legendre import leggauss
    from scipy.optimize import brentq
    from ctmm.flexible.outputs import axial_tip_displacement
    length, n = 1.3, 40
    model = PlanarModel.chain("c", [Fixed("g"), ModalBeam("arm", length=length, bending_stiffness=2.0, mass_per_length=0.5,
                                                          n_modes=n, n_axial_modes=2, axial_stiffness=1e3)],
                              gravity=(0.0, 0.0))
    nodes, weights = leggauss(1200)
    for k in (40, 30, 12):
        beta = brentq(lambda b: np.cos(b) + 1.0 / np.cosh(b), (k - 0.5) * np.pi - 0.4, (k - 0.5) * np.pi + 0.4)
        s = (np.cosh(beta) + np.cos(beta)) / (np.sinh(beta) + np.sin(beta))
        z, w = (nodes + 1.0) / 2.0 * beta, weights / 2.0 * length
        slope = beta / length * (np.sin(z) + s * np.cos(z) + (np.sin(beta) * np.sinh(z) - np.cos(beta) * np.cosh(z)
                                                              - np.cosh(beta - z)) / (np.sinh(beta) + np.sin(beta)))
        q = np.zeros(n + 2)
        q[k - 1], q[n], q[n + 1] = 0.01, 1e-3, 2e-4
        expected = math.sqrt(2.0) * (1e-3 - 2e-4) - 0.5 * 0.01 ** 2 * (slope ** 2 @ w)   # psi_k(L) = sqrt2 (-1)^(k+1)
        value = axial_tip_displacement(model, q, "arm")
        assert abs(value - expected) < 1e-10 * abs(expected)
        assert isinstance(value, float)
        history = axial_tip_displacement(model, np.vstack([q, 2 * q]), "arm")
        assert history.shape == (2,) and abs(history[0] - value) <= 1e-14 * abs(value)


def test_modal_coordinates_are_in_metres():
    """docs/flexible.md §1.1: the shapes have no unit (|phi_i(L)| = 2), so ``w = phi . q`` makes the modal coordinates
    metres, as the spatial beam's (SpatialBeam.coordinate_units); the planar ports said '1' and '1/s'.  The tip
    deflection sensor [m] of a one-mode beam reads -2 q1 ... 2 q1 whatever q1 is."""
    from ctmm.planar.ports import PlanarPorts, sensor_values
    beam = ModalBeam("arm", length=1.0, bending_stiffness=2.0, mass_per_length=0.5, n_modes=1, n_axial_modes=1,
                     axial_stiffness=1e3, stations={"tip": 1.0})
    model = PlanarModel.chain("hub_beam", [Pinned("p"), RigidBody("hub", mass=1.0, inertia=0.1, outboard=(0.1, 0.0)),
                                           FixedMounting("m"), beam], gravity=(0.0, 0.0))
    ports = PlanarPorts(model)
    q = np.array([0.3, 0.02, 0.001])
    assert abs(abs(sensor_values(model, ["arm.tip.w"], q, np.zeros(3))[0]) - 2 * 0.02) < 1e-12
    assert [ports.sensor_unit(n) for n in ("arm.tip.w", "arm.q1", "arm.u1", "arm.q1_dot", "arm.u1_dot", "hub.theta")] \
        == ["m", "m", "m", "m/s", "m/s", "rad"]
