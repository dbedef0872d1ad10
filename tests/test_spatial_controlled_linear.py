"""The linear verbs on *controlled* spatial models (issue 14, item 3), against the independent global
reference (``ctmm/reference/spatial_tree.py``, ``ctmm/reference/spatial_kinematics.py``) and a time
simulation.

The arm: a base on a vertical revolute hinge ``yaw`` (actuated, damped), a link hanging from a universal
joint ``hip`` at an offset point of the base (springs and dampers), a wrist body on a spherical joint
(sensor test only).  About the static equilibrium (the link hangs straight) the reference gives
``M, C, K`` in the same tangent coordinates (``spatial_linear_helpers.reference_matrices``).

* ``delay_margin`` of a delayed PD loop on the yaw hinge, sensed through the base's rotation vector and
  world angular velocity, equals the smallest delay at which the reference's quasi-polynomial
  ``det(M s^2 + C s + K + e e^T (kp + kd s) e^{-s tau})`` has a root on the imaginary axis, computed here
  from the crossings ``|L(i w)| = 1`` of ``L = (kp + kd s) e^T Z0(s)^-1 e`` (tolerance 1e-9 relative);
* the closed real-time loop (a world force at the link tip on the tip's sensed position and velocity)
  gives the eigenvalues of the reference's ``A`` closed by hand with the tip Jacobian of the reference
  kinematics, and the frequency response (with the delayed loop closed by ``e^{-s tau}``) equals the
  reference's ``Z(s)^-1`` (1e-9 relative);
* ``loop_transfer_function`` and ``margins`` equal the reference's ``L`` and the margin above;
* every kind of sensor row of ``C`` equals a Richardson difference of the reference kinematics
  (``1e-7``), about a point in motion (``allow_nonequilibrium``);
* a stability-chart point on either side of the margin agrees with ``ctmm.simulate`` of the controlled
  model (the yaw oscillation decays below the margin and grows above it).
"""
from __future__ import annotations

import numpy as np
import pytest
import scipy.optimize
from scipy.spatial.transform import Rotation

import ctmm
import ctmm.spatial as sp
from ctmm.control import Feedback, loop_transfer_function, margins, with_feedback
from ctmm.reference import spatial_kinematics as kinematics_reference
from ctmm.spatial.ports import sensor_values
from ctmm.reference import spatial_tree as ref
from ctmm.stability import characteristic_roots, delay_margin
from ctmm.stability_chart import stability_chart
from spatial_linear_helpers import reference_configuration, reference_matrices, reference_tree

KP, KD = 3.0, 0.4                 # yaw PD [N m/rad], [N m s/rad]
TIP_KP, TIP_KD = 20.0, 1.5        # tip loop [N/m], [N s/m]
TIP = np.array([0.02, 0.0, -0.5])


def arm(wrist: bool = False) -> sp.SpatialModel:
    elements = [
        sp.SpatialBody("base", 2.0, (0.05, 0.04, 0.02), center_of_mass=(0, 0, 0.1), points={"top": (0.1, 0, 0.2)}),
        sp.SpatialBody("link", 1.0, (0.02, 0.018, 0.004), center_of_mass=(0, 0, -0.25), points={"tip": TIP}),
        sp.Revolute(name="yaw", parent=None, child="base", axis=(0, 0, 1), damping=0.05, actuated=True),
        sp.Universal(name="hip", parent="base", point="top", child="link", axis1=(1, 0, 0), axis2=(0, 1, 0),
                     stiffness=(2.0, 3.0), damping=(0.05, 0.08)),
    ]
    if wrist:
        elements += [sp.SpatialBody("hand", 0.5, (0.003, 0.002, 0.004), center_of_mass=(0.05, 0.01, -0.03),
                                    points={"finger": (0.1, -0.05, 0.02)}),
                     sp.Spherical(name="wrist", parent="link", point="tip", child="hand", damping=0.01)]
    return sp.SpatialModel("arm", elements, gravity=(0, 0, -9.81))


