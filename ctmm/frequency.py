"""Frequency domain (linear MSTMM): forced response, FRFs, natural frequencies, mode shapes.

All functions evaluate every element's ``U(s)`` for the whole frequency vector at once and
solve the chain by batched Riccati transfer (:mod:`ctmm.assembly`).

Natural frequencies: Wittrick-Williams counting
-----------------------------------------------
For an undamped (conservative) chain the number of natural frequencies below ``omega`` is

    J(omega) = sum_j J0_j(omega) + s{K(omega)}

where ``s{K}`` is the number of negative eigenvalues met in the Gaussian elimination of the
dynamic stiffness matrix (Sylvester's law of inertia) and ``J0_j`` counts the natural frequencies
of element ``j`` with both ends clamped (0 for massless springs; see
:meth:`~ctmm.elements.beams.BeamField.clamped_frequency_count`).  The stiffness-form Riccati
transfer ``F_j = S_j d_j`` *is* that elimination: crossing a field element the pivot is
``Pi = -U12^{-1} (U11 + U12 S)`` = (element's inboard dynamic stiffness) + (condensed stiffness
``-S`` of everything inboard).  Bisection on ``J`` isolates every root, clustered or repeated,
without missing or duplicating any (Wittrick & Williams, Q. J. Mech. Appl. Math. 24, 1971).
"""
from __future__ import annotations

from typing import Any, Mapping, Sequence

import numpy as np

from . import validation
from .assembly import SOLVERS, BoundaryEnd, BoundaryStart, ChainSolution
from .errors import ModelError
from .results import FrequencyResponse, ModalResult
from .system import Chain


def _as_s(omega: Any, name: str = "omega") -> np.ndarray:
    omega = validation.finite_array(name, omega)
    if omega.ndim > 1:
        raise ModelError(f"{name} must be a scalar or 1-D array, got shape {omega.shape}")
    if np.any(omega < 0):
        raise ModelError(f"{name} must be >= 0 [rad/s], got min {omega.min()!r}")
    return 1j * np.atleast_1d(omega)


def assemble(system: Chain, s: np.ndarray, amplitudes: Mapping[int, Mapping[str, Any]] | None = None):
    """Element matrices and boundary relations of ``system`` at Laplace variables ``s``.

    Parameters
    ----------
    system : Chain
    s : ndarray
        1-D array of Laplace variables [1/s].
    amplitudes : mapping, optional
        ``{element position: {input name: phasor}}``.

    Returns
    -------
    Us, us, start, end
        Inputs of :func:`ctmm.assembly.riccati_solve`.
    """
    amplitudes = amplitudes or {}
    if hasattr(system, "assemble_frequency"):  # controlled systems extend the plant's matrices
        return system.assemble_frequency(s, amplitudes)
    layout = system.layout
    Us, us = [], []
    for pos, element in enumerate(system.elements[1:-1], start=1):
        Us.append(np.asarray(element.transfer_matrix(s), dtype=complex))
        us.append(np.asarray(element.load_vector(s, amplitudes.get(pos, {})), dtype=complex))
    e_idx, S0, P0 = system.start.start(layout, s, amplitudes.get(0, {}))
    Bm, b = system.end.end(layout, s, amplitudes.get(len(system.elements) - 1, {}))
    return Us, us, BoundaryStart(e_idx, S0, P0), BoundaryEnd(Bm, b)


def solve(system: Chain, s: np.ndarray, amplitudes=None, *, solver: str = "riccati") -> ChainSolution:
    """States at every connection point for harmonic loads (phasors), batched over ``s``."""
    if solver not in SOLVERS:
        raise ModelError(f"solver must be one of {sorted(SOLVERS)}, got {solver!r}")
    Us, us, start, end = assemble(system, s, amplitudes)
    sol = SOLVERS[solver](Us, us, start, end)
    index = getattr(system, "state_index", None)
    if index is not None:  # controlled chains interleave sensing matrices: keep the points only
        sol.states = sol.states[np.asarray(index)]
    return sol


def _output_value(system, states: np.ndarray, s: np.ndarray, name: str,
                  amplitudes: Mapping | None = None) -> np.ndarray:
    sig = system.signal(name)
    if sig.derivative == -1:  # control force of a loop: u = -C(s) e^{-s tau} (y - r)
        loop = system.loop(name.split(".")[0])
        ref = (amplitudes or {}).get(loop.name, {}).get("reference", 0.0)
        return -loop.loop_gain(s) * (states[sig.point, :, sig.component] - ref)
    return states[sig.point, :, sig.component] * s ** sig.derivative


