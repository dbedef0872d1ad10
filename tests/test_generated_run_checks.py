"""The run checks of the generated time paths are the numpy paths' (docs/verbs.md, "Run checks on the generated
paths"): a run that diverges in one way stops the same on both paths -- the same SimulationError message, time,
element and partial result.

* A planar modal beam whose RK4 step is above the stability limit of its highest mode: its deflection bound
  exceeds its length long before any coordinate reaches the divergence bound (``1e6 max(1, |q0|)``), so only the
  beam rule (:meth:`ctmm.flexible.family.FlexibleFamily.check_divergence`, every step on the numpy path) stops
  it: plain (``compiled_scene``), with a loop inside the step (``compiled_control``) and with a co-simulated
  controller (``compiled_cosim``).
* A planar kinematic loop model with a co-simulated controller and a ``divergence_bound`` its rates cross long
  before its coordinates: the numpy path bounds the tree's coordinates only (``compiled_cosim`` bounded the rates
  too, and without ``divergence_bound`` nothing: the loop plant's guard is its tree's).
* A spatial beam spinning above its first critical speed without geometric stiffening, with a co-simulated
  controller (``compiled_cosim``: the spatial plant's beam rule, every step).
"""
from __future__ import annotations

import numpy as np
import pytest

import ctmm
from ctmm.control import Feedback, with_feedback
from ctmm.errors import SimulationError
from ctmm.flexible import ModalBeam
from ctmm.planar import Pinned, PlanarModel

from _controllers_import import load_controllers
from test_spatial_beam_guard import spinner

pytest.importorskip("casadi")

T_FINAL, DT = 1.0, 0.025        # the beam's second mode (117 rad/s) is above 2 sqrt 2 / DT = 113 rad/s
START = dict(x0=[0.0, 0.01, 0.0])
SPIN = dict(x0={"arm.qy1": 0.01}, v0={"hub.angle_rate": 8.0})


@pytest.fixture(autouse=True, scope="module")
def kernel_cache(tmp_path_factory):
    with pytest.MonkeyPatch.context() as patch:
        patch.setenv("CTMM_CACHE", str(tmp_path_factory.mktemp("kernels")))
        yield


def hub_beam() -> PlanarModel:
    """A pinned modal beam (two bending modes), no gravity."""
    return PlanarModel.chain("pinned_beam", [Pinned("o"), ModalBeam("b", length=1.3, bending_stiffness=5.0,
                                                                    mass_per_length=0.7, n_modes=2)],
                             gravity=(0.0, 0.0))


def idle_pid(sensor: str, actuator: str, sample_time: float = DT):
    """A PID with zero gains: a co-simulated controller that changes nothing."""
    return load_controllers().PID(sensor, actuator, kp=0.0, ki=0.0, kd=0.0, derivative_filter_time=0.0,
                                  sample_time=sample_time)


def failure(model, compiled: bool | None, **options) -> SimulationError:
    with pytest.raises(SimulationError) as caught:
        ctmm.simulate(model, options.pop("t_final", T_FINAL), options.pop("dt", DT), compiled=compiled,
                      **options)
    return caught.value


def assert_same_failure(model, element: str, numpy: bool | None = False, **options) -> None:
    """``numpy``: the ``compiled`` value of the numpy path (``None`` for a kinematic loop model's loop driver)."""
    numpy_error, generated = (failure(model, compiled, **dict(options)) for compiled in (numpy, True))
    assert generated.element == numpy_error.element == element
    assert generated.time == numpy_error.time and 0.0 < generated.time < options.get("t_final", T_FINAL)
    assert str(generated) == str(numpy_error)
    ours, theirs = generated.partial_result, numpy_error.partial_result
    np.testing.assert_array_equal(ours.time, theirs.time)
    assert ours.time[-1] < generated.time
    plant = getattr(model, "plant", model)
    for name in getattr(plant, "tree", plant).coordinates:
        np.testing.assert_allclose(ours[name], theirs[name], rtol=1e-9, atol=1e-12, err_msg=name)


