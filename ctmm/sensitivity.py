"""``ctmm.sensitivity``: exact derivatives of frequency responses, margins and the spectral abscissa.

Derivatives with respect to **named parameters** of a lumped 1-D chain closed by embedded loops
(:class:`~ctmm.control.loops.ControlledChain`) -- and of planar and spatial models, controlled or not,
through the same ``Delta(s) = s I - A + sum K_l b_l c_l^T`` of their linearisation, with ``A``, ``B``,
the sensor rows and the equilibrium differentiated by casadi (:mod:`ctmm.sensitivity_planar`: parameters
``"<body>.mass"``, ``"<body>.inertia"``, ``"<hinge>.stiffness"``, ``"<hinge>.damping"``;
:mod:`ctmm.sensitivity_spatial`: ``"<body>.inertia.xx"``, ``"<joint>.reference"``, ``"gravity.z"``, ...)
-- for chains: element numbers (``"m3.mass"``,
``"K1.stiffness"``, ``"C1.damping"``) and loop parameters (``"<loop>.gain"``, ``"<loop>.delay"``,
``"<loop>.<sensed signal>"`` -- the weight of a sensor term, e.g. ``kp``, ``kd`` of a PD loop
``[("m6.x", kp), ("m6.v", kd)]``).  Everything is built from the closed-loop characteristic
matrix ``Delta(s)`` and its exact derivative matrices (:mod:`ctmm.sensitivity_model`):

* **frequency responses** ``H = c^T Delta^{-1} b``: ``dH/dp = -c^T Delta^{-1} (dDelta/dp)
  Delta^{-1} b``; magnitude ``d|H|/dp = Re(conj(H) dH/dp)/|H|``, phase ``Im(dH/dp / H)``;
* **peaks** ``max_w |H|`` and ``min_w |1 + L|``: the derivative at the (refined) extremum
  (envelope theorem; exact at a stationary point);
* **margins** of a loop ``L_l = K_l c_l^T Delta_{-l}^{-1} b_l`` (the other loops closed): the
  crossover frequencies move by the implicit function theorem (``dw/dp = -Re(l_p)/Re(l_w)`` at a
  gain crossover, ``-Im(l_p)/Im(l_w)`` at a phase crossover, ``l = log L``), then
  ``dPM/dp = Im(l_p) + Im(l_w) dw/dp``, ``dGM/dp = -GM (Re(l_p) + Re(l_w) dw/dp)`` and
  ``dDM/dp = (dPM/dp)/w - PM dw/dp / w^2``;
* **the spectral abscissa** (rightmost root, delays included): ``ds/dp = -w^H (dDelta/dp) v /
  w^H (dDelta/ds) v`` with ``v, w`` the right and left null vectors of ``Delta(s*)``.

The values (crossovers, roots) come from the library's verbs on the TMM (:func:`ctmm.control.margins`,
:func:`ctmm.stability.spectral_abscissa`) or, delay-free with static gains, from the quadratic
eigenvalue problem of ``Delta``; each is checked against ``Delta`` before it is differentiated (a
mismatch is refused).  What cannot be differentiated is refused by name: non-lumped elements,
connector forces as signals, finite-element subsystems of spatial models; time-domain outputs
(:func:`simulation_sensitivity`) are differentiated for planar and spatial models (modal spatial beams included),
loops included, in plant and loop numbers (:mod:`ctmm.sensitivity_time`, :mod:`ctmm.sensitivity_time_spatial`,
:mod:`ctmm.sensitivity_loop_numbers`), for free lumped chains and for controlled chains in their element and loop
numbers (:mod:`ctmm.sensitivity_time_chain`).
Accuracy and limits: ``docs/sensitivity.md``.
"""
from __future__ import annotations

import copy
import math
from dataclasses import dataclass, field
from typing import Any, Mapping, Sequence

import numpy as np

