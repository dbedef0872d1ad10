"""The manipulator scene on station ports (one model for both domains).

The scene's PZT loops sense slope rates at the patch-end stations and act with moment pairs
(ctmm.planar.ports station ports); the Lagrange checks of the closed loops are in
tests/test_manipulator_scene.py.  Here: the loops' structure, and that they are the modal
slope-rate law of the seed (modal-coordinate ports built from the beam's own shape slopes).
"""
from __future__ import annotations

import numpy as np

import ctmm
from ctmm.control import ControlledModel, Feedback
from ctmm.manipulator import SEED_KD, SEED_KP, HubPD, PZTFeedback, seed_manipulator
from ctmm.manipulator.scene import HUB_LOOP, manipulator_scene

G = np.array([[300.0, 20.0, 0.0], [0.0, 150.0, 0.0], [5.0, 0.0, 80.0]])


def test_scene_pzt_loops_act_on_station_ports_as_the_modal_slope_rate_law():
    seed = seed_manipulator()
    pd, pzt = HubPD(SEED_KP, SEED_KD, delay=0.004), PZTFeedback(G, delay=0.003)
    scene = manipulator_scene(seed, pd=pd, pzt=pzt)
    first = seed.patches[0].name
    loop = scene.loops[1]
    assert loop.name == first
    assert {name for name, _ in loop.actuator} == {f"arm.{first}_x1.moment", f"arm.{first}_x2.moment"}
    assert all(name.endswith(".slope_rate") for name, _ in loop.sensor)
    # the same law on modal-coordinate ports: sensing (G Psi) eta_dot, forces c_a Psi
    beam = scene.plant.bodies[scene.plant.body_index("arm")]
    psi = np.array([beam.shapes([p.end], 1)[:, 0] - beam.shapes([p.start], 1)[:, 0] for p in seed.patches])
    sensing, ca = G @ psi, seed.moments_per_volt
    modal = [scene.loops[0]] + [
        Feedback(p.name, sensor=[(f"arm.q{k + 1}_dot", float(sensing[j, k])) for k in range(3)],
                 actuator=[(f"arm.q{k + 1}.force", float(ca[j] * psi[j, k])) for k in range(3)],
                 gain=1.0, delay=pzt.delay) for j, p in enumerate(seed.patches)]
    omega = np.array([3.0, 15.7, 40.0, 97.0, 150.0])
    outputs = ["motor.angle", "arm.out.y"] + [f"{p.name}.u" for p in seed.patches]
    station = ctmm.frequency_response(scene, omega, input=f"{HUB_LOOP}.reference", output=outputs)
    reference = ctmm.frequency_response(ControlledModel(scene.plant, modal), omega, input=f"{HUB_LOOP}.reference",
                                        output=outputs)
    np.testing.assert_allclose(station.response, reference.response, rtol=1e-9, atol=1e-12)


# ------------------------------------------------------------------------------------------
# the exact-field frequency form (ctmm.exact_fields, fields="exact")
OMEGA = np.array([1.0, 5.0, 15.7, 40.0, 97.0, 300.0])


def seed_scene(pzt=True, n_modes=3):
    seed = seed_manipulator()
    pd = HubPD(SEED_KP, SEED_KD, delay=0.004)
    law = PZTFeedback(G, delay=0.003) if pzt else None
    return seed, pd, law, manipulator_scene(seed, pd=pd, pzt=law, n_modes=n_modes)


def test_exact_fields_of_the_scene_equal_the_continuum_reference():
    """The exact-field form against the 150-mode Lagrange model with static correction (the former
    ``LinearManipulator`` chain gave the same numbers to 1e-12 before it was removed)."""
    from ctmm.reference.manipulator_lagrange import ManipulatorLagrange

    seed, pd, pzt, scene = seed_scene()
    outputs = ["motor.angle", "arm.out.y"] + [f"{p.name}.u" for p in seed.patches]
    reference = ManipulatorLagrange.from_manipulator(seed, 150).frequency_response(
        OMEGA, kp=SEED_KP, kd=SEED_KD, pd_delay=pd.delay, pzt_gains=G, pzt_delay=pzt.delay)
    reach = seed.hub.radius + seed.arm.length
    for name, planar_input, scale in (("torque", "motor.torque", 1.0),
                                      ("theta_d", f"{HUB_LOOP}.reference", SEED_KP + SEED_KD * 1j * OMEGA)):
        exact = ctmm.frequency_response(scene, OMEGA, input=planar_input, output=outputs, fields="exact")
        expected = reference[name]
        theta = exact("motor.angle", planar_input) * scale
        np.testing.assert_allclose(theta, expected["theta"], rtol=1e-8)
        # "arm.out.y" is the inertial tip w(L) = u(L) + (r + L) theta
        np.testing.assert_allclose(exact("arm.out.y", planar_input) * scale,
                                   expected["tip"] + reach * expected["theta"], rtol=1e-8)
        volts = np.array([exact(f"{p.name}.u", planar_input) * scale for p in seed.patches])
        assert np.abs(volts - expected["voltages"]).max() < 1e-8 * np.abs(expected["voltages"]).max()
    assert exact.info["method"].startswith("exact fields")
    assert exact.units["arm.out.y"] == "m"