@pytest.mark.parametrize("store_every", [1, 3])
def test_a_diverging_modal_beam_stops_the_same_on_the_plain_generated_path(store_every):
    """Also between stored rows (``store_every = 3``: the failing step 7 is replayed from the stored step 6)."""
    model = hub_beam()
    assert_same_failure(model, "b", method="rk4", stability_check="ignore", store_every=store_every, **START)
    bounded = failure(model, True, method="rk4", stability_check="ignore", **START)
    assert "deflection bound" in str(bounded) and "exceeds its length 1.3 m" in str(bounded)


@pytest.mark.parametrize("store_every", [1, 4])
def test_a_diverging_modal_beam_stops_the_same_with_a_loop_in_the_step(store_every):
    controlled = with_feedback(hub_beam(), [Feedback("hold", "b.theta", "o.torque", gain=0.0)])
    assert_same_failure(controlled, "b", method="rk4", stability_check="ignore", store_every=store_every, **START)


def test_a_diverging_modal_beam_stops_the_same_with_a_cosimulated_controller():
    assert_same_failure(hub_beam(), "b", method="rk4", stability_check="ignore",
                        controllers=[idle_pid("b.theta", "o.torque")], **START)


def test_a_diverging_spatial_beam_stops_the_same_with_a_cosimulated_controller():
    error = failure(spinner(False), True, method="rk4", t_final=2.0, dt=0.01,
                    controllers=[idle_pid("hub.angle_rate", "arm.force_y", 0.01)], **SPIN)
    assert "deflection bound" in str(error) and error.element == "arm"
    assert_same_failure(spinner(False), "arm", method="rk4", t_final=2.0, dt=0.01,
                        controllers=[idle_pid("hub.angle_rate", "arm.force_y", 0.01)], **SPIN)


def test_a_kinematic_loop_model_bounds_the_coordinates_of_its_tree_as_on_the_numpy_path():
    from ctmm.control.static_gain import StaticGainController
    from ctmm.scenarios.four_bar import mechanism, start

    loop = mechanism()
    q0, v0 = start(loop)
    idle = StaticGainController(["h3.angle"], ["h3.torque"], [[0.0]], sample_time=2e-3)
    # the rates leave 1.0 from their start at t = 0.08 s, the crank angle at t = 0.206 s
    assert_same_failure(loop, "crank.theta", t_final=0.3, dt=1e-3, x0=q0, v0=v0, controllers=[idle],
                        divergence_bound=1.0, numpy=None)


@pytest.mark.parametrize("store_every", [1, 4])
def test_a_spinning_modal_beam_stops_on_its_deflection_before_a_later_coordinate_bound_on_the_scheme_path(
        store_every):
    """Newmark on a beam spun above its first critical speed without geometric stiffening, ``divergence_bound = 2``:
    the deflection bound exceeds the length at t = 0.035 s, a modal coordinate leaves the bound at t = 0.105 s; the
    numpy path checks both rules at every step and stops at the first (the generated scheme path reported the
    later coordinate bound); with ``store_every = 4`` the failing step 7 is replayed from the stored step 4."""
    from ctmm.schemes import Newmark

    model = PlanarModel.chain("spinning_beam", [Pinned("o"), ModalBeam(
        "b", length=1.3, bending_stiffness=5.0, mass_per_length=0.7, n_modes=2, geometric_stiffening=False)],
        gravity=(0.0, 0.0))
    assert_same_failure(model, "b", method=Newmark(), t_final=0.5, dt=0.005, x0=[0.0, 0.01, 0.0],
                        v0=[30.0, 0.0, 0.0], divergence_bound=2.0, store_every=store_every)