from . import validation
from .control.loops import ControlledChain
from .errors import ModelError, unknown_name
from .sensitivity_model import LoopCharacteristicMatrix
from .system import Chain

__all__ = ["FrequencySensitivity", "PeakSensitivity", "MarginSensitivity", "AbscissaSensitivity",
           "parameter_values", "with_parameters", "frequency_response_sensitivity", "peak_sensitivity",
           "stability_margin_sensitivity", "margin_sensitivity", "spectral_abscissa_sensitivity",
           "simulation_sensitivity"]

_MISMATCH = 1e-7     # largest relative disagreement between a library value and Delta before refusing


# -------------------------------------------------------------------------------- parameters
def characteristic_matrix(system: Any, names: Sequence[str]) -> LoopCharacteristicMatrix:
    """``Delta(s)`` of ``system`` with its derivatives: a chain's (:mod:`ctmm.sensitivity_model`) or a
    planar model's (:mod:`ctmm.sensitivity_planar`, linearised about its static equilibrium)."""
    from .sensitivity_planar import PlanarCharacteristicMatrix, is_planar_system
    from .sensitivity_spatial import SpatialCharacteristicMatrix, is_spatial_system

    if is_planar_system(system):
        return PlanarCharacteristicMatrix(system, names)
    if is_spatial_system(system):
        return SpatialCharacteristicMatrix(system, names)
    return LoopCharacteristicMatrix(system, names)


def _names(parameters: Any, *, allow_empty: bool = True) -> tuple[str, ...]:
    names = validation.names("parameters", parameters, allow_empty=allow_empty)
    if len(set(names)) != len(names):
        raise ModelError(f"parameters must not repeat a name, got {list(names)}")
    return tuple(names)


def _single(kind: str, value: Any) -> str:
    if not isinstance(value, str) or not value:
        raise ModelError(f"{kind} must be one signal name (str), got {value!r}")
    return value


def parameter_values(system: Any, parameters: str | Sequence[str]) -> dict[str, float]:
    """Current values of named parameters (module docstring for the names).

    ``"<loop>.gain"`` of a loop with an LTI controller is a factor on that controller (value 1).
    """
    from .sensitivity_planar import is_planar_system, planar_parameter_values
    from .sensitivity_spatial import is_spatial_system, spatial_parameter_values

    if is_planar_system(system):
        return planar_parameter_values(system, _names(parameters, allow_empty=False))
    if is_spatial_system(system):
        return spatial_parameter_values(system, _names(parameters, allow_empty=False))
    model = characteristic_matrix(system, _names(parameters, allow_empty=False))
    return {p.name: p.value for p in model.parameters}


