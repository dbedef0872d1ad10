"""Every public verb honours everything in the system it is given, or refuses it (issue 11, "Why" 2).

Honoured pairs are checked against independent references that share no transfer-matrix code:

* ``ctmm.reference.chain`` (global ``M, C, K``, ``eigh``) for natural frequencies;
* ``ctmm.reference.delay_chain.closed_loop_dynamic_stiffness`` (dense closed-loop solve with exact
  ``e^{-s tau}``) for the steady state of a loaded controlled chain;
* ``ctmm.reference.delay_newmark.newmark_closed_loop`` (textbook Newmark on ``M, C, K`` with the
  loop rule) for ``ctmm.simulate`` of a loaded controlled chain with loop references.

Refused pairs must raise :class:`ctmm.ModelError` naming what is not supported and what to use.
The table of all pairs is in ``docs/control.md`` §4b.
"""
from __future__ import annotations

import numpy as np
import pytest

import ctmm
import ctmm.modal
from ctmm.capabilities import describe
from ctmm.control import ControlledChain, ControllerStep, Feedback, simulate_controlled
from ctmm.control.analysis import margins
from ctmm.elements import Fixed, Free, Mass, PrescribedDisplacement, PrescribedForce, Spring, SpringDamper
from ctmm.planar import Pinned, PlanarModel, RigidBody
from ctmm.reference.chain import GlobalChain
from ctmm.reference.chain import natural_frequencies as global_natural_frequencies
from ctmm.reference.delay_chain import GlobalLoop, closed_loop_dynamic_stiffness
from ctmm.reference.delay_newmark import newmark_closed_loop
from ctmm.signals import Harmonic

MASSES = [1.0, 1.5, 2.0]
STIFFNESS = [100.0, 80.0, 120.0]
DAMPING = [0.5, 0.3, 0.4]
LOAD = Harmonic(2.0, 7.0, phase=0.3)   # force on m1 [N]: 2 sin(7 t + 0.3)


def lumped(damping=DAMPING, load=0.0) -> ctmm.Chain:
    """ground -[k0]- m0 -[k1]- m1 -[k2]- m2, free end (k_i, c_i between consecutive masses)."""
    elements = [Fixed("wall")]
    for i, (m, k, c) in enumerate(zip(MASSES, STIFFNESS, damping)):
        elements.append(SpringDamper(f"k{i}", k, c) if c else Spring(f"k{i}", k))
        elements.append(Mass(f"m{i}", m, force=load if i == 1 else 0.0))
    return ctmm.Chain("three", elements + [Free("end")])


def global_chain(damping=DAMPING) -> GlobalChain:
    n = len(MASSES)
    return GlobalChain(np.array(MASSES), np.array(STIFFNESS + [0.0]), np.array(list(damping) + [0.0]),
                       np.zeros(n + 1), np.zeros(n), np.zeros(n), start="fixed", end="free")


# Loops: (ctmm Feedback, global reference loop); velocity m2 -> m0 real time, displacement m2 -> m1 delayed
LOOPS = [(Feedback("Lv", "m2.v", "m0", gain=3.0), GlobalLoop(2, "velocity", 0, 3.0)),
         (Feedback("Lx", "m2.x", "m1", gain=20.0, delay=0.043), GlobalLoop(2, "displacement", 1, 20.0, 0.043))]


def controlled(plant: ctmm.Chain) -> ControlledChain:
    return ControlledChain(plant, [feedback for feedback, _ in LOOPS])


def planar_model() -> PlanarModel:
    link = RigidBody("a", mass=1.0, inertia=0.1, center_of_mass=(0.5, 0.0), inboard=(0.0, 0.0),
                     outboard={"tip": (1.0, 0.0)})
    return PlanarModel.chain("pendulum", [Pinned("base"), link])


# ------------------------------------------------------------------------ natural-frequency verbs
NATURAL_VERBS = {
    "natural_frequencies": lambda system: ctmm.natural_frequencies(system, n_modes=2),
    "mode_shapes": lambda system: ctmm.mode_shapes(system, n_modes=2),
    "eigenvalue_count": lambda system: ctmm.eigenvalue_count(system, [5.0, 50.0]),
    "modal_response": lambda system: ctmm.modal.modal_response(system, np.array([0.0, 0.1])),
}