def frequency_response(system: Chain, omega: Any, *, input: str | Sequence[str],  # noqa: A002
                       output: str | Sequence[str], solver: str = "riccati") -> FrequencyResponse:
    """Frequency response functions from force/displacement inputs to outputs.

    Parameters
    ----------
    system : Chain
        The model.
    omega : array_like
        Angular frequencies [rad/s], >= 0.
    input : str or sequence of str
        Input names, e.g. ``"m1.force"`` [N] or ``"base.displacement"`` [m].
    output : str or sequence of str
        Output signal names, e.g. ``"m3.x"`` [m], ``"m3.v"``, ``"m3.a"``, ``"k2.f"`` [N].
    solver : {"riccati", "plain"}
        Chain solver (plain products only for comparison).

    Returns
    -------
    FrequencyResponse
        ``response[i_out, i_in, k]`` = output phasor per unit input phasor at ``omega[k]``.

    Examples
    --------
    >>> import numpy as np, ctmm
    >>> from ctmm.elements import Fixed, Spring, Mass, Free
    >>> chain = ctmm.Chain("sdof", [Fixed("wall"), Spring("k", 100.0), Mass("m", 1.0), Free("end")])
    >>> frf = ctmm.frequency_response(chain, [0.0, 5.0], input="m.force", output="m.x")
    >>> np.allclose(frf("m.x", "m.force"), 1 / (100.0 - np.array([0.0, 25.0])))
    True
    """
    inputs = (input,) if isinstance(input, str) else tuple(input)
    outputs = (output,) if isinstance(output, str) else tuple(output)
    s = _as_s(omega)
    for o in outputs:
        system.signal(o)
    resolved = [system.input(i) for i in inputs]
    response = np.empty((len(outputs), len(inputs), s.size), dtype=complex)
    for k, inp in enumerate(resolved):
        amps = {inp.position: {inp.input: 1.0}}
        sol = solve(system, s, amps, solver=solver)
        for j, o in enumerate(outputs):
            response[j, k] = _output_value(system, sol.states, s, o, amps)
    return FrequencyResponse(np.imag(s), response, inputs, outputs, system.name)


def steady_state_response(system: Chain, omega: float, *, outputs: Sequence[str] | None = None,
                          solver: str = "riccati") -> dict[str, complex]:
    """Steady-state phasors of outputs under the elements' own harmonic/constant loads at ``omega``.

    Every load signal must be constant (used at ``omega = 0``) or
    :class:`~ctmm.signals.Harmonic` with frequency ``omega`` [rad/s].
    """
    s = _as_s(omega)
    amplitudes: dict[int, dict[str, complex]] = {}
    for pos, element in enumerate(system.elements):
        if hasattr(element, "steady_state_amplitudes"):
            amps = {}
            for key, value in element.steady_state_amplitudes().items():
                signal = getattr(element, key)
                sig_omega = getattr(signal, "omega", 0.0)
                if value != 0 and not np.isclose(sig_omega, float(np.imag(s[0]))):
                    raise ModelError(f"{element.name}.{key} varies at {sig_omega} rad/s, not at omega={omega}")
                amps[key] = value
            amplitudes[pos] = amps
    sol = solve(system, s, amplitudes, solver=solver)
    names = outputs or system.signal_names()
    return {n: complex(_output_value(system, sol.states, s, n)[0]) for n in names}


def characteristic_function(system, s: Any, *, normalize: bool = True) -> np.ndarray:
    """Characteristic function ``Delta(s)`` of a (controlled) chain, vectorised over ``s``.

    ``Delta`` is the determinant of the boundary equations accumulated by the Riccati sweep
    (product of the ``det G_j`` and of the end matrix), multiplied by the factors that clear the
    poles of the element matrices (connectors ``k + c s``, controller denominators), so that it
    is entire in ``s`` and vanishes exactly at the (closed-loop) characteristic roots, including
    exact delays ``e^{-s tau}``.

    Parameters
    ----------
    system : Chain or ControlledChain
    s : array_like
        Complex Laplace variables [1/s].
    normalize : bool
        Divide by ``Delta`` at ``s = 1`` (a constant) to keep magnitudes near one.
    """
    s_arr = np.atleast_1d(np.asarray(s, dtype=complex))
    shape = s_arr.shape
    flat = s_arr.ravel()
    Us, us, start, end = assemble(system, flat)
    sol = SOLVERS["riccati"](Us, us, start, end, want_states=False)
    log_delta = sol.log_det + np.log(_scale(system, flat).astype(complex))
    if normalize:
        Us1, us1, start1, end1 = assemble(system, np.array([1.0 + 0j]))
        ref = SOLVERS["riccati"](Us1, us1, start1, end1, want_states=False).log_det[0]
        log_delta = log_delta - ref - np.log(complex(_scale(system, np.array([1.0 + 0j]))[0]))
    return np.exp(log_delta).reshape(shape)


