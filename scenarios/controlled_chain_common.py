"""Shared model of the controlled-chain scenarios (seed 001 §9.5-9.6, Figs. 9.26-9.46).

The seed's numbers were lost with its equations; these parameters are our choice (documented
in every scenario's JSON under ``"parameters"``).  Book numbering: lumped masses ``m2, m4, m6``,
spring-damper pairs ``K1,C1`` (ground to m2), ``K3,C3`` (m2 to m4), ``K5,C5`` (m4 to m6); the
chain is fixed at the ground and free after m6::

    ground -[K1,C1]- m2 -[K3,C3]- m4 -[K5,C5]- m6 -free

=====================  =======================  ===========================================
quantity               value                    note
=====================  =======================  ===========================================
m2, m4, m6             1.0 kg each
K1, K3, K5             10.0 N/m each            first natural frequency 1.41 rad/s
C1, C3, C5             1.0 N s/m each           C = K / 10: modal damping 7.0-28.5 %
Ka                     0 and 5.0 N/m            the seed's gain (Figs. 9.29, 9.39)
loop (Figs. 9.27-9.29) u = -Ka x6 on m2         non-collocated, sensor downstream
loop (Figs. 9.30-9.31) u = -Ka x6 across K3,C3  +u on m4, -u on m2
delay (Figs. 9.36, 9.46)  tau = 0.05 s          half the delay margin (0.108 s) of Ka = 5
excitation             F6 = 1 N sin(2 t) on m6  steady-state figures
=====================  =======================  ===========================================

Not a scenario itself (no ``NAME``): imported by the ``controlled_chain_*`` modules.
"""
from __future__ import annotations

import numpy as np

import ctmm
from ctmm.control import ControlledChain, Feedback
from ctmm.elements import Fixed, Free, Mass, SpringDamper
from ctmm.reference.chain import GlobalChain
from ctmm.reference.delay_chain import GlobalLoop
from ctmm.scenario import accuracy

MASS = 1.0
STIFFNESS = 10.0
DAMPING = 1.0
KA = 5.0
DELAY = 0.05
FORCE_AMPLITUDE = 1.0
FORCE_FREQUENCY = 2.0
MASSES = ("m2", "m4", "m6")
LABELS = {"m2": "x2,1 (m2)", "m4": "x4,3 (m4)", "m6": "x6,5 (m6)"}

PARAMETERS = {
    "masses_kg": {"m2": MASS, "m4": MASS, "m6": MASS},
    "stiffness_N_per_m": {"K1": STIFFNESS, "K3": STIFFNESS, "K5": STIFFNESS},
    "damping_Ns_per_m": {"C1": DAMPING, "C3": DAMPING, "C5": DAMPING},
    "boundaries": "fixed at the ground (before K1), free after m6",
    "Ka_N_per_m": [0.0, KA],
    "delay_s": DELAY,
    "excitation": f"F6 = {FORCE_AMPLITUDE} N * sin({FORCE_FREQUENCY} t) on m6",
    "source": "parameters chosen here; the seed's values were lost (seed 001 sec. 9.5-9.6)",
}


def plant() -> ctmm.Chain:
    """The uncontrolled seed chain (book numbering)."""
    return ctmm.Chain("seed_chain", [
        Fixed("ground"), SpringDamper("K1", STIFFNESS, DAMPING), Mass("m2", MASS),
        SpringDamper("K3", STIFFNESS, DAMPING), Mass("m4", MASS),
        SpringDamper("K5", STIFFNESS, DAMPING), Mass("m6", MASS), Free("tip")])


def global_chain() -> GlobalChain:
    """The same chain for the global references (masses 0, 1, 2 = m2, m4, m6)."""
    return GlobalChain([MASS] * 3, [STIFFNESS] * 3 + [0.0], [DAMPING] * 3 + [0.0], start="fixed", end="free")