def with_parameters(system: Any, values: Mapping[str, float]) -> Any:
    """A copy of ``system`` with named parameters set (elements rebuilt, loops replaced).

    Parameters
    ----------
    system : Chain, ControlledChain, PlanarModel, SpatialModel or ControlledModel
    values : mapping
        ``{parameter name: value}``; ``"<loop>.gain"`` of an LTI controller is a factor on it.

    Raises
    ------
    ModelError
        Unknown names, values out of the element's range (mass > 0, stiffness and damping >= 0,
        a connector with both zero), a negative delay.
    """
    from .stability import with_loop_parameters

    from .sensitivity_planar import is_planar_system, planar_with_parameters
    from .sensitivity_spatial import is_spatial_system, spatial_with_parameters

    if not isinstance(values, Mapping):
        raise ModelError(f"values must be a mapping {{parameter name: value}}, got {values!r}")
    if is_planar_system(system):
        return planar_with_parameters(system, {name: values[name] for name in _names(list(values))})
    if is_spatial_system(system):
        return spatial_with_parameters(system, {name: values[name] for name in _names(list(values))})
    model = characteristic_matrix(system, _names(list(values)))
    chain = model.chain
    elements = list(chain.elements)
    per_loop: dict[str, dict] = {}
    for p in model.parameters:
        value = validation.finite(f"parameter {p.name!r}", values[p.name])
        head, _, tail = p.name.partition(".")
        if p.loop >= 0:
            per_loop.setdefault(head, {})[{"weight": tail}.get(p.kind, p.kind)] = value
            continue
        j = chain.position(head)
        element = copy.copy(elements[j])
        positive = (tail == "mass" and type(element).__name__ == "Mass") or tail == "inertance"
        if value < 0.0 or (positive and value == 0.0):
            raise ModelError(f"parameter {p.name!r} = {value!r}: a {tail} must be {'> 0' if positive else '>= 0'}")
        element.__dict__[tail] = value
        lumped = getattr(element, "stiffness", 0.0), getattr(element, "damping", 0.0)
        if not element.is_point and type(element).__name__ != "Inerter" and lumped == (0.0, 0.0):
            raise ModelError(f"parameter {p.name!r} = {value!r}: connector {head!r} needs stiffness > 0 or "
                             "damping > 0")
        element.derive_forms()
        elements[j] = element
    plant = Chain(chain.name, elements) if any(p.loop < 0 for p in model.parameters) else chain
    if isinstance(system, Chain):
        return plant
    out = ControlledChain(plant, system.loops)
    for loop, changes in per_loop.items():
        out = with_loop_parameters(out, loop, changes)
    return out


# ---------------------------------------------------------------------------- result types
@dataclass(frozen=True)
class FrequencySensitivity:
    """A SISO frequency response and its derivatives.

    Attributes
    ----------
    omega : ndarray, shape (n_omega,)
        [rad/s].
    parameters : tuple of str
    response : ndarray of complex, shape (n_omega,)
        ``H(i w)`` [output unit per input unit].
    derivative : ndarray of complex, shape (n_parameters, n_omega)
        ``dH/dp`` [H unit per parameter unit].
    magnitude, magnitude_derivative : ndarray
        ``|H|`` and ``d|H|/dp`` (same shapes as above, real).
    phase, phase_derivative : ndarray
        ``arg H`` [rad] (unwrapped along omega) and ``d arg H / dp`` [rad per parameter unit].
    """

    omega: np.ndarray
    parameters: tuple[str, ...]
    response: np.ndarray
    derivative: np.ndarray
    magnitude: np.ndarray
    magnitude_derivative: np.ndarray
    phase: np.ndarray
    phase_derivative: np.ndarray


@dataclass(frozen=True)
class PeakSensitivity:
    """An extremum over frequency and its gradient (envelope theorem).

    Attributes
    ----------
    value : float
        The extremum (``max |H|`` or ``min |1 + L|``).
    frequency : float
        Where it is attained [rad/s] (refined between grid points).
    gradient : dict
        ``{parameter: d value / d parameter}``.
    """

    value: float
    frequency: float
    gradient: dict


@dataclass(frozen=True)
class MarginSensitivity:
    """Margins of one loop (as :func:`ctmm.control.margins`) and their gradients.

    Attributes
    ----------
    margins : Margins
        The values, from :func:`ctmm.control.margins` (TMM).
    gain_margin, phase_margin, delay_margin, stability_margin : dict
        ``{parameter: derivative}`` of ``GM`` [-], ``PM`` [deg], ``DM`` [s] and ``min |1 + L|`` [-]
        (empty when the margin is infinite: no crossover).
    crossover_frequency : dict
        ``{"gain" | "phase" | "delay": {parameter: dw/dp}}`` [rad/s per parameter unit].
    """

    margins: Any
    gain_margin: dict
    phase_margin: dict
    delay_margin: dict
    stability_margin: dict
    crossover_frequency: dict = field(default_factory=dict)