def _scale(system, s: np.ndarray) -> np.ndarray:
    if hasattr(system, "characteristic_scale"):
        return system.characteristic_scale(s)
    from .elements.lumped import Connector

    scale = np.ones(s.shape, dtype=complex)
    for e in system.body:
        if isinstance(e, Connector):
            scale = scale * e.connector_stiffness(s)
    return scale


# -- natural frequencies ---------------------------------------------------------------
def _check_conservative(system: Chain) -> None:
    for e in system.elements:
        if getattr(e, "damping", 0.0):
            raise ModelError(
                f"natural_frequencies needs an undamped system, but {e.name!r} has damping="
                f"{e.damping!r}; use frequency_response for damped systems")
        if getattr(e, "is_conservative", True) is False:
            raise ModelError(f"natural_frequencies needs a conservative system; {e.name!r} is not")


def eigenvalue_count(system: Chain, omega: Any) -> np.ndarray:
    """Number of natural frequencies strictly below each ``omega`` [rad/s] (Wittrick-Williams).

    Parameters
    ----------
    system : Chain
        An undamped chain.
    omega : array_like
        Frequencies [rad/s] > 0.
    """
    omega = np.atleast_1d(validation.finite_array("omega", omega))
    if _is_lumped(system):
        return _lumped_count(system, omega)
    s = 1j * omega
    d = system.layout.half
    B = omega.size
    count = np.zeros(B, dtype=int)
    clamped = system.start.known == "displacement"
    if clamped:
        S = np.zeros((B, d, d))
    else:
        S = -np.real(system.start._stiffness(s))[:, None, None] * np.eye(d)
    for element in system.body:
        U = np.real(element.transfer_matrix(s))
        U11, U12, U21, U22 = U[:, :d, :d], U[:, :d, d:], U[:, d:, :d], U[:, d:, d:]
        if hasattr(element, "clamped_frequency_count"):
            count += np.asarray(element.clamped_frequency_count(omega), dtype=int)
        if element.is_point:
            if not clamped:
                S = U21 + U22 @ S  # U11 = I, U12 = 0 for point elements
            continue
        U12_inv = np.linalg.inv(U12)
        if clamped:
            S = U22 @ U12_inv
            clamped = False
            continue
        G = U11 + U12 @ S
        pivot = -U12_inv @ G
        count += _negative_eigenvalues(pivot)
        S = (U21 + U22 @ S) @ np.linalg.inv(G)
    if system.end.known == "force" and not clamped:
        k_end = np.real(system.end._stiffness(s))[:, None, None] * np.eye(d)
        count += _negative_eigenvalues(k_end - S)
    return count


def _is_lumped(system) -> bool:
    from .elements.lumped import Connector, PointElement

    return system.layout.size == 2 and all(isinstance(e, (PointElement, Connector)) for e in system.body)


def _lumped_count(system, omega: np.ndarray) -> np.ndarray:
    """Scalar Wittrick-Williams count for 1-D lumped chains (same recursion as the general one).

    ``S = -K_L`` (condensed dynamic stiffness of the inboard part, negated); a point element adds
    ``m w^2 - k_g``; a connector ``k`` has pivot ``k - S`` and maps ``S -> k S / (k - S)``.
    """
    from .elements.lumped import Connector

    w2 = omega * omega
    count = np.zeros(omega.size, dtype=int)
    clamped = system.start.known == "displacement"
    S = np.zeros(omega.size) if clamped else np.full(omega.size, -float(np.real(system.start._stiffness(0.0))))
    with np.errstate(divide="ignore", invalid="ignore", over="ignore"):
        for e in system.body:
            if isinstance(e, Connector):
                k = e.stiffness
                if clamped:
                    S = np.full(omega.size, -k)
                    clamped = False
                    continue
                pivot = k - S
                pivot = np.where(pivot == 0.0, -np.finfo(float).tiny, pivot)  # limit from above
                count += pivot < 0
                S = k * S / pivot
            elif not clamped:
                S = S + (e.mass * w2 - e.stiffness)
    if system.end.known == "force" and not clamped:
        count += (float(np.real(system.end._stiffness(0.0))) - S) < 0
    return count