def controlled(placement: str, gain: float, delay: float = 0.0) -> tuple[ControlledChain, list]:
    """TMM system and global loops for ``placement`` in {"m2", "K3"} (actuator of the m6 loop)."""
    if placement == "m2":
        loop = Feedback("control", "m6.x", "m2", gain=gain, delay=delay)
        ref = GlobalLoop(2, "displacement", 0, gain, delay)
    elif placement == "K3":
        loop = Feedback("control", "m6.x", "K3", gain=gain, delay=delay)
        ref = GlobalLoop(2, "displacement", 1, gain, delay, reaction_mass=0)
    else:
        raise ValueError(f"placement must be 'm2' or 'K3', got {placement!r}")
    return ControlledChain(plant(), [loop]), [ref]


def harmonic_force(t: float) -> np.ndarray:
    """Global force vector [N] of the excitation on m6."""
    return np.array([0.0, 0.0, FORCE_AMPLITUDE * np.sin(FORCE_FREQUENCY * t)])


def steady_state_history(phasors: np.ndarray, omega: float):
    """``theta -> (x, v, a)`` of the harmonic steady state ``x = Im(X e^{i w t})``."""
    def history(theta: float):
        e = np.exp(1j * omega * theta)
        return (np.imag(phasors * e), np.imag(1j * omega * phasors * e), np.imag(-omega ** 2 * phasors * e))
    return history


def style_axes(axes, ylabel_unit: str = "m") -> None:
    for ax, name in zip(axes, MASSES):
        ax.set_ylabel(f"{LABELS[name]} [{ylabel_unit}]")
        ax.grid(True, alpha=0.3)
        ax.legend(fontsize=7, loc="upper right")


def frf_comparison(placement: str, gain: float, delay: float, omega: np.ndarray) -> dict:
    """TMM closed-loop FRFs (force on m6 -> x2, x4, x6) and the dense global reference.

    Returns ``{"tmm": (3, n_omega), "reference": (3, n_omega), "error": relative error,
    "tmm_time": s, "reference_time": s, "response": the TMM FrequencyResponse}``.
    """
    import time

    from ctmm.reference.delay_chain import closed_loop_frequency_response

    system, loops = controlled(placement, gain, delay)
    start = time.perf_counter()
    response = ctmm.frequency_response(system, omega, input="m6.force", output=[f"{m}.x" for m in MASSES])
    tmm = response.response[:, 0]
    tmm_time = time.perf_counter() - start
    chain = global_chain()
    start = time.perf_counter()
    ref = np.array([closed_loop_frequency_response(chain, loops, omega, 2, i) for i in range(3)])
    ref_time = time.perf_counter() - start
    return {"tmm": tmm, "reference": ref, "tmm_time": tmm_time, "reference_time": ref_time,
            "error": float(np.max(np.abs(tmm - ref)) / np.max(np.abs(ref))), "response": response}


def steady_state_comparison(placement: str, gain: float, delay: float, t: np.ndarray) -> dict:
    """Steady state under the harmonic force on m6: TMM phasors against the global closed-loop
    delay equations integrated by the method of steps from the steady-state orbit (history
    ``theta < 0`` on the orbit too), which must stay on it.

    Returns ``{"tmm": (nt, 3), "reference": (nt, 3), "error": max abs [m], "tmm_time",
    "reference_time", "phasors"}``.
    """
    import time

    from ctmm.reference.delay_chain import closed_loop_frequency_response, method_of_steps

    system, loops = controlled(placement, gain, delay)
    w = FORCE_FREQUENCY
    start = time.perf_counter()
    phasors = FORCE_AMPLITUDE * ctmm.frequency_response(
        system, [w], input="m6.force", output=[f"{m}.x" for m in MASSES]).response[:, 0, 0]
    tmm = np.imag(phasors[None, :] * np.exp(1j * w * t)[:, None])
    tmm_time = time.perf_counter() - start
    chain = global_chain()
    start = time.perf_counter()
    ref_phasors = FORCE_AMPLITUDE * np.array(
        [closed_loop_frequency_response(chain, loops, [w], 2, i)[0] for i in range(3)])
    orbit = steady_state_history(ref_phasors, w)
    x0, v0, _ = orbit(0.0)
    solution = method_of_steps(chain, loops, float(t[-1]), x0, v0, history=orbit, force_fn=harmonic_force,
                               rtol=1e-11, atol=1e-13)
    ref = solution.evaluate(t).displacement
    ref_time = time.perf_counter() - start
    return {"tmm": tmm, "reference": ref, "phasors": phasors, "tmm_time": tmm_time, "reference_time": ref_time,
            "error": float(np.max(np.abs(tmm - ref)))}


