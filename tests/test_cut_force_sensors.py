"""Cut forces as loop sensors: ``Feedback(sensor="<cut>.force_x|y", ...)`` on a kinematic loop model.

The four-bar (scenario ``four_bar``) with a loop from the cut force on the coupler at ``h3`` to the crank torque.
The force responds to the torque at once (``F = s theta + g u`` on the tangent), so the loop carries a feedthrough.

Independent reference: the global DAE of :mod:`ctmm.reference.planar_dae` (absolute coordinates, Lagrange
multipliers), which shares no code with the tree sweep, the cut-joint mechanism or the loop driver: its crank
stiffness ``k``, torque gain ``b`` and the multiplier's slope ``s`` and torque gain ``g`` on its own constraints
(the fixtures of ``tests/test_closed_loops_feedback.py``) give the closed loop ``u = -K e^{-s tau} (F - r)``:
``theta [(k + s^2)(1 + E g) + b E s_F] = b E r`` with ``E = K e^{-s tau}`` (real-time: ``tau = 0``, the algebraic
loop solved).  In time, the values the loop read are the DAE's multipliers at the run's states under the run's
torques; the delay margin's crossing is a root of that characteristic.
"""
from __future__ import annotations

import numpy as np
import pytest

import ctmm
from ctmm.control import Feedback, with_feedback
from ctmm.errors import ModelError
from ctmm.scenarios.four_bar import BODIES, mechanism, reference, start
from ctmm.stability import delay_margin
from test_closed_loops_feedback import cut_force_tangent, tangent  # noqa: F401  (fixtures)

GAIN = 0.05                     # [N m / N]: crank torque per newton of cut force


def _force_loop(delay: float) -> Feedback:
    return Feedback("force", sensor="h3.force_y", actuator="h1.torque", gain=GAIN, delay=delay)


@pytest.mark.parametrize("delay", [0.0, 0.01], ids=["real-time", "delayed"])
def test_linearisation_closes_the_cut_force_loop_as_the_dae_does(delay, tangent, cut_force_tangent):
    k, b = tangent
    slope, gain = cut_force_tangent
    s_force, g_force = slope[1], gain[1]
    controlled = with_feedback(mechanism(), [_force_loop(delay)])
    omega = np.array([0.0, 2.0, 7.0, 15.0])
    frf = ctmm.frequency_response(controlled, omega, input="force.reference", output=["crank.theta", "force.u"])
    E = GAIN * np.exp(-1j * omega * delay)
    theta = b * E / ((k - omega ** 2) * (1.0 + E * g_force) + b * E * s_force)
    np.testing.assert_allclose(frf("crank.theta", "force.reference"), theta, rtol=1e-7)
    np.testing.assert_allclose(frf("force.u", "force.reference"), E * (1.0 - s_force * theta) / (1.0 + E * g_force),
                               rtol=1e-7)
    lin = ctmm.linearize(controlled, inputs=["force.reference" if delay == 0.0 else "h1.torque"],
                         outputs=["crank.theta", "h3.force_y"])
    if delay == 0.0:            # the algebraic loop solved: s^2 + k + b K s_F / (1 + K g) = 0
        squared = -np.linalg.eigvals(lin.state_space.A) ** 2
        expected = k + b * GAIN * s_force / (1.0 + GAIN * g_force)
        np.testing.assert_allclose(np.sort(squared.real), [expected, expected], rtol=1e-7)
        assert lin.delays == ()
    else:                       # the delayed loop beside A, its sensor's feedthrough in D
        assert [d.delay for d in lin.delays] == [delay]
        assert list(lin.state_space.output_labels) == ["crank_theta", "h3_force_y", "force_y"]
        D = np.asarray(lin.state_space.D)
        np.testing.assert_allclose(D[1:, :], g_force, rtol=1e-7)   # the force, from the torque and the loop's u
        margin = delay_margin(controlled, "force")          # |K g| < 1/2: not neutral, certified
        s = 1j * margin.critical_frequency
        E = GAIN * np.exp(-s * margin.critical_delay)
        characteristic = (s ** 2 + k) * (1.0 + E * g_force) + b * E * s_force
        assert margin.stable and abs(characteristic) < 1e-6 * k


