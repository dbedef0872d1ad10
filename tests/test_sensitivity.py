"""Exact sensitivities (ctmm.sensitivity) against Richardson-extrapolated central differences of the
library's own verbs on rebuilt systems (TMM frequency responses, margins, characteristic roots) and
against a closed form (sign and scale)."""
from __future__ import annotations

import numpy as np
import pytest

import ctmm
from ctmm import sensitivity as S
from ctmm.control import ControlledChain, Feedback, margins
from ctmm.elements import Fixed, Free, Inerter, Mass, Spring, SpringDamper
from ctmm.errors import ModelError

NAMES = ["m4.mass", "K3.stiffness", "K1.damping", "pd.m6.x", "pd.m6.v", "pd.delay"]


def seed_chain() -> ctmm.Chain:
    return ctmm.Chain("seed", [Fixed("g"), SpringDamper("K1", 10.0, 1.0), Mass("m2", 1.0),
                               SpringDamper("K3", 10.0, 1.0), Mass("m4", 1.0),
                               SpringDamper("K5", 10.0, 1.0), Mass("m6", 1.0), Free("e")])


def pd_system(delay: float = 0.05) -> ControlledChain:
    return ControlledChain(seed_chain(), [Feedback("pd", [("m6.x", 5.0), ("m6.v", 1.0)], "m2", gain=1.0,
                                                   delay=delay)])


def richardson(f, system, name: str) -> np.ndarray:
    """Central difference extrapolated over h, h/2 (error O(h^4)) of f(system with name = v + h)."""
    v = S.parameter_values(system, [name])[name]
    h = 1e-3 * max(1.0, abs(v))

    def central(step):
        up = np.asarray(f(S.with_parameters(system, {name: v + step})))
        down = np.asarray(f(S.with_parameters(system, {name: v - step})))
        return (up - down) / (2 * step)

    return (4 * central(h / 2) - central(h)) / 3


def central_difference(f, system, name: str, step: float = 1e-4) -> np.ndarray:
    """One central difference, ``h = step |value|``: half the runs of :func:`richardson` for references that are
    expensive (simulations, root searches); truncation ``O(h^2)`` (~1e-8 relative at the default step) and
    round-off ~1e-16 / step relative (each use states its measured error against its bound)."""
    v = S.parameter_values(system, [name])[name]
    h = step * abs(v)
    return (np.asarray(f(S.with_parameters(system, {name: v + h})))
            - np.asarray(f(S.with_parameters(system, {name: v - h})))) / (2 * h)


def relative(a, b) -> float:
    a, b = np.asarray(a), np.asarray(b)
    return float(np.max(np.abs(a - b)) / max(np.max(np.abs(b)), 1e-300))


def test_frequency_response_derivatives_match_differences_of_the_tmm():
    system = pd_system()
    omega = np.array([0.3, 1.4, 2.2, 3.9])
    found = S.frequency_response_sensitivity(system, NAMES, omega, input="m6.force", output="m4.v")
    direct = ctmm.frequency_response(system, omega, input="m6.force", output="m4.v")("m4.v")
    assert relative(found.response, direct) < 1e-12

    def H(s):
        return ctmm.frequency_response(s, omega, input="m6.force", output="m4.v")("m4.v")

    for i, name in enumerate(NAMES):
        fd = richardson(H, system, name)
        assert relative(found.derivative[i], fd) < 1e-6, name
        fd_magnitude = richardson(lambda s: np.abs(H(s)), system, name)
        assert relative(found.magnitude_derivative[i], fd_magnitude) < 1e-6, name
        fd_phase = richardson(lambda s: np.unwrap(np.angle(H(s))), system, name)
        assert relative(found.phase_derivative[i], fd_phase) < 1e-6, name


def test_lti_controller_factor_and_acceleration_sensor():
    import control

    plant = seed_chain()
    system = ControlledChain(plant, [Feedback("lead", [("m6.x", 1.0), ("m6.a", 0.05)], "K3",
                                              gain=control.tf([2.0, 4.0], [0.1, 1.0]), delay=0.02)])
    omega = np.array([0.7, 2.5])
    names = ["lead.gain", "lead.m6.a", "m6.mass"]
    found = S.frequency_response_sensitivity(system, names, omega, input="m2.force", output="m6.x")

    def H(s):
        return ctmm.frequency_response(s, omega, input="m2.force", output="m6.x")("m6.x")

    assert relative(found.response, H(system)) < 1e-12
    for i, name in enumerate(names):
        assert relative(found.derivative[i], richardson(H, system, name)) < 1e-6, name