def compare_placement(placement: str, quick: bool) -> dict:
    """FRFs and steady-state motion for Ka = 0 and KA with the actuator at ``placement``, each
    against the global closed-loop solve, plus the loop margins; used by the Fig. 9.27-9.31 scenarios."""
    from ctmm.control import margins

    omega = np.linspace(0.02, 6.0, 600 if quick else 3000)
    t = np.linspace(0.0, 10.0, 201 if quick else 1001)
    gains = (0.0, KA)
    frf = {g: frf_comparison(placement, g, 0.0, omega) for g in gains}
    steady = {g: steady_state_comparison(placement, g, 0.0, t) for g in gains}
    system, _ = controlled(placement, KA)
    return {"omega": omega, "t": t, "frf": frf, "steady": steady,
            "tmm_time": sum(r["tmm_time"] for r in (*frf.values(), *steady.values())),
            "reference_time": sum(r["reference_time"] for r in (*frf.values(), *steady.values())),
            "margins": margins(system, "control", np.linspace(0.02, 20.0, 2000 if quick else 8000))}


def plot_magnitude(ax, result: dict, mass: str, label: str, style: str = "-", markers: int = 50,
                   reference_label: str | None = None):
    """Bode magnitude [dB re 1 m/N] of ``mass`` in one :func:`frf_comparison` result, drawn by
    :meth:`ctmm.results.FrequencyResponse.plot` (the one Bode drawing: its axis labels and units),
    with the global closed-loop solve as ``x`` markers (about ``markers`` of them, legend entry
    ``reference_label``) in the same colour.

    Returns the TMM curve (a matplotlib ``Line2D``)."""
    result["response"].plot([ax], output=f"{mass}.x", input="m6.force", phase=False, label=label)
    line = ax.get_lines()[-1]
    line.set_linestyle(style)
    omega, k = result["response"].omega, MASSES.index(mass)
    step = max(1, omega.size // markers)
    ax.semilogx(omega[::step], 20 * np.log10(np.abs(result["reference"][k, ::step])), "x", ms=4,
                color=line.get_color(), label=reference_label)
    ax.legend(fontsize=7)
    return line


def plot_frf_pair(ax_pair, results: dict, title: str) -> None:
    """Bode magnitudes of X2, X4, X6 for the two gains in ``results`` ({gain: frf_comparison})."""
    styles = ("-", "--", "-.")
    for ax, (gain, res) in zip(ax_pair, results.items()):
        for k, name in enumerate(MASSES):
            plot_magnitude(ax, res, name, f"{LABELS[name]} TMM", styles[k],
                           reference_label="global closed-loop solve" if k == 0 else None)
        ax.set_title(f"{title}, Ka = {gain:g} N/m, force on m6")


def frf_and_steady_accuracy(frf_error: float, frf_cases: str, steady_error: float, steady_reference: str) -> list:
    """The two accuracy figures of the chain scenarios: relative FRF error [-] and steady-state error [m].

    Bounds: 1e-10 for the FRF (docs/control.md, closed-loop FRF against dense solves) and 1e-8 m for
    the steady state (1000 x the reference integrator's tolerance rtol 1e-11 on amplitudes <= 1 m).
    """
    return [
        accuracy("FRF error vs global model", frf_error, "relative", 1e-10,
                 f"max_w |H_TMM - H_ref| / max_w |H_ref| of X2, X4, X6 {frf_cases}",
                 source="docs/control.md: closed-loop FRF vs dense solve < 1e-10"),
        accuracy("steady-state error vs global model", steady_error, "m", 1e-8,
                 f"max_t |x_TMM - x_ref| of m2, m4, m6 against {steady_reference}, started on the orbit",
                 source="1000 x the reference integrator's tolerance (rtol 1e-11) on amplitudes <= 1 m")]