def _dae_forces(run, torques) -> np.ndarray:
    """The DAE's multiplier ``lambda_y`` of the cut ``h3`` at each stored state of ``run``, with the crank torque
    ``torques[k]`` [N m] from the ground (a motor on the DAE's crank)."""
    torque = [0.0]
    dae = reference()
    dae.add_motor(None, "crank", lambda t, angle, rate: torque[0])
    out = []
    for k in range(len(run.time)):
        torque[0] = float(torques[k])
        state = dae.assemble({b: run[f"{b}.theta"][k] for b in BODIES}, {b: run[f"{b}.theta_dot"][k] for b in BODIES})
        out.append(dae.solve(*state)[1][7])
    return np.array(out)


def test_delayed_cut_force_loop_reads_the_dae_multiplier_under_its_own_torque():
    """RK4, ``tau = 5 dt``: at every stored row the value the loop read (``"force.y"``, and the stored
    ``"h3.force_y"``) is the DAE's multiplier at the run's state under the run's torque ``"force.u"`` (measured
    3e-13 of the force), ``u(t) = -K y(t - tau)`` from the history at the grid, and the loop moves the crank.
    (Against a run at dt / 8 over 0.1 s: 6.7e-10, 2.0e-10 rad at dt = 2, 1 ms -- second order: the delayed force
    carries a kink at every ``t0 + k tau``, ``docs/closed_loops.md`` §3c.)"""
    loop = mechanism()
    q0, v0 = start(loop)
    controlled = with_feedback(loop, [_force_loop(0.01)])
    run = ctmm.simulate(controlled, 0.04, 2e-3, x0=q0, v0=v0, outputs=["h3.force_y"])
    assert run.info["loops"]["force"] == "history"
    reference_force = _dae_forces(run, run["force.u"])
    scale = np.max(np.abs(reference_force))
    assert np.max(np.abs(run["force.y"] - reference_force)) < 1e-11 * scale
    assert np.max(np.abs(run["h3.force_y"] - reference_force)) < 1e-11 * scale
    np.testing.assert_allclose(run["force.u"][5:], -GAIN * run["force.y"][:-5], rtol=0, atol=1e-14 * scale)
    assert np.ptp(run["force.u"][5:]) > 1e-3 * GAIN * scale             # the delayed loop follows the force
    free = ctmm.simulate(loop, 0.04, 2e-3, x0=q0, v0=v0)
    assert np.max(np.abs(free["crank.theta"] - run["crank.theta"])) > 1e-3


class _Recording:
    """A static gain ``u = K y`` that records what it measured."""

    direct_feedthrough = True

    def __init__(self, inputs, outputs, gains, sample_time):
        self.inputs, self.outputs, self.sample_time = tuple(inputs), tuple(outputs), sample_time
        self.gains, self.measured = np.asarray(gains, float), []

    def init(self, t0):
        return None

    def step(self, t, y, state):
        from ctmm.control.protocol import ControllerStep

        self.measured.append((float(t), np.array(y, float)))
        return ControllerStep(self.gains @ y, state)


def test_a_sampled_controller_reads_the_cut_force_under_the_held_torque():
    """Sampled every 2 ms (zero-order hold): each measurement of ``"h3.force_y"`` is the DAE's multiplier at the
    sample's state under the torque held up to it (the previous sample's output)."""
    loop = mechanism()
    q0, v0 = start(loop)
    controller = _Recording(["h3.force_y"], ["h1.torque"], [[-GAIN]], 2e-3)
    run = ctmm.simulate(loop, 0.02, 1e-3, x0=q0, v0=v0, controllers=[controller])
    times = np.array([t for t, _ in controller.measured])
    assert len(times) == 11 and np.allclose(times, run.time[::2])
    held = [0.0] + [-GAIN * float(y[0]) for _, y in controller.measured[:-1]]
    reference_force = _dae_forces(run, np.repeat(held, 2)[:len(run.time)])[::2]
    measured = np.array([y[0] for _, y in controller.measured])
    assert np.max(np.abs(measured - reference_force)) < 1e-11 * np.max(np.abs(reference_force))