@dataclass(frozen=True)
class AbscissaSensitivity:
    """The spectral abscissa (largest real part of the closed-loop roots) and its gradient.

    Attributes
    ----------
    value : float
        ``Re s*`` [1/s] of the rightmost root ``s*``.
    root : complex
        ``s*`` (``Im >= 0`` of a conjugate pair).
    gradient : dict
        ``{parameter: d Re s* / dp}``.
    root_gradient : dict
        ``{parameter: d s* / dp}`` (complex).
    tied_roots : tuple of complex
        Other roots (not ``s*`` or its conjugate) within ``1e-9 (1 + |s*|)`` of ``Re s*``: the
        abscissa has a kink there and ``gradient`` is one of its one-sided slopes.
    method : str
        ``"quadratic eigenvalues"`` (delay-free, static gains) or ``"characteristic roots"``.
    """

    value: float
    root: complex
    gradient: dict
    root_gradient: dict
    tied_roots: tuple = ()
    method: str = ""

    @property
    def differentiable(self) -> bool:
        """False at a tie of distinct rightmost roots (a kink of the abscissa)."""
        return not self.tied_roots


# ------------------------------------------------------------------------- frequency domain
def frequency_response_sensitivity(system: Any, parameters: str | Sequence[str], omega: Any, *,
                                   input: str, output: str) -> FrequencySensitivity:
    """Closed-loop ``H(i w)`` from ``input`` to ``output`` and its exact parameter derivatives.

    Parameters
    ----------
    system : Chain, ControlledChain, PlanarModel, SpatialModel or ControlledModel
        Lumped chain, planar or spatial model (module docstring).
    parameters : str or sequence of str
        Parameter names.
    omega : array_like
        Angular frequencies [rad/s].
    input : str
        Chains: ``"<element>.force"``; planar and spatial models: an actuator port.
    output : str
        Chains: ``"<point>.x"``, ``".v"`` or ``".a"``; planar and spatial models: a sensor port or coordinate.

    Returns
    -------
    FrequencySensitivity
    """
    model = characteristic_matrix(system, _names(parameters))
    return _response(model, validation.frequencies("omega", omega), _single("input", input),
                     _single("output", output), len(model.parameters))


def _response(model: LoopCharacteristicMatrix, w: np.ndarray, input: str, output: str,
              count: int) -> FrequencySensitivity:
    """:func:`frequency_response_sensitivity` on a built ``Delta`` (derivatives of its first ``count``
    parameters)."""
    b = model.input_vector(input)
    H = np.empty(w.size, dtype=complex)
    dH = np.empty((count, w.size), dtype=complex)
    for k, wk in enumerate(w):
        s = 1j * wk
        D = model.delta(s)
        c = model.output_row(output, s)
        x = np.linalg.solve(D, b)
        H[k] = c @ x
        if not count:
            continue
        y = np.linalg.solve(D.T, c)               # Delta^{-T} c
        for i in range(count):
            dH[i, k] = -(y @ (model.delta_p(s, i) @ x)) + y @ model.input_vector_p(input, i) \
                + model.output_row_p(output, s, i) @ x
    mag = np.abs(H)
    with np.errstate(divide="ignore", invalid="ignore"):
        dmag = np.real(np.conj(H) * dH) / mag
        dphase = np.imag(dH / H)
    return FrequencySensitivity(w, tuple(p.name for p in model.parameters[:count]), H, dH, mag, dmag,
                                np.unwrap(np.angle(H)), dphase)


def _refine_extremum(fun, w: np.ndarray, k: int) -> float:
    """Frequency of the extremum of ``fun`` near grid index ``k`` (bounded scalar search)."""
    from scipy.optimize import minimize_scalar

    lo, hi = w[max(k - 1, 0)], w[min(k + 1, w.size - 1)]
    if hi <= lo:
        return float(w[k])
    found = minimize_scalar(fun, bounds=(lo, hi), method="bounded", options={"xatol": 1e-12 * max(1.0, hi)})
    return float(found.x) if found.fun <= fun(w[k]) else float(w[k])