def test_sign_and_scale_against_the_closed_form():
    """SDOF H = 1/(k - m w^2 + i c w): dH/dk = -H^2, dH/dm = w^2 H^2, dH/dc = -i w H^2."""
    k, m, c = 100.0, 2.0, 0.7
    chain = ctmm.Chain("sdof", [Fixed("wall"), SpringDamper("k", k, c), Mass("m", m), Free("end")])
    omega = np.array([3.0, 7.0, 11.0])
    found = S.frequency_response_sensitivity(chain, ["k.stiffness", "m.mass", "k.damping"], omega,
                                             input="m.force", output="m.x")
    H = 1.0 / (k - m * omega ** 2 + 1j * c * omega)
    assert relative(found.response, H) < 1e-14
    assert relative(found.derivative[0], -H ** 2) < 1e-13
    assert relative(found.derivative[1], omega ** 2 * H ** 2) < 1e-13
    assert relative(found.derivative[2], -1j * omega * H ** 2) < 1e-13


def test_loop_transfer_over_a_grid_is_the_tmm_loop_transfer_function():
    """The characteristic matrix's ``L_l(i w)`` over a frequency grid (one batched evaluation of the loop gains
    and sensor rows) against the TMM's ``loop_transfer_function`` (the chain's transfer matrices), for both
    loops of a two-loop chain with a dynamic (lead) controller, delays and an acceleration sensor: the other
    loop closed in each (measured 2e-15)."""
    import control

    from ctmm.control import loop_transfer_function
    from ctmm.sensitivity_model import LoopCharacteristicMatrix

    system = ControlledChain(seed_chain(), [
        Feedback("pd", [("m6.x", 5.0), ("m6.v", 1.0)], "m2", gain=control.tf([1.0, 2.0], [0.1, 1.0]), delay=0.05),
        Feedback("inner", [("m4.x", 2.0), ("m2.a", 0.01)], "m4", gain=0.5, delay=0.02)])
    omega = np.linspace(0.05, 30.0, 200)
    model = LoopCharacteristicMatrix(system)
    for i, name in enumerate(("pd", "inner")):
        assert relative(model.loop_transfer(i, 1j * omega),
                        loop_transfer_function(system, name, omega).response[0, 0]) < 1e-13, name


def test_margin_derivatives_match_differences_of_margins():
    system = pd_system()
    omega = np.linspace(0.01, 30.0, 800)
    fields = ("gain_margin", "phase_margin", "delay_margin", "stability_margin")
    names = ["m4.mass", "K1.damping", "pd.m6.x", "pd.delay"]
    found = S.margin_sensitivity(system, "pd", names, omega)
    def every_margin(s):                       # one margins() per system feeds all four fields
        result = margins(s, "pd", omega)
        return [getattr(result, f) for f in fields]

    for name in names:
        fd = richardson(every_margin, system, name)
        for field, difference in zip(fields, fd):
            assert relative(getattr(found, field)[name], difference) < 1e-6, (field, name)


def test_spectral_abscissa_delay_free_against_eigenvalues_of_the_state_space():
    system = pd_system(delay=0.0)
    names = ["pd.m6.x", "pd.m6.v", "m2.mass", "K5.damping"]
    found = S.spectral_abscissa_sensitivity(system, names)
    assert found.method == "quadratic eigenvalues" and found.differentiable

    def abscissa(s):
        return np.max(np.linalg.eigvals(ctmm.interop.to_state_space(s).A).real)

    assert abs(found.value - abscissa(system)) < 1e-12
    for name in names:
        assert relative(found.gradient[name], richardson(abscissa, system, name)) < 1e-6, name


def test_spectral_abscissa_with_delay_against_characteristic_roots():
    system = pd_system(delay=0.05)
    names = ["pd.delay", "pd.m6.v", "m4.mass"]
    found = S.spectral_abscissa_sensitivity(system, names, re_min=-1.0, im_max=30.0)
    assert found.method == "characteristic roots"

    def abscissa(s):
        return ctmm.stability.spectral_abscissa(s, re_min=-1.0, im_max=30.0).value

    for name in names:
        assert relative(found.gradient[name], richardson(abscissa, system, name)) < 1e-6, name


def test_peak_derivative_matches_differences():
    system = pd_system(delay=0.0)
    omega = np.linspace(0.05, 6.0, 600)
    found = S.peak_sensitivity(system, ["pd.m6.v", "K3.stiffness"], omega, input="m6.force", output="m6.x")
    for name in ("pd.m6.v", "K3.stiffness"):
        fd = richardson(lambda s: S.peak_sensitivity(s, [], omega, input="m6.force", output="m6.x").value,
                        system, name)
        assert relative(found.gradient[name], fd) < 1e-6, name