def test_what_the_time_driver_cannot_honour_is_refused_by_name():
    loop = mechanism()
    q0, v0 = start(loop)
    with pytest.raises(ModelError, match="algebraic"):
        ctmm.simulate(with_feedback(loop, [_force_loop(0.0)]), 0.01, 1e-3, x0=q0, v0=v0)
    controller = _Recording(["h1.angle"], ["h1.torque"], [[-1.0]], 1e-3)
    with pytest.raises(ModelError, match="beside co-simulated controllers"):
        ctmm.simulate(with_feedback(loop, [_force_loop(0.01)]), 0.01, 1e-3, x0=q0, v0=v0, controllers=[controller])
    strong = Feedback("force", sensor="h3.force_y", actuator="h1.torque", gain=50.0, delay=0.01)
    with pytest.raises(ModelError, match="neutral"):
        ctmm.simulate(with_feedback(loop, [strong]), 0.01, 1e-3, x0=q0, v0=v0)


def _numpy(system, t_final: float, dt: float, *, x0, v0, **options):
    """The numpy loop driver's run (projected RK4), as ``compiled=None`` would run it without a compiler."""
    from ctmm.control.planar_time import simulate_closed_loop

    return simulate_closed_loop(system.plant, x0, v0, t_final, dt, loops=tuple(system.loops), **options)


def _algebraic_dae(gain: float, reference_value: float):
    """The DAE with a crank motor closing the real-time loop ``u = -K (lambda_y(u) - r)`` on its own multiplier:
    ``lambda_y`` is affine in the torque (two solves give it), so ``u = -K (lambda_0 - r) / (1 + K g)``."""
    torque = [0.0]
    dae = reference()
    dae.add_motor(None, "crank", lambda t, angle, rate: torque[0])
    plain = dae.solve

    def solve(q, v, baumgarte=0.0, t=0.0):
        torque[0] = 0.0
        free = plain(q, v, baumgarte, t)[1][7]
        torque[0] = 1.0
        response = plain(q, v, baumgarte, t)[1][7] - free
        torque[0] = -gain * (free - reference_value) / (1.0 + gain * response)
        return plain(q, v, baumgarte, t)

    dae.solve = solve
    return dae


def test_the_generated_cut_force_is_affine_in_the_actuators_as_the_dae_multiplier():
    """What the algebraic solve rests on: ``F = F_0 + J w`` on symbols (the generated kernel's cut-force map) is
    the DAE's multiplier at one moving state under crank and cut torques ``w`` of either sign and size (measured
    7e-15 of the force)."""
    import casadi as ca

    from ctmm.compiled_kinematic_loop_control import CompiledKinematicLoopControl

    loop = mechanism()
    q0, v0 = start(loop)
    q, v = np.asarray(q0, float), 3.0 * np.asarray(v0, float)         # on the cut joints, moving faster
    controlled = with_feedback(loop, [Feedback("force", sensor="h3.force_y", actuator="h1.torque", gain=GAIN),
                                      Feedback("hold", sensor="h3.angle", actuator="h3.torque", gain=1.0)])
    kernel = CompiledKinematicLoopControl(controlled, 1e-3)
    assert kernel.actuators == ("h1.torque", "h3.torque")
    mapping = kernel.loops.dependent.map
    F0, J = (np.asarray(a, float) for a in mapping(ca.DM(q), ca.DM(v), ca.DM(kernel.parameters), 0.0))
    torques = [0.0, 0.0]
    dae = reference()
    dae.add_motor(None, "crank", lambda t, angle, rate: torques[0])
    dae.add_motor("rocker", "coupler", lambda t, angle, rate: torques[1])
    state = dae.assemble(dict(zip(BODIES, q)), dict(zip(BODIES, v)))
    for w in ([0.0, 0.0], [0.7, 0.0], [0.0, -1.3], [25.0, 4.0]):
        torques[:] = w
        expected = dae.solve(*state)[1][7]
        assert abs(float(F0[0, 0] + J[0] @ np.array(w)) - expected) < 1e-13 * max(1.0, abs(expected)), w