def test_the_modal_form_converges_to_the_exact_fields_as_modes_are_added():
    omega = np.array([2.0, 10.0, 30.0, 60.0])             # below the 2nd mode of the 2-mode arm (~97 rad/s)
    errors = {}
    for pzt in (False, True):
        exact = ctmm.frequency_response(seed_scene(pzt)[3], omega, input="motor.torque", output="arm.out.y",
                                        fields="exact").response[0, 0]
        for n in (2, 4, 8, 16):
            modal = ctmm.frequency_response(seed_scene(pzt, n)[3], omega, input="motor.torque",
                                            output="arm.out.y").response[0, 0]
            errors[pzt, n] = float(np.max(np.abs(modal - exact) / np.abs(exact)))
    pd_only = [errors[False, n] for n in (2, 4, 8, 16)]
    assert all(b < a / 10 for a, b in zip(pd_only, pd_only[1:])) and pd_only[-1] < 1e-6
    # collocated point moments and slope sensing: the modal series converges slowly (~1/n)
    with_pzt = [errors[True, n] for n in (2, 4, 8, 16)]
    assert all(b < a for a, b in zip(with_pzt, with_pzt[1:])) and with_pzt[-1] < 2e-3


def bvp_tip_response(omega, k_hinge, c_hinge, L1, L2, EI, rhoA):
    """Tip deflection, root deflection and root slope of the second beam per unit tip force of
    clamped beam - spring-damper hinge - free beam, from the continuum boundary-value problem
    (8 coefficients of the Euler-Bernoulli solutions)."""
    out = []
    for w in omega:
        beta = (rhoA * w * w / EI) ** 0.25

        def basis(x, d):               # [cosh, sinh, cos, sin] and derivatives at x
            b = beta
            return np.array([(np.cosh, np.sinh, np.cosh, np.sinh)[d](b * x) * b ** d,
                             (np.sinh, np.cosh, np.sinh, np.cosh)[d](b * x) * b ** d,
                             (np.cos, lambda y: -np.sin(y), lambda y: -np.cos(y), np.sin)[d](b * x) * b ** d,
                             (np.sin, np.cos, lambda y: -np.sin(y), lambda y: -np.cos(y))[d](b * x) * b ** d])
        z = np.zeros(4)
        impedance = k_hinge + 1j * w * c_hinge
        rows = [np.r_[basis(0, 0), z], np.r_[basis(0, 1), z],                        # clamped
                np.r_[basis(L1, 0), -basis(0, 0)],                                     # w continuous
                np.r_[EI * basis(L1, 2), -EI * basis(0, 2)],                           # moment continuous
                np.r_[EI * basis(L1, 3), -EI * basis(0, 3)],                           # shear continuous
                np.r_[EI * basis(L1, 2) + impedance * basis(L1, 1), -impedance * basis(0, 1)],  # EI w'' = Z dtheta
                np.r_[z, basis(L2, 2)], np.r_[z, EI * basis(L2, 3)]]                   # free end, tip force
        rhs = np.zeros(8, dtype=complex)
        rhs[7] = -1.0                                                                  # EI w''' = -F
        coefficients = np.linalg.solve(np.array(rows, dtype=complex), rhs)
        second = coefficients[4:]
        out.append((basis(L2, 0) @ second, basis(0, 0) @ second, basis(0, 1) @ second))
    return np.array(out).T


