"""Controlled chains in the frequency domain: TMM closed loops against the global references.

References (independent of the TMM code): ``ctmm.reference.delay_chain`` -- dense solves of
``s^2 M + s C + K + sum g s^p e^{-s tau} b c^T`` and the generalized eigenproblem of the
delay-free closed loop -- and, for LTI controllers, the same dynamic stiffness assembled here by
hand from ``ctmm.reference.chain.assemble`` with ``C(i w)`` substituted.
"""
from __future__ import annotations

from dataclasses import dataclass

import control
import numpy as np
import pytest
from hypothesis import given, settings, strategies as st

import ctmm
from ctmm.control import ControlledChain, Feedback
from ctmm.elements import Fixed, Free, GroundedSpring, Mass, SpringDamper
from ctmm.errors import ModelError, UnknownNameError
from ctmm.reference.chain import GlobalChain, assemble
from ctmm.reference.delay_chain import (GlobalLoop, closed_loop_characteristic,
                                        closed_loop_frequency_response, closed_loop_roots)

QUANTITY = {"displacement": "x", "velocity": "v", "acceleration": "a"}


# ------------------------------------------------------------------------------ test chains
@dataclass
class Setup:
    """The same chain and loops as a TMM model and as a global reference model."""

    plant: ctmm.Chain
    chain: GlobalChain
    loops: list
    global_loops: list

    @property
    def system(self) -> ControlledChain:
        return ControlledChain(self.plant, self.loops)


def build(masses, stiffness, damping, ground, *, start: str, end: str, loops=()) -> Setup:
    """Chain ``start -[k0]- m0 -[k1]- m1 ... m(n-1) -[kn]- end`` in both descriptions.

    ``loops``: tuples ``(sensor, quantity, actuator, gain, delay, relative_to, across)``; with
    ``across`` the actuator force acts across connector ``k<actuator>`` (between masses
    ``actuator - 1`` and ``actuator``).
    """
    n = len(masses)
    stiffness, damping = np.array(stiffness, float), np.array(damping, float)
    if start == "free":
        stiffness[0] = damping[0] = 0.0
    if end == "free":
        stiffness[n] = damping[n] = 0.0
    elements = [Fixed("start") if start == "fixed" else Free("start")]
    if start == "fixed":
        elements.append(SpringDamper("k0", stiffness[0], damping[0]))
    for i in range(n):
        elements.append(Mass(f"m{i}", masses[i]))
        if ground[i] > 0:
            elements.append(GroundedSpring(f"g{i}", ground[i]))
        if i < n - 1 or end == "fixed":
            elements.append(SpringDamper(f"k{i + 1}", stiffness[i + 1], damping[i + 1]))
    elements.append(Fixed("end") if end == "fixed" else Free("end"))
    plant = ctmm.Chain("random", elements)
    chain = GlobalChain(masses, stiffness, damping, ground_stiffness=ground, start=start, end=end)
    fl, gl = [], []
    for number, (sensor, quantity, actuator, gain, delay, relative, across) in enumerate(loops):
        q = QUANTITY[quantity]
        sens = f"m{sensor}.{q}" if relative is None else [(f"m{sensor}.{q}", 1.0), (f"m{relative}.{q}", -1.0)]
        fl.append(Feedback(f"loop{number}", sens, f"k{actuator}" if across else f"m{actuator}", gain=gain,
                           delay=delay))
        gl.append(GlobalLoop(sensor, quantity, actuator, gain, delay, relative_to=relative,
                             reaction_mass=actuator - 1 if across else None))
    return Setup(plant, chain, fl, gl)