def test_generated_delayed_cut_force_loops_equal_the_numpy_driver_and_read_the_dae_multiplier():
    """``compiled=True`` (refused before): the delayed force loop (tau = 5 dt) beside a real-time PD on the crank, an
    open-loop cut torque and a reference: every stored signal = the numpy driver to round-off (measured 8e-15 of
    each signal's peak; the sample's rate along the motion is exact in the C, a backward difference in numpy: 3e-9
    with its former step, 1e-3 of the state's size), and the value the loop read is the DAE's multiplier at the run's
    state under the run's crank torque."""
    from ctmm.signals import Harmonic

    loop = mechanism()
    q0, v0 = start(loop)
    pd = Feedback("pd", sensor=[("h1.angle", 2.0), ("h1.rate", 0.2)], actuator="h1.torque", gain=1.0)
    controlled = with_feedback(loop, [_force_loop(0.01), pd])
    options = dict(x0=q0, v0=v0, outputs=["h3.force_y"], references={"force": 2.0, "pd": 2.0 * q0[0]},
                   inputs={"h3.torque": Harmonic(0.3, 15.0)})
    generated = ctmm.simulate(controlled, 0.1, 2e-3, compiled=True, **options)
    plain = _numpy(controlled, 0.1, 2e-3, **options)
    assert generated.info["method"] == "rk4-generated" and generated.info["loops"]["force"] == "history"
    assert sorted(generated.time_signals()) == sorted(plain.time_signals())
    for name in plain.time_signals():
        scale = max(1.0, float(np.max(np.abs(plain[name]))))
        assert np.max(np.abs(generated[name] - plain[name])) <= 1e-12 * scale, name
    torque = generated["force.u"] + generated["pd.u"]
    dae = reference()
    held = [0.0, 0.0]
    dae.add_motor(None, "crank", lambda t, angle, rate: held[0])
    dae.add_motor("rocker", "coupler", lambda t, angle, rate: held[1])
    multiplier = []
    for k, t in enumerate(generated.time):
        held[:] = [float(torque[k]), 0.3 * np.sin(15.0 * t)]
        state = dae.assemble({b: generated[f"{b}.theta"][k] for b in BODIES},
                             {b: generated[f"{b}.theta_dot"][k] for b in BODIES})
        multiplier.append(dae.solve(*state)[1][7])
    reference_force = np.array(multiplier)
    scale = np.max(np.abs(reference_force))
    assert np.max(np.abs(generated["force.y"] - reference_force)) < 1e-11 * scale
    np.testing.assert_allclose(generated["force.u"][5:], -GAIN * (generated["force.y"][:-5] - 2.0), rtol=0,
                               atol=1e-14 * scale)