@pytest.mark.parametrize("verb", list(NATURAL_VERBS))
def test_natural_frequency_verbs_refuse_feedback_loops(verb):
    """Closed-loop roots are not undamped natural frequencies: refused (was the plant's answer or a
    numpy broadcast error), with the closed-loop tool and ``system.plant`` named."""
    system = controlled(lumped(damping=[0.0] * 3))
    instead = r"ctmm\.simulate" if verb == "modal_response" else r"ctmm\.stability\.characteristic_roots"
    with pytest.raises(ctmm.ModelError, match=rf"{verb} cannot honour the feedback loops \['Lv', 'Lx'\].*"
                                              rf"{instead}.*system\.plant"):
        NATURAL_VERBS[verb](system)


@pytest.mark.parametrize("verb", ["natural_frequencies", "mode_shapes", "eigenvalue_count"])
def test_natural_frequency_verbs_refuse_damping(verb):
    """``eigenvalue_count`` used to count a damped chain's undamped frequencies without a word."""
    with pytest.raises(ctmm.ModelError, match=r"needs an undamped system, but 'k0' has damping=0\.5; "
                                              r"use ctmm\.frequency_response"):
        NATURAL_VERBS[verb](lumped())


def test_controlled_chain_without_loops_is_its_plant():
    """A ControlledChain with no loop is answered as its plant: equal to global ``eigh``."""
    plant = lumped(damping=[0.0] * 3, load=LOAD)   # loads do not enter natural frequencies
    reference = global_natural_frequencies(global_chain(damping=[0.0] * 3))
    omega = ctmm.natural_frequencies(ControlledChain(plant, []), n_modes=3)
    np.testing.assert_allclose(omega, reference, rtol=1e-12)
    counts = ctmm.eigenvalue_count(ControlledChain(plant, []), [0.5 * (reference[0] + reference[1])])
    assert counts.tolist() == [1]


# ------------------------------------------------------------------------ systems that are not chains
CHAIN_VERBS = {
    "ctmm.simulate": lambda system: ctmm.simulate(system, 0.1, 0.01),
    "simulate_controlled": lambda system: simulate_controlled(system, 0.1, 0.01),
    "frequency_response": lambda system: ctmm.frequency_response(system, [1.0], input="m0.force",
                                                                 output="m0.x"),
    "steady_state_response": lambda system: ctmm.steady_state_response(system, 1.0),
    "characteristic_function": lambda system: ctmm.characteristic_function(system, [1j]),
    **NATURAL_VERBS,
}


PLANAR_ANSWERED = {"frequency_response", "natural_frequencies", "mode_shapes", "eigenvalue_count"}


@pytest.mark.parametrize("verb", [v for v in CHAIN_VERBS if v != "modal_response"])
def test_chain_verbs_refuse_other_models(verb):
    """None or a planar model got AttributeError from inside the solver; now a ModelError that names
    the type and, for a planar model, the planar verbs."""
    with pytest.raises(ctmm.ModelError, match=r"system must be a ctmm\.Chain or a ctmm\.control\.ControlledChain, "
                                              r"got NoneType"):
        CHAIN_VERBS[verb](None)
    if verb in PLANAR_ANSWERED or verb == "ctmm.simulate":   # answered through ctmm.linearize / simulated (tests/test_linearize.py, tests/test_planar_simulate.py)
        return
    with pytest.raises(ctmm.ModelError, match=r"got PlanarModel .*with the verbs that answer every model: ctmm\.simulate, ctmm\.linearize"):
        CHAIN_VERBS[verb](planar_model())


def spatial_pendulum():
    import ctmm.spatial as sp
    from ctmm.control import with_feedback

    plant = sp.SpatialModel("swing", [sp.SpatialBody("b", 1.0, (0.1, 0.1, 0.1), center_of_mass=(0, 0, -0.5)),
                                      sp.Revolute(name="hinge", parent=None, child="b", axis=(1, 0, 0), actuated=True)])
    return plant, with_feedback(plant, [Feedback("pd", [("hinge.angle", 5.0), ("hinge.rate", 1.0)], "hinge.torque",
                                                 gain=1.0, delay=0.01)])


@pytest.mark.parametrize("verb", ["simulate_controlled", "steady_state_response", "characteristic_function"])
def test_chain_verbs_refuse_spatial_models_naming_the_verbs_that_answer_them(verb):
    """A spatial model and a controlled one are answered by the verbs of every model (the linear ones through
    the linearisation: tests/test_spatial_controlled_linear.py); the chain-only verbs refuse and name them."""
    plant, controlled = spatial_pendulum()
    with pytest.raises(ctmm.ModelError, match=r"got SpatialModel .*ctmm\.linearize, ctmm\.frequency_response.*"
                                              r"ctmm\.stability with loops"):
        CHAIN_VERBS[verb](plant)
    with pytest.raises(ctmm.ModelError, match=r"got ControlledModel .*planar and spatial plants with loops.*"
                                              r"ctmm\.linearize, ctmm\.frequency_response.*delay_margin"):
        CHAIN_VERBS[verb](controlled)