def yaw_pd(delay: float, gain: float = 1.0) -> Feedback:
    return Feedback("pd", sensor=[("base.rotation_z", KP), ("base.omega_z", KD)], actuator="yaw.torque", gain=gain,
                    delay=delay)


TIP_LOOP = Feedback("tip", sensor=[("link.tip.y", TIP_KP), ("link.tip.vy", TIP_KD)], actuator="link.tip.force_y",
                    gain=1.0)


def reference_dynamics(q0: np.ndarray) -> tuple[np.ndarray, np.ndarray, np.ndarray, np.ndarray]:
    """``M, C, K`` of the reference about ``q0`` and the (3, nv) world-velocity Jacobian of the link tip."""
    model = arm()
    tree, q_ref = reference_tree(model), reference_configuration(model, q0)
    kin = kinematics_reference.kinematics(tree, q_ref, np.zeros(tree.nv))
    tip = kinematics_reference.point_jacobian(kin, 1, kin.origin[1] + kin.rotation[1] @ TIP)
    return (*reference_matrices(model, q0), tip)


def yaw_unit(n: int) -> np.ndarray:
    e = np.zeros(n)
    e[0] = 1.0                    # the yaw hinge is the first velocity; its torque the first generalised force
    return e


def reference_margin(mass, damping, stiffness) -> tuple[float, float]:
    """The smallest delay [s] (and its frequency) at which ``1 + L(s) e^{-s tau}`` vanishes on the imaginary
    axis, ``L = (kp + kd s) e^T (M s^2 + C s + K)^-1 e``."""
    e = yaw_unit(mass.shape[0])

    def loop(w: float) -> complex:
        s = 1j * w
        return (KP + KD * s) * e @ np.linalg.solve(mass * s * s + damping * s + stiffness, e)

    grid = np.logspace(-2, 3, 4000)
    excess = np.array([abs(loop(w)) - 1.0 for w in grid])
    crossings = []
    for i in np.nonzero(np.diff(np.sign(excess)))[0]:
        w = scipy.optimize.brentq(lambda x: abs(loop(x)) - 1.0, grid[i], grid[i + 1], xtol=1e-15, rtol=1e-15)
        crossings.append((np.mod(np.angle(-loop(w)), 2.0 * np.pi) / w, w))
    return min(crossings)


def test_delay_margin_is_the_root_of_the_reference_quasi_polynomial() -> None:
    system = with_feedback(arm(), [yaw_pd(0.05)])
    lin = ctmm.linearize(system)
    assert [d.name for d in lin.delays] == ["pd"] and lin.state_space.input_labels == ["pd_u"]
    mass, damping, stiffness, _ = reference_dynamics(lin.operating_point.q)
    e = yaw_unit(mass.shape[0])
    # without delay the reference's closed loop is stable: the first crossing is the margin
    n = mass.shape[0]
    closed = np.block([[np.zeros((n, n)), np.eye(n)], [-np.linalg.solve(mass, stiffness + KP * np.outer(e, e)),
                                                       -np.linalg.solve(mass, damping + KD * np.outer(e, e))]])
    assert np.max(np.linalg.eigvals(closed).real) < 0.0
    tau, w = reference_margin(mass, damping, stiffness)
    dm = delay_margin(system)
    assert dm.stable and dm.certificate.certified
    assert dm.critical_delay == pytest.approx(tau, rel=1e-9) and dm.critical_frequency == pytest.approx(w, rel=1e-9)
    # each characteristic root within its own error estimate of a root of the reference's determinant

    def determinant(s: complex) -> complex:
        return np.linalg.det(mass * s * s + damping * s + stiffness + np.outer(e, e) * (KP + KD * s) * np.exp(-s * 0.05))

    roots = characteristic_roots(system, re_min=-3.0, im_max=40.0)
    assert roots.reliable and roots.roots.size >= 4
    for s, error in zip(roots.roots, roots.error_estimates):
        exact = complex(scipy.optimize.newton(determinant, complex(s), tol=1e-14, maxiter=100))
        assert abs(s - exact) <= max(error, 1e-12 * abs(s)) and abs(s - exact) <= 1e-4 * abs(s), (s, exact, error)


