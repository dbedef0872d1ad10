"""Spatial cut forces as loop sensors in the generated loop driver (``compiled=True``, refused before).

Two scenes: the hinged pendulum (a free body held by a **revolute** cut, ``"hinge.force_x"`` -> ``"hinge.torque"``)
and the R-U-S-R four-bar (scenario ``spatial_four_bar``: a **spherical** cut ``s3``, ``"s3.force_z"`` ->
``"h1.torque"``, beside a real-time PD on the crank and a moment on the rocker).

Independent references: the numpy loop driver (``compiled=None``; delayed loops: it refuses real-time ones, which are
algebraic) and the spatial Newton-Euler DAE of :mod:`ctmm.reference.spatial_loop_dae` (bodies in world coordinates,
every joint as constraint rows, its multipliers the joint forces; it shares no code with the tree sweep, the cut
joints or the loop driver): at every stored row the value the loop read is the DAE's multiplier at the run's state
under the run's actuator values, and a real-time loop follows the DAE whose motor closes the same algebraic loop on
its own multiplier.
"""
from __future__ import annotations

import numpy as np
import pytest

import ctmm
from ctmm.control import Feedback, with_feedback
from ctmm.errors import ModelError
from ctmm.signals import Harmonic
from spatial_loop_helpers import dae_of, hinged_pendulum, poses, rusr
from test_compiled_kinematic_loop_control import _equal

GAIN = 0.2          # [N m / N]: torque per newton of cut force
STEP = 2e-3         # [s]


def _pendulum():
    """The hinged pendulum, a moving start on its cut joint, its loop (revolute cut) and the DAE's rows: the cut's
    force rows, the actuator's world moments ``{body: moment per unit}``."""
    loop = hinged_pendulum()
    q, v = loop.consistent_state({"free.qw": np.cos(0.25), "free.qy": np.sin(0.25), "free.x": 0.01},
                                 {"free.wy": 2.0}, keep=["free.wy"])
    return loop, q, v, "hinge.force_x", "hinge.torque", 0, {0: np.array([0.0, 1.0, 0.0])}


def _four_bar():
    """The R-U-S-R four-bar (spherical cut ``s3``; DAE rows: the tree's two revolutes 5 each and the universal 4,
    then s3's force), its start and the crank torque about world x on the crank (body 0)."""
    from ctmm.scenarios.spatial_four_bar import start

    loop = rusr()
    q, v = start(loop)
    return loop, q, v, "s3.force_z", "h1.torque", 14 + 2, {0: np.array([1.0, 0.0, 0.0])}


SCENES = {"revolute": _pendulum, "spherical": _four_bar}


def _body(loop, name: str) -> int:
    """The DAE's index of body ``name`` (the tree's order)."""
    return [body.name for body in loop.tree.bodies].index(name)


def _states(loop, run) -> tuple[np.ndarray, np.ndarray]:
    return (np.column_stack([run[name] for name in loop.tree.coordinates]),
            np.column_stack([run[name] for name in loop.tree.velocities]))


def _multipliers(loop, run, row: int, moments) -> np.ndarray:
    """The DAE's multiplier ``row`` at every stored state of ``run`` under the world moments ``moments(k)``
    (``{body: (3,)}``) of row ``k``."""
    dae = dae_of(loop)
    positions, velocities = _states(loop, run)
    return np.array([dae.accelerations(dae.state(*poses(loop, positions[k], velocities[k])), moments(k))[1][row]
                     for k in range(len(run.time))])