# ------------------------------------------------------------------------ honoured: loops + loads
def test_steady_state_of_loaded_controlled_chain_equals_dense_closed_loop_solve():
    """``steady_state_response`` closes every loop (real-time and delayed, exact ``e^{-i w tau}``)
    under the element's own harmonic load: equal to ``D(i w)^{-1} F`` of the global model."""
    system = controlled(lumped(load=LOAD))
    w = LOAD.omega
    result = ctmm.steady_state_response(system, w, outputs=["m0.x", "m1.x", "m2.x"])
    phasor = -1j * LOAD.amplitude * np.exp(1j * LOAD.phase)           # F(t) = Re(phasor e^{iwt})
    t = 0.37
    assert abs((phasor * np.exp(1j * w * t)).real - LOAD(t)) < 1e-14
    D = closed_loop_dynamic_stiffness(global_chain(), [g for _, g in LOOPS], np.array([1j * w]))[0]
    expected = np.linalg.solve(D, np.array([0.0, phasor, 0.0]))
    got = np.array([result[f"m{i}.x"] for i in range(3)])
    np.testing.assert_allclose(got, expected, rtol=1e-11, atol=1e-14 * np.max(np.abs(expected)))


def test_simulate_loaded_controlled_chain_with_references_equals_global_newmark():
    """``ctmm.simulate`` honours a time-varying element load, a real-time and a delayed loop and
    constant loop references together: equal to the global closed-loop Newmark, in which the
    reference enters as the force ``+g r`` on the actuated mass (``u = -g (y - r)``)."""
    references = {"Lv": 0.2, "Lx": -0.01}
    x0 = {"m2": 0.05}
    result = ctmm.simulate(controlled(lumped(load=LOAD)), 0.6, 0.01, x0=x0, references=references)
    gains = {feedback.name: feedback.gain for feedback, _ in LOOPS}

    def force(t: float) -> np.ndarray:
        return np.array([gains["Lv"] * references["Lv"], LOAD(t) + gains["Lx"] * references["Lx"], 0.0])

    ref = newmark_closed_loop(global_chain(), [g for _, g in LOOPS], 0.6, 0.01, [0.0, 0.0, 0.05], np.zeros(3),
                              force_fn=force)
    got = np.column_stack([result[f"m{i}.x"] for i in range(3)])
    scale = np.max(np.abs(ref.displacement))
    assert np.max(np.abs(got - ref.displacement)) < 1e-12 * scale
    # the references really act: without them the answer differs by far more than round-off
    plain = ctmm.simulate(controlled(lumped(load=LOAD)), 0.6, 0.01, x0=x0)
    assert np.max(np.abs(plain["m1.x"] - result["m1.x"])) > 1e-4


# ------------------------------------------------------------------------ options that would be ignored
def test_simulate_refuses_coupling_without_controllers():
    with pytest.raises(ctmm.ModelError, match=r"coupling='previous' only applies to co-simulated controllers"):
        ctmm.simulate(controlled(lumped()), 0.1, 0.01, coupling="previous")


def test_simulate_refuses_plain_chain_options_with_loops():
    with pytest.raises(ctmm.ModelError, match=r"solver='plain' applies to uncontrolled chains only"):
        ctmm.simulate(controlled(lumped()), 0.1, 0.01, solver="plain")


def test_simulate_refuses_references_without_loops():
    with pytest.raises(ctmm.UnknownNameError, match=r"unknown loop 'L'; available: \(none\)"):
        ctmm.simulate(lumped(), 0.1, 0.01, references={"L": 1.0})


def test_margins_of_a_plain_chain_names_the_missing_loop():
    """Was "margins(data) takes no loop/omega": a chain was taken for frequency data."""
    with pytest.raises(ctmm.ModelError, match=r"margins needs a ControlledChain with loop 'L'.*plain Chain"):
        margins(lumped(), "L", np.linspace(1.0, 10.0, 20))
    with pytest.raises(ctmm.ModelError, match=r"margins\(system, loop, omega\) needs a ControlledChain, got NoneType"):
        margins(None, "L", np.linspace(1.0, 10.0, 20))