def peak_sensitivity(system: Any, parameters: str | Sequence[str], omega: Any, *, input: str,
                     output: str) -> PeakSensitivity:
    """``max_w |H(i w)|`` (refined between grid points) and its gradient.

    The maximiser is a stationary point of ``|H|`` in ``w``, so the total derivative is the
    partial one there (envelope theorem).  The grid must resolve the peak.
    """
    names = _names(parameters)
    model = characteristic_matrix(system, names)
    input, output = _single("input", input), _single("output", output)
    grid = _response(model, validation.frequencies("omega", omega), input, output, 0)
    k = int(np.argmax(grid.magnitude))

    def negative(x: float) -> float:
        return -float(_response(model, np.array([x]), input, output, 0).magnitude[0])

    wk = _refine_extremum(negative, grid.omega, k)
    at = _response(model, np.array([wk]), input, output, len(names))
    return PeakSensitivity(float(at.magnitude[0]), wk,
                           {n: float(at.magnitude_derivative[i, 0]) for i, n in enumerate(names)})


# ------------------------------------------------------------------------- loop transfer
def _loop_terms(model: LoopCharacteristicMatrix, loop: int, s: complex) -> tuple[complex, complex, np.ndarray]:
    """``L(s)``, ``dL/ds`` and ``dL/dp`` (all parameters) of loop ``loop``, others closed."""
    D = model.delta(s, skip=loop)
    b = model.actuator(loop)
    c, dc = model.sensor(loop, s)
    K, dK = model.loop_gain(loop, s)
    x = np.linalg.solve(D, b)
    y = np.linalg.solve(D.T, c)
    g = c @ x
    g_s = dc @ x - y @ (model.delta_s(s, skip=loop) @ x)
    L = K * g
    L_s = dK * g + K * g_s
    L_p = np.empty(len(model.parameters), dtype=complex)
    for i in range(len(model.parameters)):
        g_p = model.sensor_p(i, loop, s) @ x - y @ (model.delta_p(s, i, skip=loop) @ x) \
            + y @ model.actuator_p(i, loop)
        L_p[i] = model.loop_gain_p(s, i, loop) * g + K * g_p
    return complex(L), complex(L_s), L_p


def _loop_index(model: LoopCharacteristicMatrix, loop: str, system: Any) -> int:
    if not model.loops:
        raise ModelError(f"system must have feedback loops (a ControlledChain or ControlledModel) for the margins of "
                         f"loop {loop!r}, got {system!r:.80}")
    for i, lp in enumerate(model.loops):
        if lp.name == loop:
            return i
    raise unknown_name("loop", loop, [lp.name for lp in model.loops])


def stability_margin_sensitivity(system: Any, loop: str, parameters: str | Sequence[str],
                                 omega: Any) -> PeakSensitivity:
    """``min_w |1 + L(i w)|`` of ``loop`` (refined) and its gradient (``1 / max |S|``)."""
    model = characteristic_matrix(system, _names(parameters))
    i = _loop_index(model, loop, system)
    w = validation.frequencies("omega", omega)

    def distance(x: float) -> float:
        return abs(1.0 + _loop_terms(model, i, 1j * x)[0])

    k = int(np.argmin(np.abs(1.0 + model.loop_transfer(i, 1j * w))))
    wk = _refine_extremum(distance, w, k)
    L, _, L_p = _loop_terms(model, i, 1j * wk)
    value = abs(1.0 + L)
    gradient = np.real(np.conj(1.0 + L) * L_p) / value
    return PeakSensitivity(float(value), wk, {p.name: float(gradient[k]) for k, p in enumerate(model.parameters)})