def _negative_eigenvalues(pivot: np.ndarray) -> np.ndarray:
    if pivot.shape[-1] == 1:
        return (pivot[:, 0, 0] < 0).astype(int)
    sym = 0.5 * (pivot + np.swapaxes(pivot, -1, -2))
    return np.sum(np.linalg.eigvalsh(sym) < 0, axis=-1)


def natural_frequencies(system: Chain, *, n_modes: int | None = None, omega_max: float | None = None,
                        rtol: float = 1e-14) -> np.ndarray:
    """Undamped natural frequencies [rad/s] by Wittrick-Williams counting and bisection.

    Parameters
    ----------
    system : Chain
        An undamped chain.
    n_modes : int, optional
        Number of lowest frequencies wanted (rigid-body modes count, returned as 0).
    omega_max : float, optional
        Return all natural frequencies below ``omega_max`` [rad/s] instead.
    rtol : float
        Relative bracket width at which bisection stops.

    Returns
    -------
    ndarray
        Ascending natural frequencies; a repeated frequency appears once per multiplicity.
    """
    _check_conservative(system)
    if (n_modes is None) == (omega_max is None):
        raise ModelError("give exactly one of n_modes (int >= 1) or omega_max (rad/s > 0)")
    if n_modes is not None:
        if not isinstance(n_modes, (int, np.integer)) or n_modes < 1:
            raise ModelError(f"n_modes must be an integer >= 1, got {n_modes!r}")
        hi = 1.0
        while eigenvalue_count(system, [hi])[0] < n_modes:
            hi *= 2.0
            if hi > 1e15:
                raise ModelError(f"chain {system.name!r} has fewer than {n_modes} natural frequencies")
        targets = np.arange(1, n_modes + 1)
    else:
        hi = validation.positive("omega_max", omega_max)
        total = int(eigenvalue_count(system, [hi])[0])
        targets = np.arange(1, total + 1)
    if targets.size == 0:
        return np.zeros(0)
    tiny = hi * 1e-12
    n_rigid = int(eigenvalue_count(system, [tiny])[0])
    roots = np.zeros(targets.size)
    flexible = targets > n_rigid
    k = targets[flexible]
    lo = np.full(k.size, tiny)
    up = np.full(k.size, hi)
    # bisection on the count: root_k = inf{omega : count(omega) >= k}
    while True:
        active = (up - lo) > rtol * up
        if not np.any(active):
            break
        mid = 0.5 * (lo + up)
        c = eigenvalue_count(system, mid[active])
        below = c >= k[active]
        idx = np.flatnonzero(active)
        up[idx[below]] = mid[active][below]
        lo[idx[~below]] = mid[active][~below]
    roots[flexible] = 0.5 * (lo + up)
    return roots


def mode_shapes(system: Chain, *, n_modes: int | None = None, omega_max: float | None = None) -> ModalResult:
    """Natural frequencies and mode shapes (states at all connection points).

    A shape is computed by one step of inverse iteration done with the transfer matrices: the
    forced response at the computed natural frequency to a generic load (fixed pseudo-random
    amplitudes on every element input).  This is a backward-stable solve whose result is the
    mode to relative accuracy ``|w - w_k| / gap``, also for strongly localised modes where a
    homogeneous back-substitution from one end would amplify round-off.  Shapes are normalised
    so that the largest displacement component is +1.
    """
    omega = natural_frequencies(system, n_modes=n_modes, omega_max=omega_max)
    s = 1j * np.maximum(omega, 1e-300)
    rng = np.random.default_rng(20260101)
    amplitudes = {pos: {e.inputs[0]: 1.0 + rng.random()} for pos, e in enumerate(system.elements)
                  if e.inputs and pos not in (0, len(system.elements) - 1)}
    if amplitudes:
        sol = solve(system, s, amplitudes)
    else:  # no element takes a load: homogeneous back-substitution from the end
        Us, us, start, end = assemble(system, s)
        us = [np.zeros_like(u) for u in us]
        start.P0 = np.zeros_like(start.P0)
        end.b = np.zeros_like(end.b)
        sol = SOLVERS["riccati"](Us, us, start, end, homogeneous=True)
    shapes = np.transpose(sol.states, (1, 0, 2))  # (modes, points, components)
    d = system.layout.half
    disp = shapes[..., :d].reshape(len(omega), -1)
    ref = disp[np.arange(len(omega)), np.argmax(np.abs(disp), axis=1)]
    shapes = np.real_if_close(shapes / ref[:, None, None], tol=1e6)
    return ModalResult(omega, shapes, system.layout.components, tuple(system.point_names()))