@pytest.mark.parametrize("reference_value", [0.0, 3.0])
def test_generated_real_time_cut_force_loop_is_the_algebraic_loop_of_the_dae(reference_value):
    """A real-time loop on the cut force (algebraic: the numpy driver refuses it) solved exactly in the generated
    step: the run follows the DAE whose motor closes the same algebraic loop on its own multiplier (measured 1.4e-10
    rad over 0.2 s at dt = 1 ms), every row's ``u = -K (y - r)`` to round-off with ``y`` the DAE's multiplier at the
    row's state under ``u``, and the loop acts."""
    loop = mechanism()
    q0, v0 = start(loop)
    controlled = with_feedback(loop, [_force_loop(0.0)])
    run = ctmm.simulate(controlled, 0.2, 1e-3, x0=q0, v0=v0, compiled=True, references={"force": reference_value},
                        outputs=["h3.force_y"])
    assert run.info["loops"] == {"force": "real-time"}
    dae = _algebraic_dae(GAIN, reference_value)
    dae_run = dae.simulate(dae.assemble(dict(zip(BODIES, q0)), dict(zip(BODIES, v0))), 0.2, t_eval=run.time)
    assert max(np.max(np.abs(run[f"{n}.theta"] - dae_run.angle(n))) for n in BODIES) < 1e-9
    reference_force = _dae_forces(run, run["force.u"])
    scale = np.max(np.abs(reference_force))
    assert np.max(np.abs(run["force.y"] - reference_force)) < 1e-11 * scale
    assert np.max(np.abs(run["h3.force_y"] - run["force.y"])) < 1e-13 * scale
    np.testing.assert_allclose(run["force.u"], -GAIN * (run["force.y"] - reference_value), rtol=0,
                               atol=1e-14 * scale)
    free = ctmm.simulate(loop, 0.2, 1e-3, x0=q0, v0=v0)
    assert np.max(np.abs(free["crank.theta"] - run["crank.theta"])) > 1e-3


def test_generated_cut_force_loops_refuse_by_name():
    """A singular algebraic loop (``1 + K g = 0`` at the start: ``g`` from the numpy model's solve) names the loop and
    its gain; saturation on a real-time one, co-simulated controllers beside one and a neutral delayed one too."""
    from ctmm.control.static_gain import StaticGainController

    loop = mechanism()
    q0, v0 = start(loop)
    ports = with_feedback(loop, []).ports
    response = (loop.solve(q0, v0, 0.0, ports.inputs({"h1.torque": 1.0}))[1][0, 1]
                - loop.solve(q0, v0, 0.0, None)[1][0, 1])
    gain = -1.0 / float(response)
    singular = Feedback("force", sensor="h3.force_y", actuator="h1.torque", gain=gain)
    with pytest.raises(ModelError, match=f"real-time loops 'force' \\(gain {gain!r}.*singular"):
        ctmm.simulate(with_feedback(loop, [singular]), 0.01, 1e-3, x0=q0, v0=v0, compiled=True)
    saturated = Feedback("force", sensor="h3.force_y", actuator="h1.torque", gain=GAIN, saturation=(-1.0, 1.0))
    with pytest.raises(ModelError, match="loop 'force': a real-time loop on \\['h3.force_y'\\] with saturation"):
        ctmm.simulate(with_feedback(loop, [saturated]), 0.01, 1e-3, x0=q0, v0=v0, compiled=True)
    controller = StaticGainController(["h1.angle"], ["h3.torque"], [[-1.0]], sample_time=1e-3)
    with pytest.raises(ModelError, match="beside co-simulated controllers"):
        ctmm.simulate(with_feedback(loop, [_force_loop(0.01)]), 0.01, 1e-3, x0=q0, v0=v0, compiled=True,
                      controllers=[controller])
    strong = Feedback("force", sensor="h3.force_y", actuator="h1.torque", gain=50.0, delay=0.01)
    with pytest.raises(ModelError, match="neutral"):
        ctmm.simulate(with_feedback(loop, [strong]), 0.01, 1e-3, x0=q0, v0=v0, compiled=True)


@pytest.fixture(scope="module")
def pendulum():
    """The hinged pendulum (a free body held by a revolute cut about world y at its origin), a start and its
    hanging equilibrium."""
    from ctmm.spatial import closed_loop_linear as linear
    from spatial_loop_helpers import hinged_pendulum

    loop = hinged_pendulum()
    q, v = loop.consistent_state({"free.qw": np.cos(0.25), "free.qy": np.sin(0.25), "free.x": 0.01},
                                 {"free.wy": 2.0}, keep=["free.wy"])
    return loop, q, v, linear.equilibrium(loop, q)