def _crossing(model, i, w0: float, part: str, target: float) -> tuple[float, complex, complex, np.ndarray]:
    """Newton refinement of a crossover on ``Delta`` (``part``: ``"gain"`` -> log|L| = 0,
    ``"phase"`` -> arg L = target) and the log-derivatives there."""
    w = w0
    for _ in range(8):
        L, L_s, L_p = _loop_terms(model, i, 1j * w)
        l_w = 1j * L_s / L
        if part == "gain":
            f, fw = math.log(abs(L)), l_w.real
        else:
            f = (np.angle(L) - target + math.pi) % (2 * math.pi) - math.pi
            fw = l_w.imag
        step = f / fw
        w -= step
        if abs(step) <= 1e-14 * max(1.0, abs(w)):
            break
    L, L_s, L_p = _loop_terms(model, i, 1j * w)
    if abs(w - w0) > _MISMATCH * max(1.0, abs(w0)) * 1e3:
        raise ModelError(f"ctmm.sensitivity: the {part} crossover of loop {model.loops[i].name!r} at "
                         f"{w0!r} rad/s (ctmm.control.margins, TMM) is not one of Delta (Newton moved it to "
                         f"{w!r} rad/s); refusing to differentiate a mismatched model")
    return w, L, 1j * L_s / L, L_p / L


def margin_sensitivity(system: ControlledChain, loop: str, parameters: str | Sequence[str],
                       omega: Any) -> MarginSensitivity:
    """Gain, phase, delay and stability margins of ``loop`` with their exact gradients.

    Parameters
    ----------
    system : ControlledChain or ControlledModel (planar or spatial plant)
    loop : str
    parameters : str or sequence of str
    omega : array_like
        Dense grid [rad/s] covering the crossovers (as for :func:`ctmm.control.margins`).

    Returns
    -------
    MarginSensitivity
        Derivatives of the margins :func:`ctmm.control.margins` reports (the crossover it picks);
        where two crossovers tie for the delay or phase margin the margin has a kink and the
        gradient is that of the reported crossover.
    """
    from .control.analysis import margins as compute_margins

    names = _names(parameters)
    model = characteristic_matrix(system, names)
    i = _loop_index(model, loop, system)
    found = compute_margins(system, loop, omega)
    crossover: dict = {}
    pm, dm, gm = {}, {}, {}
    if math.isfinite(found.phase_margin):
        w, L, l_w, l_p = _crossing(model, i, found.gain_crossover_frequency, "gain", 0.0)
        dw = -l_p.real / l_w.real
        crossover["gain"] = dict(zip(names, dw.tolist()))
        pm = dict(zip(names, np.degrees(l_p.imag + l_w.imag * dw).tolist()))
    if math.isfinite(found.delay_margin):
        w, L, l_w, l_p = _crossing(model, i, found.delay_crossover_frequency, "gain", 0.0)
        dw = -l_p.real / l_w.real
        crossover["delay"] = dict(zip(names, dw.tolist()))
        phase = found.delay_margin * w
        dm = dict(zip(names, ((l_p.imag + l_w.imag * dw) / w - phase * dw / w ** 2).tolist()))
    if math.isfinite(found.gain_margin) and found.gain_margin > 0:
        w, L, l_w, l_p = _crossing(model, i, found.phase_crossover_frequency, "phase", math.pi)
        dw = -l_p.imag / l_w.imag
        crossover["phase"] = dict(zip(names, dw.tolist()))
        gm = dict(zip(names, (-found.gain_margin * (l_p.real + l_w.real * dw)).tolist()))
    stability = stability_margin_sensitivity(system, loop, names, omega)
    return MarginSensitivity(found, gm, pm, dm, stability.gradient, crossover)