def test_loop_transfer_function_and_margins_equal_the_reference() -> None:
    system = with_feedback(arm(), [yaw_pd(0.05)])
    mass, damping, stiffness, _ = reference_dynamics(ctmm.linearize(system).operating_point.q)
    e = yaw_unit(mass.shape[0])
    omega = np.array([0.5, 7.0, 17.0, 60.0])
    s = 1j * omega
    expected = [(KP + KD * z) * np.exp(-z * 0.05) * e @ np.linalg.solve(mass * z * z + damping * z + stiffness, e)
                for z in s]
    L = loop_transfer_function(system, "pd", omega)
    np.testing.assert_allclose(L("pd.L", "pd.u"), expected, rtol=1e-9)
    tau, _ = reference_margin(mass, damping, stiffness)
    result = margins(system, "pd", np.linspace(0.1, 40.0, 400))
    assert result.delay_margin == pytest.approx(tau - 0.05, rel=1e-8)
    assert any("spatial model: L is that of the linearisation" in note for note in result.notes)


def test_closed_loops_give_the_reference_eigenvalues_and_frequency_response() -> None:
    delay = 0.03
    system = with_feedback(arm(), [TIP_LOOP, yaw_pd(delay)])
    lin = ctmm.linearize(system, inputs=["yaw.torque", "link.tip.force_x", "tip.reference"],
                         outputs=["yaw.angle", "link.tip.x", "tip.u"])
    mass, damping, stiffness, tip = reference_dynamics(lin.operating_point.q)
    n = mass.shape[0]
    J = tip[1]                                          # d (tip y) / d x = the tip's world-y velocity row
    K_closed, C_closed = stiffness + TIP_KP * np.outer(J, J), damping + TIP_KD * np.outer(J, J)
    A_ref = np.block([[np.zeros((n, n)), np.eye(n)], [-np.linalg.solve(mass, K_closed), -np.linalg.solve(mass, C_closed)]])
    ours = np.sort_complex(np.linalg.eigvals(lin.state_space.A))
    np.testing.assert_allclose(ours, np.sort_complex(np.linalg.eigvals(A_ref)), rtol=1e-9, atol=1e-9)
    omega = np.array([0.3, 6.9, 12.0, 45.0])
    frf = ctmm.frequency_response(system, omega, input=["yaw.torque", "link.tip.force_x", "tip.reference"],
                                  output=["yaw.angle", "link.tip.x", "tip.u", "pd.u"])
    e = yaw_unit(n)
    for k, w in enumerate(omega):
        s = 1j * w
        yaw_law = (KP + KD * s) * np.exp(-s * delay)
        Z = mass * s * s + C_closed * s + K_closed + yaw_law * np.outer(e, e)
        forces = np.column_stack([e, tip[0], J])        # unit yaw torque, tip force x, tip reference (u = -(y - r))
        x = np.linalg.solve(Z, forces)
        expected = np.vstack([e @ x, tip[0] @ x, -(TIP_KP + TIP_KD * s) * (J @ x) + np.array([0, 0, 1.0]),
                              -yaw_law * (e @ x)])
        np.testing.assert_allclose(frf.response[:, :, k], expected, rtol=1e-9, atol=1e-12 * np.max(np.abs(expected)))
    assert frf.units["link.tip.x"] == "m" and frf.units["yaw.torque"] == "N m"


def _reference_sensors(tree, q: np.ndarray, v: np.ndarray) -> np.ndarray:
    """The sensors of :data:`SENSORS` from the reference kinematics (scipy for the rotation maps)."""
    kin = kinematics_reference.kinematics(tree, q, v)
    out = []
    for body in (1, 2):
        R, w = kin.rotation[body], kin.omega[body]
        point = {1: TIP, 2: np.array([0.1, -0.05, 0.02])}[body]
        world = kin.origin[body] + R @ point
        out += list(w) + list(R.T @ w) + list(Rotation.from_matrix(R).as_euler("XYZ"))
        out += list(Rotation.from_matrix(R).as_rotvec()) + list(world)
        out += list(kinematics_reference.point_jacobian(kin, body, world) @ v)
    wrist = tree.q_start[2]
    return np.array(out + [q[1], q[2], v[2], q[wrist], q[wrist + 3]])   # quaternions scalar last