def random_setup(seed: int, *, delays: bool = True, accelerations: bool = True, n_loops: int | None = None) -> Setup:
    """A random damped chain (2-6 masses) with 1-3 loops: upstream, downstream, collocated,
    relative or across a connector; displacement, velocity or acceleration sensing."""
    rng = np.random.default_rng(seed)
    n = int(rng.integers(2, 7))
    masses = rng.uniform(0.5, 2.0, n)
    stiffness = rng.uniform(50.0, 200.0, n + 1)
    damping = rng.uniform(0.2, 1.0, n + 1)
    ground = np.where(rng.random(n) < 0.3, rng.uniform(10.0, 50.0, n), 0.0)
    start = "fixed" if rng.random() < 0.7 else "free"
    end = "fixed" if (start == "free" or rng.random() < 0.4) else "free"
    quantities = ["displacement", "velocity"] + (["acceleration"] if accelerations else [])
    loops = []
    for _ in range(n_loops or int(rng.integers(1, 4))):
        quantity = str(rng.choice(quantities))
        sensor = int(rng.integers(n))
        kind = rng.integers(4)
        actuator = sensor if kind == 0 else int(rng.integers(n))           # collocated or anywhere
        relative = None
        if kind == 1 and n > 1:
            relative = int((sensor + 1 + rng.integers(n - 1)) % n)
        across = bool(kind == 2 and actuator >= 1)
        scale = {"displacement": 50.0, "velocity": 1.0, "acceleration": 0.2}[quantity]
        gain = float(rng.uniform(-1.0, 1.0) * scale)
        delay = float(rng.choice([0.0, rng.uniform(0.001, 0.1)])) if delays else 0.0
        loops.append((sensor, quantity, actuator, gain, delay, relative, across))
    return build(masses, stiffness, damping, ground, start=start, end=end, loops=loops)


def relative_error(a, b) -> float:
    return float(np.max(np.abs(a - b)) / np.max(np.abs(b)))


OMEGA = np.linspace(0.3, 40.0, 157)


# ------------------------------------------------------------------------ closed-loop FRF
@settings(max_examples=40, deadline=None, derandomize=True)
@given(st.integers(0, 2**31 - 1))
def test_closed_loop_frf_equals_global_reference(seed):
    setup = random_setup(seed)
    n = setup.chain.size
    rng = np.random.default_rng(seed + 1)
    i_in, i_out = int(rng.integers(n)), int(rng.integers(n))
    quantity = str(rng.choice(["displacement", "velocity", "acceleration"]))
    frf = ctmm.frequency_response(setup.system, OMEGA, input=f"m{i_in}.force",
                                  output=f"m{i_out}.{QUANTITY[quantity]}")
    ref = closed_loop_frequency_response(setup.chain, setup.global_loops, OMEGA, i_in, i_out, quantity)
    assert relative_error(frf.response[0, 0], ref) < 1e-10


@pytest.mark.parametrize("placement", ["downstream", "upstream", "collocated", "across", "relative"])
def test_seed_chain_loop_placements_with_delay(placement):
    """Seed Fig. 9.27/9.30 chain (3 masses) with every placement of a delayed loop."""
    sensor, actuator, relative, across = {"downstream": (2, 0, None, False), "upstream": (0, 2, None, False),
                                          "collocated": (1, 1, None, False), "across": (2, 1, None, True),
                                          "relative": (2, 0, 1, False)}[placement]
    setup = build([1.0, 1.5, 2.0], [100.0, 80.0, 120.0, 0.0], [0.5, 0.3, 0.4, 0.0], [0.0] * 3,
                  start="fixed", end="free",
                  loops=[(sensor, "displacement", actuator, 5.0, 0.05, relative, across),
                         (1, "velocity", 2, 0.8, 0.0, None, False)])
    for i_in in range(3):
        frf = ctmm.frequency_response(setup.system, OMEGA, input=f"m{i_in}.force",
                                      output=["m0.x", "m1.x", "m2.x"])
        for i_out in range(3):
            ref = closed_loop_frequency_response(setup.chain, setup.global_loops, OMEGA, i_in, i_out)
            assert relative_error(frf.response[i_out, 0], ref) < 1e-12