def test_describe_lists_loops_delays_and_damping():
    contents = describe(controlled(lumped()))
    assert contents.kind == "controlled chain"
    assert contents.loops == ("Lv", "Lx") and contents.delayed_loops == ("Lx",) and contents.lti_loops == ()
    assert contents.damped == ("k0", "k1", "k2")
    assert describe(lumped(damping=[0.0] * 3)).damped == ()


# ------------------------------------------------------------------------ honoured: prescribed base motion
BASE = Harmonic(0.02, 5.0)   # base displacement [m]: 0.02 sin(5 t)


def base_driven(damping=DAMPING) -> ctmm.Chain:
    """The chain of :func:`lumped` with the wall replaced by a prescribed displacement; the first
    connector is a pure spring, so the base acts on m0 exactly as the force ``k0 y(t)``."""
    elements = [PrescribedDisplacement("base", BASE), Spring("k0", STIFFNESS[0]), Mass("m0", MASSES[0])]
    for i in (1, 2):
        elements += [SpringDamper(f"k{i}", STIFFNESS[i], damping[i]), Mass(f"m{i}", MASSES[i])]
    return ctmm.Chain("driven", elements + [Free("end")])


def test_simulate_controlled_chain_with_prescribed_base_motion_equals_global_newmark():
    """Real-time and delayed loops with a prescribed base displacement: equal to the global Newmark
    of the walled chain loaded by ``k0 y(t)`` on m0."""
    result = ctmm.simulate(controlled(base_driven()), 0.6, 0.01)
    damping = [0.0] + DAMPING[1:]
    ref = newmark_closed_loop(global_chain(damping), [g for _, g in LOOPS], 0.6, 0.01, np.zeros(3), np.zeros(3),
                              force_fn=lambda t: np.array([STIFFNESS[0] * BASE(t), 0.0, 0.0]))
    got = np.column_stack([result[f"m{i}.x"] for i in range(3)])
    assert np.max(np.abs(ref.displacement)) > 1e-3
    assert np.max(np.abs(got - ref.displacement)) < 1e-12 * np.max(np.abs(ref.displacement))


def test_base_displacement_frequency_response_of_controlled_chain_equals_dense_solve():
    """``frequency_response`` from ``base.displacement`` with the loops closed: ``D(i w) X = k0 e_0``."""
    omega = np.array([0.5, 4.0, 9.0, 30.0])
    frf = ctmm.frequency_response(controlled(base_driven()), omega, input="base.displacement",
                                  output=["m0.x", "m2.x"])
    damping = [0.0] + DAMPING[1:]
    D = closed_loop_dynamic_stiffness(global_chain(damping), [g for _, g in LOOPS], 1j * omega)
    X = np.linalg.solve(D, np.broadcast_to(np.array([STIFFNESS[0], 0.0, 0.0]), (omega.size, 3))[..., None])[..., 0]
    np.testing.assert_allclose(frf("m0.x", "base.displacement"), X[:, 0], rtol=1e-11)
    np.testing.assert_allclose(frf("m2.x", "base.displacement"), X[:, 2], rtol=1e-11)


@pytest.mark.parametrize("delay", [0.0, 0.05])
def test_loop_sensing_a_prescribed_base_is_honoured_in_both_domains(delay):
    """A loop that senses the prescribed base displacement ``y`` and pushes m0 adds the known force
    ``-g y(t - tau)``: time response = global Newmark with that force (the delay is a whole number
    of steps, so the history is sampled exactly), FRF from ``base.displacement`` = dense solve of
    ``D(i w) X = (k0 - g e^{-i w tau}) e_0``."""
    gain = 30.0
    system = ControlledChain(base_driven(), [Feedback("B", "base.x", "m0", gain=gain, delay=delay)])
    result = ctmm.simulate(system, 0.6, 0.01)
    chain = global_chain([0.0] + DAMPING[1:])

    def force(t: float) -> np.ndarray:
        sensed = BASE(t - delay) if t >= delay else 0.0
        return np.array([STIFFNESS[0] * BASE(t) - gain * sensed, 0.0, 0.0])

    ref = newmark_closed_loop(chain, [], 0.6, 0.01, np.zeros(3), np.zeros(3), force_fn=force)
    got = np.column_stack([result[f"m{i}.x"] for i in range(3)])
    assert np.max(np.abs(got - ref.displacement)) < 1e-12 * np.max(np.abs(ref.displacement))

    omega = np.array([0.5, 4.0, 9.0])
    frf = ctmm.frequency_response(system, omega, input="base.displacement", output="m2.x")
    D = closed_loop_dynamic_stiffness(chain, [], 1j * omega)
    rhs = (STIFFNESS[0] - gain * np.exp(-1j * omega * delay))[:, None] * np.array([1.0, 0.0, 0.0])
    X = np.linalg.solve(D, rhs[..., None])[..., 0]
    np.testing.assert_allclose(frf("m2.x", "base.displacement"), X[:, 2], rtol=1e-11)