@pytest.mark.parametrize("scene", sorted(SCENES))
def test_generated_delayed_spatial_cut_force_loop_equals_the_numpy_driver_and_reads_the_dae_multiplier(scene):
    """``tau = 5 dt``: every stored signal = the numpy loop driver to round-off (measured 6e-14 revolute, 3e-14
    spherical of each signal's peak; the numpy driver's sample rate is a backward difference), the value the loop
    read is the DAE's multiplier at the run's state under the run's torques (4e-14 / 3e-14 N of 4.6 / 4.2 N),
    ``u = -K (y(t - tau) - r)``."""
    from ctmm.control.planar_time import simulate_closed_loop

    loop, q, v, sensor, actuator, row, axes = SCENES[scene]()
    laws = [Feedback("force", sensor=sensor, actuator=actuator, gain=GAIN, delay=5 * STEP)]
    if scene == "spherical":        # a real-time PD beside it on the same crank, an open-loop moment on the rocker
        laws.append(Feedback("pd", sensor=[("h1.angle", 2.0), ("h1.rate", 0.2)], actuator="h1.torque", gain=1.0))
    options = dict(outputs=[sensor], references={"force": 0.5, **({"pd": 0.4} if scene == "spherical" else {})},
                   inputs={"rocker.moment_y": Harmonic(0.3, 15.0)} if scene == "spherical" else {})
    controlled = with_feedback(loop, laws)
    generated = ctmm.simulate(controlled, 0.06, STEP, x0=q, v0=v, compiled=True, **options)
    plain = simulate_closed_loop(loop, q, v, 0.06, STEP, loops=tuple(laws), **options)
    assert generated.info["loops"]["force"] == "history"
    _equal(generated, plain)
    torque = generated["force.u"] + (generated["pd.u"] if scene == "spherical" else 0.0)

    def moments(k: int) -> dict:
        out = {body: torque[k] * axis for body, axis in axes.items()}
        if scene == "spherical":
            out[_body(loop, "rocker")] = np.array([0.0, 0.3 * np.sin(15.0 * generated.time[k]), 0.0])
        return out

    multiplier = _multipliers(loop, generated, row, moments)
    scale = np.max(np.abs(multiplier))
    assert np.max(np.abs(generated["force.y"] - multiplier)) < 1e-11 * scale
    assert np.max(np.abs(generated[sensor] - multiplier)) < 1e-11 * scale
    np.testing.assert_allclose(generated["force.u"][5:], -GAIN * (generated["force.y"][:-5] - 0.5), rtol=0,
                               atol=1e-13 * scale)


def _algebraic_dae(loop, row: int, axes: dict, reference_value: float):
    """The DAE with a motor closing the real-time loop ``u = -K (mu(u) - r)`` on its own multiplier ``mu`` (affine
    in the torque: two solves give it), ``u = -K (mu_0 - r) / (1 + K g)``; returns the DAE and ``torques(t, y)``."""
    dae = dae_of(loop)

    def torque(y: np.ndarray) -> float:
        free = dae.accelerations(y)[1][row]
        response = dae.accelerations(y, dict(axes))[1][row] - free
        return -GAIN * (free - reference_value) / (1.0 + GAIN * response)

    return dae, lambda t, y: {body: torque(y) * axis for body, axis in axes.items()}


@pytest.mark.parametrize("scene", sorted(SCENES))
def test_generated_real_time_spatial_cut_force_loop_is_the_algebraic_loop_of_the_dae(scene):
    """A real-time loop on a spatial cut force (algebraic: the numpy driver refuses it) solved exactly in the
    generated step: the run follows the DAE whose motor closes the same algebraic loop on its own multiplier
    (centres of mass and rotations, measured 1.5e-11 revolute, 1.7e-9 spherical over 0.1 s at 2 ms: RK4's error,
    1.1e-10 at 1 ms), every row's ``u = -K (y - r)`` with ``y`` the DAE's multiplier at the row's state under ``u``
    (3e-14 N), and the loop acts."""
    loop, q, v, sensor, actuator, row, axes = SCENES[scene]()
    controlled = with_feedback(loop, [Feedback("force", sensor=sensor, actuator=actuator, gain=GAIN)])
    run = ctmm.simulate(controlled, 0.1, STEP, x0=q, v0=v, compiled=True, references={"force": 0.5},
                        outputs=[sensor])
    assert run.info["loops"] == {"force": "real-time"}
    dae, torques = _algebraic_dae(loop, row, axes, 0.5)
    _, Y = dae.simulate(dae.state(*poses(loop, q, v)), run.time, torques=torques)
    positions, velocities = _states(loop, run)
    error = 0.0
    for k in range(len(run.time)):
        x, R, _, _ = poses(loop, positions[k], velocities[k])
        error = max(error, max(np.abs(a - b).max() for a, b in zip(x, dae.split(Y[k])[0])),
                    max(np.abs(a - b).max() for a, b in zip(R, dae.rotations(Y[k]))))
    assert error < 1e-8
    multiplier = _multipliers(loop, run, row, lambda k: {b: run["force.u"][k] * a for b, a in axes.items()})
    scale = np.max(np.abs(multiplier))
    assert np.max(np.abs(run["force.y"] - multiplier)) < 1e-11 * scale
    assert np.max(np.abs(run[sensor] - run["force.y"])) < 1e-13 * scale
    np.testing.assert_allclose(run["force.u"], -GAIN * (run["force.y"] - 0.5), rtol=0, atol=1e-14 * scale)
    free = ctmm.simulate(loop, 0.1, STEP, x0=q, v0=v)
    assert max(np.max(np.abs(free[name] - run[name])) for name in loop.tree.coordinates) > 1e-4


