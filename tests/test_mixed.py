"""Mixed MSTMM: a pendulum chain carrying a finite-element beam (ctmm.fem.GlobalSubsystem on the one
articulated sweep) against the independent global Lagrange model :mod:`ctmm.reference.mixed_global`."""
from __future__ import annotations

import numpy as np
import pytest

import ctmm
from ctmm.fem import BeamElement, FiniteElementModel
from ctmm.planar import ElasticHinge, PlanarModel, Pinned, RigidBody, SmoothHinge
from ctmm.planar.sweep import accelerations
from ctmm.reference.mixed_global import BeamSegment, GlobalChain, RigidSegment

ELEMENTS, LENGTH, EI, EA, RHO_A = 3, 1.0, 20.0, 2.0e3, 1.0
HINGE_STIFFNESS = 2.0


def cubic_tip_spring(u, u_dot, t):
    """``-k3 u_y^3 - c u_y'`` on the tip node's transverse DOF (frame axes): a nonlinear internal law."""
    f = np.zeros_like(u)
    f[-2] = -4.0e5 * u[-2] ** 3 - 0.3 * u_dot[-2]
    return f


def build(force=None, rayleigh=(0.0, 0.0)):
    nodes = {f"n{k}": (k * LENGTH / ELEMENTS, 0.0) for k in range(ELEMENTS + 1)}
    fe = FiniteElementModel("beam", nodes, [BeamElement(f"e{k}", f"n{k}", f"n{k + 1}", EI, EA, RHO_A)
                                            for k in range(ELEMENTS)], rayleigh=rayleigh)
    wrapped = None
    if force is not None:                                 # ctmm passes all DOFs (frame node first, zero)
        def wrapped(u, u_dot, t):
            out = np.zeros_like(u)
            out[3:] = force(u[3:], u_dot[3:], t)
            return out
    beam = fe.subsystem("flex", ("n0", f"n{ELEMENTS}"), nonlinear_force=wrapped)
    upper = RigidBody.uniform_link("upper", mass=1.0, length=1.0)
    lower = RigidBody.uniform_link("lower", mass=0.5, length=0.8)
    model = PlanarModel.chain("fe_pendulum", [Pinned("base"), upper, SmoothHinge("h2"), beam,
                                              ElasticHinge("h3", stiffness=HINGE_STIFFNESS), lower])
    reference = GlobalChain([RigidSegment(1.0, 1.0, 1.0 / 12, 0.5),
                             BeamSegment(LENGTH, ELEMENTS, EI, EA, RHO_A, rayleigh=rayleigh, force=force),
                             RigidSegment(0.8, 0.5, 0.5 * 0.64 / 12, 0.4, stiffness=HINGE_STIFFNESS)])
    return model, reference


def initial_state(model):
    q0 = np.zeros(model.n_coordinates)
    names = model.coordinates
    q0[names.index("upper.theta")] = -0.5
    q0[names.index("flex.theta")] = 0.3
    q0[names.index("lower.theta")] = 0.3
    q0[names.index("flex.n3_uy")] = 0.02
    q0[names.index("flex.n3_rz")] = 0.03
    return q0


def histories(result, model):
    q = np.column_stack([result.extra[c] for c in model.coordinates])
    v = np.column_stack([result.extra[c + "_dot"] for c in model.coordinates])
    return q, v


def test_coordinates_match_the_reference_order():
    model, reference = build()
    assert model.n_coordinates == reference.n == 2 + 3 * ELEMENTS + 1
    assert model.coordinates[1:5] == ("flex.theta", "flex.n1_ux", "flex.n1_uy", "flex.n1_rz")


@pytest.mark.parametrize("force, rayleigh", [(None, (0.0, 0.0)), (cubic_tip_spring, (0.5, 1e-4))])
def test_accelerations_equal_the_global_model(force, rayleigh):
    model, reference = build(force, rayleigh)
    rng = np.random.default_rng(7)
    for _ in range(3):
        q = rng.normal(size=model.n_coordinates)
        v = rng.normal(size=model.n_coordinates)
        q[2:-1] *= 0.01
        a = accelerations(model, q, v, 0.0)
        a_ref = reference.accelerations(q, v)
        assert np.max(np.abs(a - a_ref)) <= 1e-11 * np.max(np.abs(a_ref))


@pytest.mark.parametrize("force", [None, cubic_tip_spring])
def test_rk4_history_equals_the_global_model_with_the_same_integrator(force):
    model, reference = build(force)
    q0 = initial_state(model)
    dt, t_final = 1e-3, 0.25
    result = ctmm.simulate(model, t_final, dt, method="rk4", x0=q0)
    q, v = histories(result, model)
    _, q_ref, v_ref = reference.rk4(q0, np.zeros_like(q0), t_final, dt)
    assert np.max(np.abs(q - q_ref)) < 1e-8
    assert np.max(np.abs(v - v_ref)) < 1e-8
    assert np.max(np.abs(q[:, model.coordinates.index("flex.n3_uy")])) > 0.01       # the beam vibrates
    if force is None:       # the energies of both models agree (RK4 at omega_max dt ~ 0.5 damps the top modes)
        e = [model.energy(q[k], v[k]) for k in (0, q.shape[0] - 1)]
        e_ref = [reference.energy(q_ref[k], v_ref[k]) for k in (0, q.shape[0] - 1)]
        assert e == pytest.approx(e_ref, rel=1e-10)


def test_energy_of_a_subsystem_with_a_nonlinear_force_needs_its_potential():
    from ctmm.errors import ModelError
    model, _ = build(cubic_tip_spring)
    q0 = initial_state(model)
    with pytest.raises(ModelError, match="potential"):
        model.energy(q0, np.zeros_like(q0))