def test_a_hinged_two_beam_chain_equals_the_continuum_boundary_value_problem():
    from ctmm.flexible import ModalBeam
    from ctmm.planar import Fixed, PlanarModel, SpringDamperHinge
    from ctmm.planar.elements import FixedMounting

    L1, L2, EI, RHOA, K, C = 0.6, 0.5, 20.0, 0.5, 15.0, 0.05
    first = ModalBeam("first", length=L1, bending_stiffness=EI, mass_per_length=RHOA, n_modes=3)
    second = ModalBeam("second", length=L2, bending_stiffness=EI, mass_per_length=RHOA, n_modes=3,
                       stations={"tip": L2})
    model = PlanarModel.chain("hinged", [Fixed("ground"), FixedMounting("clamp"), first,
                                         SpringDamperHinge("h", stiffness=K, damping=C), second], gravity=(0.0, 0.0))
    omega = np.array([0.5, 7.0, 33.0, 120.0, 400.0])
    exact = ctmm.frequency_response(model, omega, input="second.tip.force", output=["second.out.y", "second.tip.w"],
                                    fields="exact")
    tip, root, root_slope = bvp_tip_response(omega, K, C, L1, L2, EI, RHOA)
    np.testing.assert_allclose(exact("second.out.y", "second.tip.force"), tip, rtol=1e-9)
    # the station sensor is the deflection in the beam's own (root tangent) frame
    np.testing.assert_allclose(exact("second.tip.w", "second.tip.force"), tip - root - L2 * root_slope, rtol=1e-8)


def test_one_sweep_for_every_input_equals_a_solve_per_input():
    """The exact form's open loop solves all its chain inputs in one Riccati sweep (the beam matrices evaluated
    once, the load vectors stacked: ``chain_assembly.solve_load_cases``); its states equal the former loop of
    one ``solve`` per input bit for bit, at frequencies where the beams are subdivided (3000, 1e4 rad/s) too."""
    from ctmm.chain_assembly import solve, solve_load_cases, subdivided
    from ctmm.exact_fields import exact_form

    chain = exact_form(seed_scene()[3].plant).chain
    s = 1j * np.append(OMEGA, [3000.0, 1e4])
    assert len(subdivided(chain, 1e4)[0]) > len(chain.body)
    # every chain input: hub and patch moments, forces, the tip's loads
    cases = [{entry.position: {entry.input: 1.0}} for entry in map(chain.input, chain.input_names())]
    stacked = solve_load_cases(chain, s, cases)
    one_by_one = np.stack([solve(chain, s, case).states for case in cases])
    assert stacked.shape == (len(cases), len(chain.body) + 1, s.size, 4)
    assert np.array_equal(stacked, one_by_one)


def test_exact_fields_refuse_what_they_cannot_map():
    import pytest

    from ctmm.errors import ModelError
    from ctmm.flexible import ModalBeam
    from ctmm.planar import Fixed, PlanarModel, RigidBody, SmoothHinge

    seed, pd, pzt, scene = seed_scene()
    with pytest.raises(ModelError, match="modal coordinate"):
        ctmm.frequency_response(scene, [1.0], input="motor.torque", output="arm.q1", fields="exact")
    with pytest.raises(ModelError, match="axial"):
        ctmm.frequency_response(scene, [1.0], input="motor.torque", output="arm.out.x", fields="exact")
    with pytest.raises(ModelError, match="fields must be one of"):
        ctmm.frequency_response(scene, [1.0], input="motor.torque", output="arm.out.y", fields="exakt")
    beam = ModalBeam("b", length=1.0, bending_stiffness=5.0, mass_per_length=0.3, n_modes=2)
    link = RigidBody("l", mass=1.0, inertia=0.1, center_of_mass=(0.5, 0.0), outboard=(1.0, 0.0))
    heavy = PlanarModel.chain("heavy", [Fixed("g"), SmoothHinge("p"), link, SmoothHinge("q"), beam])
    with pytest.raises(ModelError, match="free"):       # hangs straight: gravity along it is taken, its free hinge not
        ctmm.frequency_response(heavy, [1.0], input="p.torque", output="l.theta", fields="exact")
    free = PlanarModel.chain("free", [Fixed("g"), SmoothHinge("p"), link, SmoothHinge("q"), beam], gravity=(0, 0))
    with pytest.raises(ModelError, match="free"):
        ctmm.frequency_response(free, [1.0], input="p.torque", output="l.theta", fields="exact")
    with pytest.raises(ModelError, match="for planar models"):
        from ctmm.exact_fields import exact_form
        chain = exact_form(scene.plant).chain                           # a 1-D chain has nothing to convert
        ctmm.frequency_response(chain, [1.0], input="hub__root.moment", output="hub__root.theta", fields="exact")