def test_the_generated_spatial_cut_force_is_affine_in_the_actuators_as_the_dae_multiplier():
    """What the algebraic solve rests on: ``F = F_0 + J w`` on symbols (the kernel's cut-force map of the spherical
    cut, all three axes) is the DAE's multiplier at a moving state under a crank torque and a rocker moment of
    either sign and size (measured 5e-15 of the force)."""
    import casadi as ca

    from ctmm.compiled_kinematic_loop_control import CompiledKinematicLoopControl

    loop, q, v, _, _, _, _ = _four_bar()
    v = 3.0 * np.asarray(v, float)                  # on the cut joints (the rows are linear in v), moving faster
    controlled = with_feedback(loop, [Feedback(f"f{axis}", sensor=f"s3.force_{axis}", actuator=actuator, gain=GAIN)
                                      for axis, actuator in (("x", "h1.torque"), ("y", "rocker.moment_y"),
                                                             ("z", "h1.torque"))])
    kernel = CompiledKinematicLoopControl(controlled, STEP)
    assert kernel.actuators == ("h1.torque", "rocker.moment_y")
    assert kernel.loops.dependent.names == ("s3.force_x", "s3.force_y", "s3.force_z")
    F0, J = (np.asarray(a, float) for a in kernel.loops.dependent.map(ca.DM(q), ca.DM(v), ca.DM.zeros(0), 0.0))
    dae = dae_of(loop)
    state = dae.state(*poses(loop, q, v))
    for w in ([0.0, 0.0], [0.7, 0.0], [0.0, -1.3], [25.0, 4.0]):
        moments = {0: np.array([w[0], 0.0, 0.0]), _body(loop, "rocker"): np.array([0.0, w[1], 0.0])}
        expected = dae.accelerations(state, moments)[1][14:17]
        assert np.max(np.abs(F0[:, 0] + J @ np.array(w) - expected)) < 1e-12 * max(1.0, np.max(np.abs(expected))), w


def test_generated_spatial_cut_force_loops_refuse_by_name(monkeypatch, tmp_path):
    """What the generated kernels do not cover is refused by name: a singular algebraic loop (``1 + K g = 0`` at the
    start, ``g`` from the numpy model's solve: the loop and its gain), saturation on a real-time loop, co-simulated
    controllers beside one, a neutral delayed one, and a cut-force loop in a generated DT-TMM scheme; each before
    anything is compiled (an empty kernel cache stays empty)."""
    from ctmm.control.static_gain import StaticGainController

    monkeypatch.setenv("CTMM_CACHE", str(tmp_path))
    loop, q, v, sensor, actuator, _, _ = _pendulum()
    ports = with_feedback(loop, []).ports
    forces = [loop.cut_loads(q, loop.solve(q, v, 0.0, inputs)[1])[0][0][0]
              for inputs in (ports.inputs({actuator: 1.0}), None)]
    gain = -1.0 / float(forces[0] - forces[1])
    singular = Feedback("force", sensor=sensor, actuator=actuator, gain=gain)
    with pytest.raises(ModelError, match=f"real-time loops 'force' \\(gain {gain!r}.*singular"):
        ctmm.simulate(with_feedback(loop, [singular]), 0.01, STEP, x0=q, v0=v, compiled=True)
    saturated = Feedback("force", sensor=sensor, actuator=actuator, gain=GAIN, saturation=(-1.0, 1.0))
    with pytest.raises(ModelError, match="loop 'force': a real-time loop on \\['hinge.force_x'\\] with saturation"):
        ctmm.simulate(with_feedback(loop, [saturated]), 0.01, STEP, x0=q, v0=v, compiled=True)
    delayed = Feedback("force", sensor=sensor, actuator=actuator, gain=GAIN, delay=5 * STEP)
    controller = StaticGainController(["free.wy"], ["p.moment_x"], [[-1.0]], sample_time=STEP)
    with pytest.raises(ModelError, match="loops on the cut forces \\['hinge.force_x'\\] beside co-simulated"):
        ctmm.simulate(with_feedback(loop, [delayed]), 0.01, STEP, x0=q, v0=v, compiled=True, controllers=[controller])
    strong = Feedback("force", sensor=sensor, actuator=actuator, gain=-5.0 * gain, delay=5 * STEP)
    with pytest.raises(ModelError, match="neutral"):
        ctmm.simulate(with_feedback(loop, [strong]), 0.01, STEP, x0=q, v0=v, compiled=True)
    with pytest.raises(ModelError, match="sensor 'hinge.force_x'.*DT-TMM schemes.*method='rk4'"):
        ctmm.simulate(with_feedback(loop, [delayed]), 0.01, STEP, x0=q, v0=v, compiled=True, method="newmark")
    assert not list(tmp_path.rglob("*.so"))