SENSORS = [name for body, point in (("link", "tip"), ("hand", "finger"))
           for pattern in ("{b}.omega_{a}", "{b}.omega_body_{a}", "{b}.angle_{a}", "{b}.rotation_{a}", "{b}.{p}.{a}",
                           "{b}.{p}.v{a}")
           for name in (pattern.format(b=body, p=point, a=a) for a in "xyz")]
SENSORS += ["hip.q1", "hip.q2", "hip.q2_rate", "wrist.qx", "wrist.qw"]


@pytest.mark.parametrize("half_angle", [0.35, 1.3])     # the hand's rotation vector from the trace / from R_zz
def test_sensor_rows_equal_differences_of_the_reference_kinematics(half_angle: float) -> None:
    model = arm(wrist=True)
    turn = np.r_[np.cos(half_angle), np.sin(half_angle) * np.array([0.6, 0.0, 0.8])]
    q0 = model.normalized(np.r_[0.4, 0.3, -0.5, turn])
    v0 = np.r_[0.7, -0.4, 0.9, 0.0, 0.0, 0.0]           # spherical rates zero (the tangent is built about rest)
    lin = ctmm.linearize(model, (q0, v0), inputs=[], outputs=SENSORS, allow_nonequilibrium=True)
    C = np.asarray(lin.state_space.C)
    tree, q_ref = reference_tree(model), reference_configuration(model, q0)
    n = model.n_velocities

    def sensed(x: np.ndarray) -> np.ndarray:
        return _reference_sensors(tree, ref.retract(tree, q_ref, x[:n]), v0 + x[n:])

    base = sensed(np.zeros(2 * n))
    np.testing.assert_allclose(sensor_values(model, SENSORS, q0, v0), base, rtol=0, atol=1e-12)
    h = 1e-3
    for k in range(2 * n):
        step = np.zeros(2 * n)
        differences = []
        for scale in (1.0, 0.5):
            step[k] = h * scale
            differences.append((sensed(step) - sensed(-step)) / (2.0 * h * scale))
        richardson = (4.0 * differences[1] - differences[0]) / 3.0
        np.testing.assert_allclose(C[:, k], richardson, rtol=0, atol=1e-7, err_msg=f"column {k}")


def test_stability_chart_point_agrees_with_simulation() -> None:
    critical = delay_margin(with_feedback(arm(), [yaw_pd(0.05)])).critical_delay
    below, above = 0.6 * critical, 1.5 * critical
    chart = stability_chart(with_feedback(arm(), [yaw_pd(below)]), ("gain", [1.0, 1.2]), ("delay", [below, above]))
    assert bool(chart.stable[0, 0]) and not bool(chart.stable[1, 0])
    for delay, stable in ((below, True), (above, False)):
        result = ctmm.simulate(with_feedback(arm(), [yaw_pd(delay)]), 1.5, 1e-2, method="rk4",
                               x0={"yaw.angle": 0.02}, outputs=["yaw.angle"])
        t, y = np.asarray(result.time), np.abs(np.asarray(result["yaw.angle"]))
        first, last = np.max(y[t <= 0.5]), np.max(y[t >= 1.0])
        assert (last < 0.5 * first) if stable else (last > 2.0 * first), (delay, first, last)