def test_exact_natural_frequencies_of_a_hinged_two_beam_chain_are_the_continuum_roots():
    from scipy.optimize import brentq

    from ctmm.flexible import ModalBeam
    from ctmm.planar import ElasticHinge, Fixed, PlanarModel
    from ctmm.planar.elements import FixedMounting

    L1, L2, EI, RHOA, K = 0.6, 0.5, 20.0, 0.5, 15.0
    def model(n_modes):
        return PlanarModel.chain("hinged", [
            Fixed("ground"), FixedMounting("clamp"),
            ModalBeam("first", length=L1, bending_stiffness=EI, mass_per_length=RHOA, n_modes=n_modes),
            ElasticHinge("h", stiffness=K),
            ModalBeam("second", length=L2, bending_stiffness=EI, mass_per_length=RHOA, n_modes=n_modes)],
            gravity=(0.0, 0.0))

    exact = ctmm.natural_frequencies(model(1), n_modes=4, fields="exact")

    def determinant(w):             # the homogeneous boundary-value problem of bvp_tip_response
        beta = (RHOA * w * w / EI) ** 0.25
        funcs = [(np.cosh, np.sinh, np.cosh, np.sinh), (np.sinh, np.cosh, np.sinh, np.cosh),
                 (np.cos, lambda y: -np.sin(y), lambda y: -np.cos(y), np.sin),
                 (np.sin, np.cos, lambda y: -np.sin(y), lambda y: -np.cos(y))]

        def basis(x, d):
            return np.array([f[d](beta * x) * beta ** d for f in funcs])
        z = np.zeros(4)
        rows = [np.r_[basis(0, 0), z], np.r_[basis(0, 1), z], np.r_[basis(L1, 0), -basis(0, 0)],
                np.r_[basis(L1, 2), -basis(0, 2)], np.r_[basis(L1, 3), -basis(0, 3)],
                np.r_[EI * basis(L1, 2) + K * basis(L1, 1), -K * basis(0, 1)],
                np.r_[z, basis(L2, 2)], np.r_[z, basis(L2, 3)]]
        return np.linalg.det(np.array(rows))

    grid = np.linspace(1.0, 1200.0, 4000)
    values = np.array([determinant(w) for w in grid])
    roots = [brentq(determinant, a, b, xtol=1e-13) for a, b, fa, fb in
             zip(grid, grid[1:], values, values[1:]) if fa * fb < 0][:4]
    np.testing.assert_allclose(exact, roots, rtol=1e-9)
    modal = ctmm.natural_frequencies(model(1), n_modes=2)       # Rayleigh-Ritz: upper bounds
    assert np.all(modal >= exact[:2] * (1 - 1e-12))


def test_exact_fields_refuse_kinks_trees_and_modal_only_physics():
    import pytest

    from ctmm.errors import ModelError
    from ctmm.flexible import ModalBeam
    from ctmm.planar import ElasticHinge, Fixed, Pinned, PlanarModel, RigidBody
    from ctmm.planar.elements import FixedMounting

    def beam(name="b", **extra):
        return ModalBeam(name, length=0.5, bending_stiffness=5.0, mass_per_length=0.3, n_modes=1, **extra)

    def chain(*bodies_and_hinges):
        return PlanarModel.chain("c", [Fixed("g"), FixedMounting("m"), *bodies_and_hinges], gravity=(0.0, 0.0))

    kinked = chain(beam("a"), ElasticHinge("h", stiffness=3.0, rest_angle=0.3), beam())
    with pytest.raises(ModelError, match="not straight"):
        ctmm.frequency_response(kinked, [1.0], input="h.torque", output="h.angle", fields="exact")
    with pytest.raises(ModelError, match="damping ratio"):
        ctmm.natural_frequencies(chain(beam(damping_ratio=0.01)), n_modes=1, fields="exact")
    hooked = chain(beam().with_modal_forces(beam().moment_pair(0.1, 0.2, 1.0)))
    with pytest.raises(ModelError, match="modal-force hooks"):
        ctmm.natural_frequencies(hooked, n_modes=1, fields="exact")
    link = RigidBody("l", mass=1.0, inertia=0.1, center_of_mass=(0.2, 0.05), outboard=(0.4, 0.0))
    with pytest.raises(ModelError, match="off its axis"):
        ctmm.natural_frequencies(chain(link), n_modes=1, fields="exact")
    fork = RigidBody("f", mass=1.0, inertia=0.1, outboard={"left": (0.4, 0.0), "right": (0.4, 0.0)})
    tree = PlanarModel("tree", [Pinned("g", child="f"), fork,
                                ElasticHinge("h1", parent="f.left", child="b1", stiffness=2.0), beam("b1"),
                                ElasticHinge("h2", parent="f.right", child="b2", stiffness=2.0), beam("b2")],
                       gravity=(0.0, 0.0))
    with pytest.raises(ModelError, match="not a serial chain"):
        ctmm.natural_frequencies(tree, n_modes=1, fields="exact")
    with pytest.raises(ModelError, match="uncontrolled"):
        ctmm.natural_frequencies(seed_scene(pzt=False)[3], n_modes=1, fields="exact")