def test_generated_delayed_cut_force_loop_on_a_driven_tree_equals_the_numpy_driver():
    """The driven slider-crank (its crank at a prescribed angle: the sensors move with time) with a delayed loop from
    the spherical cut's force to the pendulum's hinge and a real-time PD beside it: every stored signal = the numpy
    driver to round-off (measured 2e-13 of each signal's peak; the sample's rate along the motion with ``dF/dt``)."""
    from ctmm.control.planar_time import simulate_closed_loop
    from test_compiled_spatial_driven_loops import slider_crank, start

    loop = slider_crank(bob_actuated=True)
    q, v = start(loop)
    laws = (Feedback("force", sensor="s4.force_x", actuator="h5.torque", gain=0.05, delay=5 * STEP),
            Feedback("pd", sensor=[("h5.angle", 0.5), ("h5.rate", 0.05)], actuator="h5.torque", gain=1.0))
    options = dict(outputs=["s4.force_x"], references={"force": 0.2})
    generated = ctmm.simulate(with_feedback(loop, laws), 0.06, STEP, x0=q, v0=v, compiled=True, **options)
    plain = simulate_closed_loop(loop, q, v, 0.06, STEP, loops=laws, **options)
    assert generated.info["loops"] == {"force": "history", "pd": "real-time"}
    _equal(generated, plain)
    assert np.max(np.abs(generated["force.u"])) > 1e-3


def _cut_kind_scenes():
    """Loop models with a universal cut, a prismatic cut with a law and an actuation between two moving bodies, and
    a driven prismatic cut (its drive force part of the cut force): ``(loop, q, v, t, actuators)``."""
    import ctmm.spatial as sp
    from ctmm.nonlinear_laws import LinearLaw
    from ctmm.spatial.closed_loops import SpatialCutJoint, SpatialKinematicLoopModel
    from spatial_loop_helpers import hooke_pendulum, rod

    hooke = hooke_pendulum()
    q, v = hooke.consistent_state({"free.qw": np.cos(0.2), "free.qx": np.sin(0.2)}, {"free.wx": 1.5, "free.wy": -1.0},
                                  keep=["free.wx", "free.wy"])
    yield hooke, q, v, 0.0, ("p.moment_x", "p.force_y")
    link = sp.SpatialBody("link", 0.3, np.diag([0.003, 0.002, 0.001]), center_of_mass=(0.02, 0.0, 0.0))
    cut = SpatialCutJoint(name="c", parent="arm", point="origin", child="link", kind="prismatic", axis=(0, 0, 1),
                          normal=(1, 0, 0), parent_normal=(1, 0, 0), law=LinearLaw(40.0, 0.3), rest=-0.2,
                          actuation=Harmonic(0.3, 5.0))
    sleeve = SpatialKinematicLoopModel(sp.SpatialModel("two_moving", [
        rod("arm", 0.8, 0.6), sp.Revolute(name="h1", parent=None, child="arm", axis=(1, 0, 0), actuated=True),
        link, sp.Free(name="free", parent=None, child="link")]), [cut])
    q, v = sleeve.consistent_state({"h1.angle": 0.4, "free.z": -0.3}, {"h1.angle_rate": 1.5}, keep=["h1"])
    yield sleeve, q, v, 0.13, ("c.force", "h1.torque")
    tree = sp.SpatialModel("slider", [sp.SpatialBody("p", 1.2, np.diag([0.02, 0.03, 0.025]),
                                                     center_of_mass=(0.05, 0.02, 0.0)),
                                      sp.Free(name="free", parent=None, child="p")])
    drive = dict(position=Harmonic(0.05, 5.0, np.pi / 2), rate=Harmonic(0.25, 5.0, np.pi),
                 acceleration=Harmonic(-1.25, 5.0, np.pi / 2))
    driven = SpatialKinematicLoopModel(tree, [SpatialCutJoint(name="guide", parent=None, child="p", kind="prismatic",
                                                              axis=(0.0, 0.6, 0.8), **drive)])
    q, v = driven.consistent_state({"free.y": 0.03, "free.z": 0.04}, {})
    yield driven, q, v, 0.0, ("p.force_z", "p.moment_x")