@pytest.mark.parametrize("store_every", [1, 7])
@pytest.mark.parametrize("case", ["beam", "bound"])
def test_a_controlled_spatial_run_stops_with_the_numpy_loop_drivers_message(case, store_every):
    """Loops inside the generated spatial step: a beam past its deflection bound (no stiffening) and the hub angle
    past ``divergence_bound`` (stiffened, a stable run) stop with the message of the numpy loop driver's guard
    (:func:`ctmm.spatial.integrate.divergence_check`), not a message of the generated path's own, at the failing
    step also between stored rows (``store_every = 7``: the interval replayed step by step)."""
    controlled = with_feedback(spinner(case == "bound"), [Feedback("rate", "hub.angle_rate", "arm.force_y",
                                                                   gain=0.0)])
    options = dict(divergence_bound=0.5) if case == "bound" else {}
    assert_same_failure(controlled, "spinner" if case == "bound" else "arm", method="rk4", t_final=2.0, dt=0.01,
                        store_every=store_every, **SPIN, **options)


@pytest.mark.parametrize("loops", [False, True])
@pytest.mark.parametrize("store_every", [1, 7])
@pytest.mark.parametrize("case", ["beam", "bound"])
def test_a_spatial_scheme_run_stops_with_the_numpy_schemes_message(case, store_every, loops):
    """Newmark in generated C on the spinning beam, alone and with a loop inside the step
    (``compiled_spatial_scheme_loops``): past its deflection bound (no stiffening, step 19) and an entry past
    ``divergence_bound`` (stiffened, step 2): the numpy scheme path's message (its method label aside), time,
    element and partial result, also between stored rows (``store_every = 7``: the interval replayed step by step;
    the stored rows alone gave t = 0.21 s and 0.07 s)."""
    from ctmm.schemes import Newmark

    options = dict(divergence_bound=0.5) if case == "bound" else {}
    model = spinner(case == "bound")
    if loops:
        model = with_feedback(model, [Feedback("rate", "hub.angle_rate", "arm.force_y", gain=0.0)])
    numpy_error, generated = (failure(model, compiled, method=Newmark(), t_final=2.0, dt=0.01, store_every=store_every,
                                      **SPIN, **options) for compiled in (False, True))
    assert numpy_error.time == pytest.approx(0.02 if case == "bound" else 0.19, abs=1e-12)
    assert generated.element == numpy_error.element == ("spinner" if case == "bound" else "arm")
    assert generated.time == numpy_error.time and 0.0 < generated.time < 2.0
    assert str(generated) == str(numpy_error).replace("(dt-tmm/", "(dt-tmm-generated/")
    np.testing.assert_array_equal(generated.partial_result.time, numpy_error.partial_result.time)
    for name in ("hub.angle", "arm.qy1"):
        np.testing.assert_allclose(generated.partial_result[name], numpy_error.partial_result[name], rtol=1e-9,
                                   atol=1e-12, err_msg=name)


def test_a_diverging_spatial_beam_set_of_a_mapped_batch_stops_as_on_the_numpy_path():
    """``simulate_batch`` runs spatial sets mapped in one C call per block (``ParameterKernel.run_mapped``) with the
    guarded step: the set of the spinning beam without stiffening stops at the numpy RK4's step (t = 0.19 s, between
    the stored rows 0.14 s and 0.21 s), with its message (method label aside), element and partial result; the stiffer
    set (first critical speed above the spin) runs to the end."""
    sets = [{"arm.bending_stiffness_y": 1.4e5}, {"arm.mass_per_length": 1.2}]
    batch = ctmm.simulate_batch(spinner(False), sets, 2.0, 0.01, store_every=7, **SPIN)
    assert list(batch.failures) == [1] and batch.results[0] is not None
    generated, numpy_error = batch.failures[1], failure(spinner(False), False, method="rk4", t_final=2.0, dt=0.01,
                                                        store_every=7, **SPIN)
    assert generated.element == numpy_error.element == "arm"
    assert generated.time == numpy_error.time == pytest.approx(0.19, abs=1e-12)
    assert str(generated) == str(numpy_error).replace("(rk4)", "(rk4-generated)")
    np.testing.assert_array_equal(generated.partial_result.time, numpy_error.partial_result.time)
    np.testing.assert_allclose(generated.partial_result["arm.qy1"], numpy_error.partial_result["arm.qy1"],
                               rtol=1e-9, atol=1e-12)