def test_loop_signals_in_frequency_domain():
    """``loop.y`` is the sensed value and ``loop.u = -C e^{-s tau} (y - r)``."""
    setup = build([1.0, 1.5, 2.0], [100.0, 80.0, 120.0, 0.0], [0.5, 0.3, 0.4, 0.0], [0.0] * 3,
                  start="fixed", end="free", loops=[(2, "displacement", 0, 5.0, 0.05, None, False)])
    frf = ctmm.frequency_response(setup.system, OMEGA, input=["m1.force", "loop0.reference"],
                                  output=["m2.x", "loop0.y", "loop0.u"])
    np.testing.assert_allclose(frf("loop0.y", "m1.force"), frf("m2.x", "m1.force"), rtol=1e-13)
    k = 5.0 * np.exp(-1j * OMEGA * 0.05)
    np.testing.assert_allclose(frf("loop0.u", "m1.force"), -k * frf("m2.x", "m1.force"), rtol=1e-12)
    # reference: y = T r with T = K P /(1 + K P), P from the open plant
    P = ctmm.frequency_response(setup.plant, OMEGA, input="m0.force", output="m2.x")("m2.x")
    np.testing.assert_allclose(frf("loop0.y", "loop0.reference"), k * P / (1 + k * P), rtol=1e-11)
    np.testing.assert_allclose(frf("loop0.u", "loop0.reference"), k / (1 + k * P), rtol=1e-11)


# ------------------------------------------------------------------- characteristic roots
def newton(f, s0: complex, *, steps: int = 60) -> complex:
    s = complex(s0)
    for _ in range(steps):
        h = 1e-7 * max(1.0, abs(s))
        value = f(s)
        derivative = (f(s + h) - f(s - h)) / (2 * h)
        step = value / derivative
        s -= step
        if abs(step) < 1e-14 * max(1.0, abs(s)):
            break
    return s


@settings(max_examples=8, deadline=None, derandomize=True)
@given(st.integers(0, 2**31 - 1))
def test_delay_free_closed_loop_roots_are_zeros_of_characteristic_function(seed):
    setup = random_setup(seed, delays=False)
    roots = closed_loop_roots(setup.chain, setup.global_loops)
    system = setup.system

    def delta(s):
        return complex(ctmm.characteristic_function(system, [s])[0])

    scale = max(1.0, float(np.max(np.abs(roots))))
    for root in roots[np.imag(roots) >= 0]:
        found = newton(delta, root * (1 + 1e-4) + 1e-4j * scale)
        assert abs(found - root) < 1e-8 * scale, (root, found)


@settings(max_examples=15, deadline=None, derandomize=True)
@given(st.integers(0, 2**31 - 1))
def test_characteristic_function_proportional_to_global_determinant(seed):
    """With delays: Delta_TMM(s) / det D(s) is one constant over the complex plane."""
    setup = random_setup(seed)
    rng = np.random.default_rng(seed)
    s = rng.uniform(-3, 1, 12) + 1j * rng.uniform(-30, 30, 12)
    tmm = ctmm.characteristic_function(setup.system, s)
    ref = closed_loop_characteristic(setup.chain, setup.global_loops, s)
    ratio = tmm / ref
    np.testing.assert_allclose(ratio, ratio[0], rtol=1e-9)


# ------------------------------------------------------------------------ LTI controllers
def hand_reference(chain: GlobalChain, terms, omega, i_in: int, i_out: int) -> np.ndarray:
    """``(K - w^2 M + i w C + sum C_l(i w) e^{-i w tau} (i w)^p b c^T) X = e_in`` solved per w."""
    M, C, K = assemble(chain)
    out = np.empty(omega.size, dtype=complex)
    for k, w in enumerate(omega):
        s = 1j * w
        D = K - w * w * M + s * C + 0j
        for ctrl, delay, order, b, c in terms:
            D = D + complex(ctrl(s)) * np.exp(-s * delay) * s ** order * np.outer(b, c)
        rhs = np.zeros(chain.size, complex)
        rhs[i_in] = 1.0
        out[k] = np.linalg.solve(D, rhs)[i_out]
    return out