@pytest.mark.parametrize("index", [0, 1, 2], ids=["universal", "prismatic-law", "prismatic-driven"])
def test_the_cut_force_map_of_every_cut_kind_is_the_numpy_cut_load(index):
    """``F_0 + J w`` on symbols (:meth:`SpatialKinematicLoopSymbols.input_sensor_map`, the forces of the unknowns
    alone: a law's and an actuation's load along a prismatic guide not in it, a driven cut's drive force in it) =
    :meth:`SpatialKinematicLoopModel.cut_loads` of the numpy solve under the same actuator values, at a moving
    state and a time where the actuation and the drive move: to ``10 eps cond(G)`` of the force, the round-off of the
    boundary solve (measured 2e-14 universal, 1.1e-12 = 1.7 eps cond(G) prismatic with law, cond(G) = 2.8e3, 4e-15
    driven prismatic)."""
    import casadi as ca

    from ctmm.compiled_spatial_kinematic_loops import symbolic_spatial_closed_loop
    from ctmm.compiled_spatial_loop_symbols import SpatialKinematicLoopSymbols

    loop, q, v, t, actuators = list(_cut_kind_scenes())[index]
    ports = with_feedback(loop, []).ports
    closed, _, coordinates, law_moments = symbolic_spatial_closed_loop(loop, actuators)
    symbols = SpatialKinematicLoopSymbols(loop, ports, coordinates, law_moments, closed)
    names = [f"{loop.cuts[0].name}.force_{axis}" for axis in "xyz"]
    assert symbols.input_dependent == frozenset(names)
    F0, J = (np.asarray(a, float) for a in symbols.input_sensor_map(names, len(actuators))(q, v, ca.DM.zeros(0), t))
    assert np.max(np.abs(J)) > 1e-3
    bound = 10.0 * np.finfo(float).eps * np.linalg.cond(np.asarray(closed(q, v, np.zeros(2), np.zeros(0), t)[5]))
    for w in ([0.0, 0.0], [0.7, 0.0], [0.0, -1.3], [25.0, 4.0]):
        inputs = ports.inputs(dict(zip(actuators, w)))
        expected = loop.cut_loads(q, loop.solve(q, v, t, inputs)[1], t)[0][0]
        assert np.max(np.abs(F0[:, 0] + J @ np.array(w) - expected)) < bound * max(1.0, np.max(np.abs(expected))), w


def test_generated_delayed_loop_on_the_force_at_a_beam_tip_equals_the_numpy_driver():
    """A cut pinning a SpatialBeam's tip (the point traced on symbols, the force through the beam's own load path):
    a delayed loop from the pin's force to the hub's moment = the numpy driver to round-off (measured 1.2e-14 of
    each signal's peak)."""
    from test_compiled_kinematic_loop_control import _numpy
    from test_spatial_cut_points import BEAM, PinnedBeamReference, assembled, beam_loop, beam_state

    q0, u0 = beam_state(4)
    u0, p0 = assembled(PinnedBeamReference(True, BEAM["length"]), q0, u0)
    controlled = with_feedback(beam_loop(True, "tip", p0), [Feedback("force", sensor="pin.force_y",
                                                                     actuator="hub.moment_z", gain=0.05, delay=STEP)])
    options = dict(x0=q0, v0=u0, outputs=["yaw.angle"])
    generated = ctmm.simulate(controlled, 0.02, 1e-3, compiled=True, **options)
    _equal(generated, _numpy(controlled, 0.02, 1e-3, **options))
    assert np.ptp(generated["force.u"]) > 0.05