# ------------------------------------------------------------------------ spectral abscissa
def spectral_abscissa_sensitivity(system: Any, parameters: str | Sequence[str], *,
                                  re_min: float | None = None, im_max: float | None = None
                                  ) -> AbscissaSensitivity:
    """Rightmost closed-loop root and the gradient of its real part.

    Parameters
    ----------
    system : Chain, ControlledChain, PlanarModel, SpatialModel or ControlledModel
    parameters : str or sequence of str
    re_min, im_max : float, optional
        Search region [1/s], [rad/s] of :func:`ctmm.stability.spectral_abscissa`; required when a
        loop has a delay or an LTI controller (then the roots come from the TMM characteristic
        function); delay-free static-gain loops use the quadratic eigenvalue problem of ``Delta``.

    Returns
    -------
    AbscissaSensitivity

    Raises
    ------
    ModelError
        No root found right of ``re_min``, a multiple rightmost root (not differentiable), a root
        that is not one of ``Delta`` (model mismatch), a missing region.
    """
    model = characteristic_matrix(system, _names(parameters))
    if all(lp.delay == 0.0 and not lp.is_lti for lp in model.loops):
        roots = model.delay_free_roots()
        method = "quadratic eigenvalues"
    else:
        from .stability import spectral_abscissa

        if re_min is None or im_max is None:
            raise ModelError(f"spectral_abscissa_sensitivity: a loop has a delay or an LTI controller, so the "
                             f"roots are searched in a region: give re_min [1/s] and im_max [rad/s], got "
                             f"re_min={re_min!r}, im_max={im_max!r}")
        found = spectral_abscissa(system, re_min=re_min, im_max=im_max)
        if found.below_re_min or found.root is None:
            raise ModelError(f"spectral_abscissa_sensitivity: no root right of re_min={re_min!r}; lower re_min")
        roots = np.asarray(found.roots.roots, dtype=complex)
        method = "characteristic roots"
    if roots.size == 0:
        raise ModelError("spectral_abscissa_sensitivity: the closed loop has no finite root")
    root = complex(roots[np.argmax(roots.real + 1e-12 * np.sign(roots.imag))])
    if root.imag < 0:
        root = root.conjugate()
    D = model.delta(root)
    U, sigma, Vh = np.linalg.svd(D)
    size = model.scale(root)
    if sigma[-1] > _MISMATCH * size:
        raise ModelError(f"spectral_abscissa_sensitivity: the root {root!r} is not a root of Delta (smallest "
                         f"singular value {sigma[-1]:.3g}, terms of size {size:.3g}); refusing a mismatched model")
    v, w = Vh[-1].conj(), U[:, -1]
    if method == "characteristic roots":      # the root finder's tolerance: Newton on Delta to round-off
        start = root
        for _ in range(6):
            step = -(w.conj() @ D @ v) / (w.conj() @ model.delta_s(root) @ v)
            root += step
            D = model.delta(root)
            U, sigma, Vh = np.linalg.svd(D)
            v, w = Vh[-1].conj(), U[:, -1]
            if abs(step) <= 1e-15 * (1.0 + abs(root)):
                break
        if abs(root - start) > 1e-4 * (1.0 + abs(start)):
            raise ModelError(f"spectral_abscissa_sensitivity: Newton on Delta moved the root {start!r} of "
                             f"ctmm.stability.spectral_abscissa to {root!r}; refusing a mismatched model")
    denominator = w.conj() @ model.delta_s(root) @ v
    scale = np.linalg.norm(model.delta_s(root))
    if abs(denominator) <= 1e-8 * scale or (sigma.size > 1 and sigma[-2] <= 1e-8 * size):
        raise ModelError(f"spectral_abscissa_sensitivity: the rightmost root {root!r} is multiple; its "
                         "derivative does not exist")
    ds = np.array([-(w.conj() @ model.delta_p(root, i) @ v) / denominator for i in range(len(model.parameters))])
    tol = 1e-9 * (1.0 + abs(root))
    ties = tuple(complex(r) for r in roots if abs(r.real - root.real) <= tol
                 and abs(r - root) > tol and abs(r - root.conjugate()) > tol and r.imag >= 0)
    names = [p.name for p in model.parameters]
    return AbscissaSensitivity(root.real, root, dict(zip(names, ds.real.tolist())), dict(zip(names, ds.tolist())),
                               ties, method)