def test_refusals_name_what_is_not_differentiable():
    system = pd_system()
    omega = [1.0]
    with pytest.raises(ModelError, match="K3.*mass.*damping, stiffness"):
        S.frequency_response_sensitivity(system, ["K3.mass"], omega, input="m6.force", output="m6.x")
    with pytest.raises(ModelError, match="nothing"):
        S.frequency_response_sensitivity(system, ["nothing.mass"], omega, input="m6.force", output="m6.x")
    with pytest.raises(ModelError, match="K3.f"):
        S.frequency_response_sensitivity(system, ["m2.mass"], omega, input="m6.force", output="K3.f")
    with pytest.raises(ModelError, match="kp.*delay, gain"):
        S.frequency_response_sensitivity(system, ["pd.kp"], omega, input="m6.force", output="m6.x")
    with pytest.raises(ModelError, match="K3.*mass.*damping, stiffness"):          # in time too
        S.simulation_sensitivity(system, ["K3.mass"], t_final=1.0, dt=0.01)
    with pytest.raises(ModelError, match="re_min"):
        S.spectral_abscissa_sensitivity(system, ["m2.mass"])
    with pytest.raises(ModelError, match="mass must be > 0"):
        S.with_parameters(system, {"m2.mass": 0.0})
    chain = ctmm.Chain("s", [Fixed("w"), Spring("k", 1.0), Mass("m", 1.0), Free("e")])
    with pytest.raises(ModelError, match="loop"):
        S.margin_sensitivity(chain, "pd", ["m.mass"], [1.0])


def test_spectral_abscissa_with_a_massless_point():
    """A massless point between a spring-damper and a spring: the pencil has infinite eigenvalues,
    which must not be taken for roots."""
    chain = ctmm.Chain("c", [Fixed("w"), SpringDamper("k1", 10.0, 0.3), Spring("k2", 5.0), Mass("m", 1.0),
                             Free("e")])
    names = ["k1.damping", "k2.stiffness", "m.mass"]
    found = S.spectral_abscissa_sensitivity(chain, names)

    def abscissa(s):
        return np.max(np.linalg.eigvals(ctmm.interop.to_state_space(s).A).real)

    assert abs(found.value - abscissa(chain)) < 1e-12
    for name in names:
        assert relative(found.gradient[name], richardson(abscissa, chain, name)) < 1e-6, name


def test_inerter_numbers_against_the_closed_form():
    """A mass held by an inerter in parallel with a spring-damper, ``H = 1/((m + b) s^2 + c s + k)``:
    ``dH/db = -s^2 H^2``, ``dH/dk = -H^2``, ``dH/dc = -s H^2`` and the root's ``ds/db = -s^2/(2 (m + b) s + c)``
    (the inerter's numbers were refused, the message listing the very numbers it refused)."""
    b, k, c, m = 0.4, 50.0, 0.3, 1.2
    chain = ctmm.Chain("i", [Fixed("w"), Inerter("in", b, stiffness=k, damping=c), Mass("m", m), Free("e")])
    omega = np.array([2.0, 6.0, 13.0])
    s = 1j * omega
    names = ["in.inertance", "in.stiffness", "in.damping"]
    found = S.frequency_response_sensitivity(chain, names, omega, input="m.force", output="m.x")
    H = 1.0 / ((m + b) * s ** 2 + c * s + k)
    assert relative(found.response, H) < 1e-14
    for i, expected in enumerate((-s ** 2 * H ** 2, -H ** 2, -s * H ** 2)):
        assert relative(found.derivative[i], expected) < 1e-13, names[i]
    root = (-c + np.sqrt(complex(c * c - 4 * (m + b) * k))) / (2 * (m + b))
    abscissa = S.spectral_abscissa_sensitivity(chain, ["in.inertance"])
    assert abs(abscissa.root - root) < 1e-12 * abs(root)
    assert abs(abscissa.root_gradient["in.inertance"] - (-root ** 2 / (2 * (m + b) * root + c))) < 1e-12
    assert S.parameter_values(chain, names) == {"in.inertance": b, "in.stiffness": k, "in.damping": c}
    pure = S.with_parameters(chain, {"in.inertance": 0.9, "in.stiffness": 0.0, "in.damping": 0.0})
    assert (pure.elements[1].inertance, pure.elements[1].stiffness, pure.elements[1].damping) == (0.9, 0.0, 0.0)
    with pytest.raises(ModelError, match="inertance must be > 0"):
        S.with_parameters(chain, {"in.inertance": 0.0})
    with pytest.raises(ModelError, match="in.*mass.*damping, inertance, stiffness"):
        S.frequency_response_sensitivity(chain, ["in.mass"], omega, input="m.force", output="m.x")