@pytest.mark.parametrize("system", [lumped(), controlled(lumped())], ids=["Chain", "ControlledChain"])
def test_planar_verbs_refuse_chains(system):
    """A 1-D chain (with or without loops) given to a planar verb got AttributeError; now the
    chain verbs are named."""
    from ctmm.planar import simulate_rk4
    from ctmm.planar.equilibrium import static_equilibrium

    with pytest.raises(ctmm.ModelError, match=r"ctmm\.planar simulation: model must be a ctmm\.planar\.PlanarModel, "
                                              r"got .*Chain.*ctmm\.simulate"):
        simulate_rk4(system, [0.0], [0.0], t_final=0.1, dt=0.01)
    with pytest.raises(ctmm.ModelError, match=r"ctmm\.planar\.equilibrium: model must be a ctmm\.planar\.PlanarModel"):
        static_equilibrium(system, [0.0])


# ------------------------------------------------------------------------ co-simulated controllers
class ConstantOutput:
    """A co-simulated controller that writes a constant value to one input (evaluated every step)."""

    inputs = ("m0.x",)
    sample_time = None
    direct_feedthrough = False

    def __init__(self, output: str, value: float) -> None:
        self.outputs = (output,)
        self.value = value

    def init(self, t0: float):
        return None

    def step(self, t: float, y: np.ndarray, state):
        return ControllerStep(np.array([self.value]), state)


def test_controller_output_across_a_connector_equals_global_newmark():
    """A controller output on a connector input acts across it (``+u`` outboard, ``-u`` inboard)."""
    result = ctmm.simulate(lumped(), 0.5, 0.01, controllers=[ConstantOutput("k2.force", 2.0)])
    ref = newmark_closed_loop(global_chain(), [], 0.5, 0.01, np.zeros(3), np.zeros(3),
                              force_fn=lambda t: np.array([0.0, -2.0, 2.0]))
    got = np.column_stack([result[f"m{i}.x"] for i in range(3)])
    assert np.max(np.abs(got - ref.displacement)) < 1e-12 * np.max(np.abs(ref.displacement))


@pytest.mark.parametrize("output", ["base.displacement", "tip.force"])
def test_controller_outputs_on_boundaries_are_refused(output):
    """Was silently misapplied ("base.displacement" moved the chain as some other load) or an
    IndexError ("tip.force")."""
    chain = ctmm.Chain("bounded", [PrescribedDisplacement("base", 0.0), Spring("k0", 100.0), Mass("m0", 1.0),
                                   PrescribedForce("tip", 0.0)])
    with pytest.raises(ctmm.ModelError, match=rf"controller output '{output}' is a boundary input.*drivable "
                                              r"outputs: k0\.force, m0\.force"):
        ctmm.simulate(chain, 0.1, 0.01, controllers=[ConstantOutput(output, 1.0)])


def test_improper_controller_is_refused_where_it_cannot_be_realised():
    """``C(s) = kp + kd s`` is exact in the frequency domain; in time and in a state-space export it
    was a raw python-control ValueError."""
    import control
    from ctmm.interop import to_state_space

    plant = ctmm.Chain("one", [Fixed("wall"), SpringDamper("k0", 100.0, 0.5), Mass("m0", 1.0), Free("end")])
    system = ControlledChain(plant, [Feedback("pd", "m0.x", "m0", gain=control.tf([0.5, 10.0], [1.0]))])
    omega = np.array([1.0, 10.0])
    frf = ctmm.frequency_response(system, omega, input="m0.force", output="m0.x")
    np.testing.assert_allclose(frf("m0.x", "m0.force"), 1 / (110.0 - omega ** 2 + 1j * omega), rtol=1e-13)
    with pytest.raises(ctmm.ModelError, match=r"loop 'pd': the controller C\(s\) cannot be realised in time"):
        ctmm.simulate(system, 0.1, 0.01)
    with pytest.raises(ctmm.ModelError, match=r"loop 'pd': the controller C\(s\) cannot be realised by to_state_space"):
        to_state_space(system, inputs="m0.force", outputs="m0.x")