# ---------------------------------------------------------------------------- time domain
def simulation_sensitivity(system: Any, parameters: str | Sequence[str], *, t_final: float, dt: float, q0: Any = None,
                           qdot0: Any = None, outputs: str | Sequence[str] | None = None,
                           x0: Mapping[str, float] | None = None, v0: Mapping[str, float] | None = None) -> Any:
    """Outputs of an RK4 run of a planar or spatial model (loops closed: real-time, LTI, delayed) or of a
    lumped chain (free response) and their exact derivatives with respect to plant and loop numbers.

    Planar models: forward sensitivities of the generated RK4 step by casadi (:func:`ctmm.sensitivity_time.
    planar_simulation_sensitivity`: arrays ``q0``, ``qdot0`` or ``x0``, ``v0`` as :func:`ctmm.simulate` takes
    them, outputs ``"<coordinate>"`` / ``"<coordinate>_dot"``); spatial models: the same on the generated spatial step
    (:func:`ctmm.sensitivity_time_spatial.spatial_simulation_sensitivity`: ``x0``, ``v0`` as
    :func:`ctmm.simulate` takes them, outputs coordinates, velocities and sensor ports); loop numbers
    (``"<loop>.gain"``, ``"<loop>.<sensor>"``, realisation entries ``"<loop>.A[i,j]"``...) as directions in the
    step's parameters (:mod:`ctmm.sensitivity_loop_numbers`); chains: the RK4 of their explicit form with its
    stages differentiated (:func:`ctmm.sensitivity_time.chain_simulation_sensitivity`: ``x0``, ``v0``
    by point name, outputs ``"<point>.x"`` / ``".v"``); controlled chains, and chains with loads as a
    ``ControlledChain`` without loops, in their element and loop numbers through the generated chain step
    (:func:`ctmm.sensitivity_time_chain.controlled_chain_simulation_sensitivity`).  Returns a :class:`TimeSensitivity`.

    Raises
    ------
    ModelError
        Loop delays (a whole number of steps of the generated ring), finite-element subsystems of spatial
        models, models that cannot be compiled, unknown or zero parameters.
    """
    from .sensitivity_planar import is_planar_system
    from .sensitivity_spatial import is_spatial_system
    from .sensitivity_time import chain_forced, chain_simulation_sensitivity, planar_simulation_sensitivity as planar
    from .sensitivity_time import simulation_start
    from .sensitivity_time_chain import controlled_chain_simulation_sensitivity
    from .sensitivity_time_spatial import spatial_simulation_sensitivity as spatial

    q0, qdot0 = simulation_start(system, q0, qdot0, x0, v0, is_planar_system(system))
    if is_spatial_system(system):
        return spatial(system, parameters, t_final=t_final, dt=dt, x0=x0, v0=v0, outputs=outputs)
    if isinstance(system, ControlledChain) or isinstance(system, Chain) and chain_forced(system):
        controlled = system if isinstance(system, ControlledChain) else ControlledChain(system, [])   # loaded chain
        return controlled_chain_simulation_sensitivity(controlled, parameters, t_final=t_final, dt=dt, x0=x0, v0=v0,
                                                       outputs=outputs)
    if isinstance(system, Chain):
        return chain_simulation_sensitivity(system, parameters, t_final=t_final, dt=dt, x0=x0, v0=v0, outputs=outputs)
    if not is_planar_system(system):
        raise ModelError(f"simulation_sensitivity: derivatives of time-domain outputs are implemented for a "
                         f"ctmm.Chain or ControlledChain of lumped elements and for planar and spatial models, alone "
                         f"or in a ControlledModel; {type(system).__name__} is not supported; use the frequency-"
                         "domain, margin and spectral-abscissa sensitivities of ctmm.sensitivity where they apply")
    return planar(system, parameters, t_final=t_final, dt=dt, q0=q0, qdot0=qdot0, outputs=outputs)