def _stored_load_scenes():
    """:func:`_cut_kind_scenes` (universal, prismatic with law and actuation, driven prismatic), the ball on a spherical
    cut with a 3-axis law (tests/test_spatial_spherical_cut_law.py) and a free body on a driven revolute cut (its drive
    moment part of the cut moment): ``(loop, q, v)``."""
    import ctmm.spatial as sp
    from ctmm.spatial.closed_loops import SpatialCutJoint, SpatialKinematicLoopModel
    from test_spatial_spherical_cut_law import LAW, _ball, _start

    scenes = [(loop, q, v) for loop, q, v, _, _ in _cut_kind_scenes()]
    ball = _ball(LAW)
    scenes.append((ball, *_start(ball)))
    tree = sp.SpatialModel("hinged", [sp.SpatialBody("p", 1.2, np.diag([0.02, 0.03, 0.025]),
                                                     center_of_mass=(0.1, 0.0, -0.3)),
                                      sp.Free(name="free", parent=None, child="p")])
    drive = dict(position=Harmonic(0.2, 5.0, np.pi / 2), rate=Harmonic(1.0, 5.0, np.pi),
                 acceleration=Harmonic(-5.0, 5.0, np.pi / 2))
    hinge = SpatialKinematicLoopModel(tree, [SpatialCutJoint(name="hinge", parent=None, child="p", kind="revolute",
                                                             axis=(0, 1, 0), **drive)])
    scenes.append((hinge, *hinge.consistent_state({}, {})))
    return scenes


def _numpy_stored_loads(loop, run) -> tuple[np.ndarray, np.ndarray]:
    """The numpy run's stored cut forces and moments at the rows of ``run``, row by row
    (:meth:`SpatialKinematicLoopModel.stored_row`: the numpy solve, :meth:`~SpatialKinematicLoopModel.cut_loads` and
    the spherical law's moment -- the formula the generated runs evaluated in numpy before their kernels output it)."""
    forces, moments = [], []
    for t, q, v in zip(run.t, run.q, run.v):
        _, _, loads, law = loop.stored_row(q, v, float(t))
        forces.append([f for f, _ in loads])
        moments.append(np.array([m for _, m in loads]) + law)
    return np.array(forces), np.array(moments)


@pytest.mark.parametrize("index", range(5), ids=["universal", "prismatic-law", "prismatic-driven", "spherical-law",
                                                  "revolute-driven"])
def test_the_generated_runs_store_the_numpy_cut_loads_row_by_row(index):
    """The generated RK4's stored cut forces and moments (output by its kernel, ``F`` and ``M`` of
    :func:`ctmm.compiled_spatial_kinematic_loops.symbolic_spatial_closed_loop`) = the numpy formula at the same stored
    states, row by row, for every cut kind (a law's moment, a drive's moment and force in them): to 1e-12 of the
    largest load (measured <= 1.5e-14).  The generated schemes store the same ``M`` (the closed-loop function mapped
    over their rows): tests/test_compiled_spatial_loop_schemes.py against the numpy scheme."""
    from ctmm.compiled_spatial_kinematic_loops import simulate_spatial_kinematic_loops_generated

    loop, q, v = _stored_load_scenes()[index]
    run = simulate_spatial_kinematic_loops_generated(loop, q, v, t_final=0.02, dt=1e-3)
    forces, moments = _numpy_stored_loads(loop, run)
    scale = max(1.0, np.abs(forces).max(), np.abs(moments).max())
    assert np.abs(moments).max() > 1e-2 and run.cut_force.shape == forces.shape == (len(run.t), 1, 3)
    assert np.abs(run.cut_force - forces).max() <= 1e-12 * scale
    assert np.abs(run.cut_moment - moments).max() <= 1e-12 * scale