def test_implicit_dt_tmm_with_a_nonlinear_subsystem_converges_to_the_global_model_at_second_order():
    model, reference = build(cubic_tip_spring, (0.5, 1e-4))
    q0 = initial_state(model)
    t_final = 0.02
    q_ref, _ = reference.solve(q0, np.zeros_like(q0), np.array([0.0, t_final]))
    errors = []
    for dt in (1.25e-4, 6.25e-5):
        result = ctmm.simulate(model, t_final, dt, method="newmark", x0=q0)
        q, _ = histories(result, model)
        errors.append(np.max(np.abs(q[-1] - q_ref[-1])))
    assert errors[1] < 3e-5                               # 1.6e-5 (the tip moves by 2e-2)
    assert 3.5 < errors[0] / errors[1] < 4.5             # trapezoidal Newmark: O(h^2) (4.16)


def test_natural_frequencies_equal_eigh_of_the_global_linearisation():
    model, reference = build()
    q_rest = np.zeros(reference.n)
    q_rest[reference.theta_index] = -np.pi / 2
    q_rest = reference.equilibrium(q_rest)
    expected = reference.natural_frequencies(q_rest)[:6]
    omega = ctmm.natural_frequencies(model, n_modes=6)
    assert omega == pytest.approx(expected, rel=1e-9)


def global_matrices(reference):
    """``M, C, K`` of the global model about its hanging equilibrium (``C`` by complex step of its rates)."""
    q_rest = np.zeros(reference.n)
    q_rest[reference.theta_index] = -np.pi / 2
    q_rest = reference.equilibrium(q_rest)
    n = reference.n
    M, _ = reference._generalised(q_rest, np.zeros(n), 0.0)   # noqa: SLF001 - test reads the reference's matrices
    K = reference._stiffness(q_rest)                           # noqa: SLF001
    C = np.zeros((n, n))
    for k in range(n):                                           # d(rhs)/d(qdot) by complex step
        dv = np.zeros(n, complex)
        dv[k] = 1e-30j
        C[:, k] = -reference._generalised(q_rest.astype(complex), dv, 0.0)[1].imag / 1e-30   # noqa: SLF001
    return M, C, K


def test_frequency_response_equals_the_global_dynamic_stiffness():
    model, reference = build(rayleigh=(0.5, 1e-4))
    n = reference.n
    M, C, K = global_matrices(reference)
    omega = np.array([1.0, 4.0, 30.0, 150.0])
    response = ctmm.frequency_response(model, omega, input="flex.n3_uy.force", output="lower.theta")
    i_in, i_out = model.coordinates.index("flex.n3_uy"), model.coordinates.index("lower.theta")
    for k, w in enumerate(omega):
        x = np.linalg.solve(K - w * w * M + 1j * w * C, np.eye(n)[:, i_in])
        assert response.response[0, 0, k] == pytest.approx(x[i_out], rel=1e-8)


def test_a_feedback_loop_on_the_mixed_model_equals_a_hinge_law_of_the_global_model():
    """A real-time PD loop from the upper link's angle and rate to the base torque is, in the global
    model, a ground spring-damper (k = KP, c = KD): the closed loop in time (RK4, same step)."""
    from ctmm.control import Feedback, with_feedback
    kp, kd = 6.0, 0.8
    model, _ = build()
    closed = with_feedback(model, [Feedback("pd", [("upper.theta", kp), ("upper.omega", kd)], "base.torque",
                                            gain=1.0)])
    reference = GlobalChain([RigidSegment(1.0, 1.0, 1.0 / 12, 0.5, stiffness=kp, damping=kd),
                             BeamSegment(LENGTH, ELEMENTS, EI, EA, RHO_A),
                             RigidSegment(0.8, 0.5, 0.5 * 0.64 / 12, 0.4, stiffness=HINGE_STIFFNESS)])
    q0 = initial_state(model)
    result = ctmm.simulate(closed, 0.1, 1e-3, method="rk4", x0=q0)
    q = np.column_stack([result[c] for c in model.coordinates])
    _, q_ref, _ = reference.rk4(q0, np.zeros_like(q0), 0.1, 1e-3)
    assert np.max(np.abs(q - q_ref)) < 1e-8


def test_generated_code_runs_the_subsystem_as_the_numpy_sweep():
    """compiled=True generates the subsystem's terms with the rest of the scene (casadi) -- same numbers."""
    model, reference = build(rayleigh=(0.5, 1e-4))
    q0 = initial_state(model)
    result = ctmm.simulate(model, 0.02, 1e-3, method="rk4", x0=q0, compiled=True)
    q, _ = histories(result, model)
    _, q_ref, _ = reference.rk4(q0, np.zeros_like(q0), 0.02, 1e-3)
    assert np.max(np.abs(q - q_ref)) < 1e-9


def test_generated_code_refuses_a_subsystems_nonlinear_force_by_name():
    """The documented contract (docs/mixed.md §7: a nonlinear_force is Python code, refused by the generated path):
    the refusal names the subsystem and its nonlinear_force, not 'time-dependent loads on a beam' with advice to
    use ctmm.signals, which cannot express a state law."""
    model, _ = build(force=cubic_tip_spring)
    with pytest.raises(ctmm.ModelError, match=r"subsystems with a nonlinear_force: 'flex'.*compiled=False") as info:
        ctmm.simulate(model, 0.01, 1e-3, method="rk4", x0=initial_state(model), compiled=True)
    assert "ctmm.signals" not in str(info.value)