@pytest.mark.parametrize("controller", ["pid", "lead_lag"])
def test_lti_controllers_are_exact_in_frequency_domain(controller):
    s = control.tf("s")
    if controller == "pid":     # PID with filtered derivative
        C1 = 20.0 + 5.0 / s + 2.0 * s / (0.02 * s + 1)
    else:                       # lead-lag
        C1 = 8.0 * (s / 3.0 + 1) / (s / 30.0 + 1) * (s / 0.5 + 1) / (s / 0.05 + 1)
    C2 = 0.5 * (s / 10 + 1) / (s / 100 + 1)
    setup = build([1.0, 1.5, 2.0], [100.0, 80.0, 120.0, 0.0], [0.5, 0.3, 0.4, 0.0], [0.0] * 3,
                  start="fixed", end="free")
    loops = [Feedback("a", "m2.x", "m0", gain=C1, delay=0.03),
             Feedback("b", [("m1.v", 1.0), ("m0.v", -1.0)], "k1", gain=C2)]
    system = ControlledChain(setup.plant, loops)
    e = np.eye(3)
    terms = [(C1, 0.03, 0, e[0], e[2]), (C2, 0.0, 1, e[1] - e[0], e[1] - e[0])]
    for i_in in (0, 2):
        frf = ctmm.frequency_response(system, OMEGA, input=f"m{i_in}.force", output=["m0.x", "m2.x"])
        for j, i_out in enumerate((0, 2)):
            ref = hand_reference(setup.chain, terms, OMEGA, i_in, i_out)
            assert relative_error(frf.response[j, 0], ref) < 1e-11


# ----------------------------------------------------------------------------- errors
def seed_plant() -> ctmm.Chain:
    return build([1.0, 1.5, 2.0], [100.0, 80.0, 120.0, 0.0], [0.5, 0.3, 0.4, 0.0], [0.0] * 3,
                 start="fixed", end="free").plant


def test_unknown_sensor_lists_known_signals():
    with pytest.raises(UnknownNameError, match=r"loop 'l'.*unknown signal 'm9.x'.*available:.*m2\.x"):
        ControlledChain(seed_plant(), [Feedback("l", "m9.x", "m0", gain=1.0)])


def test_unknown_actuator_lists_known_ones():
    with pytest.raises(UnknownNameError, match=r"unknown actuator.*'m9'.*available: k0, k0.force, k1, k1.force, k2, k2.force, m0, m0.force, m1"):
        ControlledChain(seed_plant(), [Feedback("l", "m2.x", "m9", gain=1.0)])


@pytest.mark.parametrize("kwargs, message", [
    (dict(delay=-0.1), r"delay must be >= 0"),
    (dict(gain=float("nan")), r"gain must be finite"),
    (dict(gain=float("inf")), r"gain must be finite"),
    (dict(delay=float("inf")), r"delay must be finite"),
])
def test_invalid_loop_parameters(kwargs, message):
    params = dict(gain=1.0, delay=0.0) | kwargs
    with pytest.raises(ModelError, match=message):
        Feedback("l", "m2.x", "m0", **params)


def test_discrete_or_mimo_controllers_are_rejected():
    with pytest.raises(ModelError, match="discrete-time"):
        Feedback("l", "m2.x", "m0", gain=control.tf([1], [1, -0.5], 0.01))
    with pytest.raises(ModelError, match="SISO"):
        Feedback("l", "m2.x", "m0", gain=control.ss(np.eye(2) * -1, np.eye(2), np.eye(2), np.zeros((2, 2))))


def test_duplicate_loop_names_and_unknown_loop_signal():
    plant = seed_plant()
    with pytest.raises(ModelError, match="unique"):
        ControlledChain(plant, [Feedback("l", "m2.x", "m0", gain=1.0), Feedback("l", "m1.x", "m0", gain=1.0)])
    system = ControlledChain(plant, [Feedback("l", "m2.x", "m0", gain=1.0)])
    with pytest.raises(UnknownNameError, match=r"unknown signal 'l.q'.*l\.u.*l\.y"):
        ctmm.frequency_response(system, [1.0], input="m0.force", output="l.q")