@pytest.mark.parametrize("compiled", [None, True])
@pytest.mark.parametrize("kind", ["planar", "spatial"])
def test_a_kinematic_loop_model_alone_refuses_divergence_bound_by_name(kind, compiled):
    """A kinematic loop model without loops, inputs or controllers runs its own RK4 with projection (numpy:
    :func:`ctmm.loop_integration.integrate_loop_model`; generated: ``compiled_kinematic_loops``,
    ``compiled_spatial_kinematic_loops``), which has no ``divergence_bound`` check: the argument is refused by name,
    not dropped (the DT-TMM schemes and the loop-closing driver take it)."""
    if kind == "planar":
        from ctmm.scenarios.four_bar import mechanism, start
    else:
        from ctmm.scenarios.spatial_four_bar import mechanism, start
    loop = mechanism()
    q0, v0 = start(loop)
    with pytest.raises(ctmm.ModelError, match=r"divergence_bound=1\.0"):
        ctmm.simulate(loop, 0.01, 1e-3, method="rk4", x0=q0, v0=v0, divergence_bound=1.0, compiled=compiled)


def runaway_loops(sensor: str, actuator: str, pole: float) -> list:
    """An idle loop, then a loop whose controller ``C(s) = 1 / (s - pole)`` grows without bound behind an actuator
    saturated at 1e-3: its state overflows while the plant's coordinates and rates stay finite and small (RK4 of
    ``dt = 0.01`` and ``pole = 10^6`` multiplies it by about 4e14 a step, the schemes' trapezoidal controller step
    with ``pole = 199.5`` by (1 + pole dt / 2) / (1 - pole dt / 2) = 1199)."""
    import control

    return [Feedback("calm", sensor, actuator, gain=0.0),
            Feedback("runaway", sensor, actuator, gain=control.tf([1.0], [1.0, -pole]), saturation=(-1e-3, 1e-3))]


@pytest.mark.filterwarnings("ignore::RuntimeWarning")       # the numpy path's overflow of the runaway state
@pytest.mark.parametrize("store_every", [1, 5])
@pytest.mark.parametrize("method", ["rk4", "newmark"])
@pytest.mark.parametrize("kind", ["planar", "spatial"])
def test_a_loop_controller_state_that_overflows_stops_the_same_named_by_its_loop(kind, method, store_every):
    """Loops inside the generated step (RK4: ``compiled_control``; Newmark: ``compiled_scheme_loops``,
    ``compiled_spatial_scheme_loops``), planar and spatial: a controller state that goes non-finite while ``q`` and
    ``v`` stay finite stops with the numpy path's message naming the loop (element: the loop), at its step also
    between stored rows (``store_every = 5``: the interval replayed step by step).  Before, the generated RK4
    reported "the state (with controller states and delay ring)" or "controller state or delay history" at the
    stored row, no loop named, and the generated schemes ran to the end (a silent wrong answer)."""
    import ctmm.spatial as sp
    from ctmm.schemes import Newmark

    if kind == "planar":
        plant, start = hub_beam(), dict(stability_check="ignore", **START)
        sensor, actuator = "b.theta", "o.torque"
    else:
        plant = sp.SpatialModel("wheel", [sp.SpatialBody("disc", 1.0, np.diag([0.1, 0.1, 0.2])), sp.Revolute(
            name="hub", parent=None, child="disc", axis=(0.0, 0.0, 1.0), actuated=True)])
        start, sensor, actuator = dict(v0={"hub.angle_rate": 1.0}), "hub.angle_rate", "hub.torque"
    pole, t_final = (1.0e6, 0.5) if method == "rk4" else (199.5, 1.5)
    controlled = with_feedback(plant, runaway_loops(sensor, actuator, pole))
    options = dict(method="rk4" if method == "rk4" else Newmark(), t_final=t_final, dt=0.01, store_every=store_every,
                   **start)
    assert_same_failure(controlled, "runaway", **options)
    error = failure(controlled, True, **options)
    assert str(error).startswith("non-finite controller state of loop 'runaway' at t = ")