def test_refusals_name_what_is_not_supported() -> None:
    system = with_feedback(arm(), [yaw_pd(0.05)])
    for verb in (lambda m: ctmm.natural_frequencies(m, n_modes=2), lambda m: ctmm.mode_shapes(m, n_modes=2),
                 lambda m: ctmm.eigenvalue_count(m, [1.0])):
        with pytest.raises(ctmm.ModelError, match=r"cannot honour the feedback loops \['pd'\].*characteristic_roots"
                                                  r".*system\.plant"):
            verb(system)
    model = arm()
    tilted = np.array([0.0, 0.0, np.pi / 2])            # the link turned by 90 deg about its second axis: gimbal lock
    with pytest.raises(ctmm.ModelError, match=r"'link\.angle_x' is at gimbal lock"):
        ctmm.linearize(model, (tilted, np.zeros(3)), inputs=["yaw.torque"], outputs=["link.angle_x", "yaw.angle"],
                       allow_nonequilibrium=True)
    with pytest.raises(ctmm.ModelError, match=r"'base\.rotation_z' reads a rotation of pi rad"):
        ctmm.linearize(model, (np.array([np.pi, 0.0, 0.0]), np.zeros(3)), outputs=["base.rotation_z", "yaw.angle"])
    with pytest.raises(ctmm.ModelError, match=r"unknown output .*link\.tip\.q.*available: .*link\.tip\.vx"):
        ctmm.linearize(system, outputs=["link.tip.q"])
    with pytest.raises(ctmm.ModelError, match=r"accelerations are not sensors"):
        ctmm.linearize(system, outputs=["link.tip.ax"])
    with pytest.raises(ctmm.ModelError, match=r"unknown spatial input .*link\.torque"):
        ctmm.linearize(system, inputs=["link.torque"])
    with pytest.raises(ctmm.ModelError, match=r"input 'hip\.torque1': joint 'hip' is not actuated"):
        ctmm.linearize(system, inputs=["hip.torque1"])
    saturating = with_feedback(arm(), [Feedback("pd", sensor="yaw.angle", actuator="yaw.torque", gain=1.0,
                                                saturation=(-1, 1))])
    with pytest.raises(ctmm.ModelError, match=r"ctmm\.linearize needs linear loops, but loop 'pd' saturates"):
        ctmm.linearize(saturating)


def test_real_time_lti_controller_states_are_appended_as_the_reference_lag() -> None:
    """A first-order lag ``C(s) = k / (T s + 1)`` on the tip's sensed y: its state joins ``A``."""
    import control

    gain, lag = 15.0, 0.05
    loop = Feedback("lag", sensor="link.tip.y", actuator="link.tip.force_y", gain=control.tf([gain], [lag, 1.0]))
    system = with_feedback(arm(), [loop])
    lin = ctmm.linearize(system, inputs=["yaw.torque"], outputs=["link.tip.y", "lag.u"])
    assert lin.state_space.state_labels[-1] == "lag_controller0" and lin.delays == ()
    mass, damping, stiffness, tip = reference_dynamics(lin.operating_point.q)
    n, J = mass.shape[0], tip[1]
    # x' = v, M v' = -K x - C v - J^T xi (u = -xi), xi' = (k J x - xi) / T
    A_ref = np.zeros((2 * n + 1, 2 * n + 1))
    A_ref[:n, n:2 * n] = np.eye(n)
    A_ref[n:2 * n, :n], A_ref[n:2 * n, n:2 * n] = -np.linalg.solve(mass, stiffness), -np.linalg.solve(mass, damping)
    A_ref[n:2 * n, 2 * n] = -np.linalg.solve(mass, J)
    A_ref[2 * n, :n], A_ref[2 * n, 2 * n] = gain * J / lag, -1.0 / lag
    np.testing.assert_allclose(np.sort_complex(np.linalg.eigvals(lin.state_space.A)),
                               np.sort_complex(np.linalg.eigvals(A_ref)), rtol=1e-9, atol=1e-9)
    omega = np.array([0.7, 9.0])
    frf = ctmm.frequency_response(system, omega, input="yaw.torque", output=["link.tip.y", "lag.u"])
    e = yaw_unit(n)
    for k, w in enumerate(omega):
        s = 1j * w
        law = gain / (lag * s + 1.0)
        x = np.linalg.solve(mass * s * s + damping * s + stiffness + law * np.outer(J, J), e)
        np.testing.assert_allclose(frf.response[:, 0, k], [J @ x, -law * (J @ x)], rtol=1e-9)