@pytest.mark.parametrize("delay", [0.0, 0.01], ids=["real-time", "delayed"])
def test_spatial_cut_force_loop_linearised_as_the_compound_pendulum(delay, pendulum):
    """``"hinge.force_x"`` -> ``"hinge.torque"``: the compound pendulum's closed form about the hanging equilibrium,
    ``J theta'' = -m g r theta + u``, the horizontal cut force on the body ``F_x = -m r theta''`` (the centre of mass
    ``r`` below the pivot), closed as above (measured 2e-11)."""
    loop, _, _, point = pendulum
    mass, arm = 1.2, np.hypot(0.1, 0.3)
    inertia = 0.03 + mass * arm ** 2
    k, b = mass * 9.81 * arm / inertia, 1.0 / inertia
    s_force, g_force = mass * arm * k, -mass * arm * b
    controlled = with_feedback(loop, [Feedback("force", sensor="hinge.force_x", actuator="hinge.torque", gain=0.2,
                                               delay=delay)])
    omega = np.array([0.0, 2.0, 7.0])
    frf = ctmm.frequency_response(controlled, omega, input="force.reference", output=["hinge.angle", "force.u"],
                                  operating_point=point)
    E = 0.2 * np.exp(-1j * omega * delay)
    theta = b * E / ((k - omega ** 2) * (1.0 + E * g_force) + b * E * s_force)
    np.testing.assert_allclose(frf("hinge.angle", "force.reference"), theta, rtol=1e-9)
    np.testing.assert_allclose(frf("force.u", "force.reference"), E * (1.0 - s_force * theta) / (1.0 + E * g_force),
                               rtol=1e-9)


def test_spatial_delayed_cut_force_loop_reads_the_dae_multiplier(pendulum):
    """RK4, ``tau = 5 dt``: the value the loop read is the spatial DAE's multiplier (its own rows, bodies in world
    coordinates) at the run's state under the run's cut torque about world y (measured 3e-14 N of 4.7 N); refused:
    a real-time loop (algebraic; the generated kernel solves it, ``tests/test_compiled_spatial_cut_force_loops.py``,
    where ``compiled=True`` runs this loop, refused before)."""
    from spatial_loop_helpers import dae_of, poses

    loop, q, v, _ = pendulum
    controlled = with_feedback(loop, [Feedback("force", sensor="hinge.force_x", actuator="hinge.torque", gain=0.2,
                                               delay=0.01)])
    run = ctmm.simulate(controlled, 0.03, 2e-3, x0=q, v0=v, outputs=["hinge.force_x"])
    dae = dae_of(loop)
    positions = np.column_stack([run[name] for name in loop.tree.coordinates])
    velocities = np.column_stack([run[name] for name in loop.tree.velocities])
    multiplier = np.array([dae.accelerations(dae.state(*poses(loop, positions[k], velocities[k])),
                                             {0: run["force.u"][k] * np.array([0.0, 1.0, 0.0])})[1][0]
                           for k in range(len(run.time))])
    scale = np.max(np.abs(multiplier))
    assert np.max(np.abs(run["force.y"] - multiplier)) < 1e-11 * scale
    assert np.max(np.abs(run["hinge.force_x"] - multiplier)) < 1e-11 * scale
    np.testing.assert_allclose(run["force.u"][5:], -0.2 * run["force.y"][:-5], rtol=0, atol=1e-13 * scale)
    with pytest.raises(ModelError, match="algebraic"):
        ctmm.simulate(with_feedback(loop, [Feedback("force", sensor="hinge.force_x", actuator="hinge.torque",
                                                    gain=0.2)]), 0.01, 1e-3, x0=q, v0=v)
