"""Frequency domain (linear MSTMM): forced response, FRFs, natural frequencies, mode shapes.

All functions evaluate every element's ``U(s)`` for the whole frequency vector at once and
solve the chain by batched Riccati transfer (:mod:`ctmm.chain_assembly`, :mod:`ctmm.assembly`).

Natural frequencies, their counting and mode shapes live in :mod:`ctmm.natural` (re-exported here).
Planar models (:class:`~ctmm.planar.model.PlanarModel`, ``ControlledModel``) are answered through
their linearisation by :mod:`ctmm.planar_frequency`, spatial models by :mod:`ctmm.spatial_frequency`
(dispatched here).
"""
from __future__ import annotations

import time
from typing import Any, Mapping, Sequence

import numpy as np

from . import validation
from .assembly import SOLVERS, ChainSolution
from . import planar_frequency, spatial_exact_fields, spatial_frequency
from .capabilities import require_chain
from .chain_assembly import assemble, laplace_variables, solve  # noqa: F401  (assemble, solve: public here too)
from .elements.axial import AxialJoint
from .entire_values import entire_logs
from .errors import ModelError
from . import natural
from .planar_frequency import is_planar_system
from .results import FrequencyResponse
from .signal_units import signal_unit
from .system import Chain, require_system


def _output_value(system, solution: ChainSolution, s: np.ndarray, name: str,
                  amplitudes: Mapping | None = None) -> np.ndarray:
    sig = system.signal(name)
    value = solution.at(sig.point)[:, sig.component]
    if sig.derivative == -1:  # control force of a loop: u = -C(s) e^{-s tau} (y - r)
        loop = system.loop(name.split(".")[0])
        ref = (amplitudes or {}).get(loop.name, {}).get("reference", 0.0)
        return -loop.loop_gain(s) * (value - ref)
    return value * s ** sig.derivative


def frequency_response(system: Chain, omega: Any, *, input: str | Sequence[str],  # noqa: A002
                       output: str | Sequence[str], solver: str = "riccati",
                       operating_point: Any = None, fields: str | None = None) -> FrequencyResponse:
    """Frequency response functions from force/displacement inputs to outputs.

    Parameters
    ----------
    system : Chain, ControlledChain, PlanarModel, ControlledModel or SpatialModel
        The model.  A spatial model (or a ControlledModel on one) is answered through its linearisation
        (:func:`ctmm.spatial_frequency.frequency_response`: actuator ports and input components as inputs,
        sensor ports, tangent coordinates and velocities as outputs, loops closed).  A planar model is answered through its linearisation about
        ``operating_point`` (:func:`ctmm.planar_frequency.frequency_response`: actuator inputs,
        sensor outputs of :mod:`ctmm.planar.ports`).
    omega : array_like
        Angular frequencies [rad/s], >= 0.
    input : str or sequence of str
        Input names, e.g. ``"m1.force"`` [N] or ``"base.displacement"`` [m].
    output : str or sequence of str
        Output signal names, e.g. ``"m3.x"`` [m], ``"m3.v"``, ``"m3.a"``, ``"k2.f"`` [N].
    solver : {"riccati", "plain"}
        Chain solver (plain products only for comparison).
    operating_point : optional
        Planar models only (:func:`ctmm.linearize`; default: the static equilibrium).
    fields : {"modal", "exact"}, optional
        Planar and spatial models: ``"exact"`` answers a straight chain with beams by exact beam fields
        (:mod:`ctmm.exact_fields`, :mod:`ctmm.spatial_exact_fields`); default ``"modal"`` (the model as built).

    Returns
    -------
    FrequencyResponse
        ``response[i_out, i_in, k]`` = output phasor per unit input phasor at ``omega[k]``.  A chain's
        ``info["kernel"]`` says which recursion answered: ``"compiled"`` (a lumped chain with a C compiler
        present, :mod:`ctmm.compiled_chain_frequency`) or ``"numpy"``.

    Examples
    --------
    >>> import numpy as np, ctmm
    >>> from ctmm.elements import Fixed, Spring, Mass, Free
    >>> chain = ctmm.Chain("sdof", [Fixed("wall"), Spring("k", 100.0), Mass("m", 1.0), Free("end")])
    >>> frf = ctmm.frequency_response(chain, [0.0, 5.0], input="m.force", output="m.x")
    >>> np.allclose(frf("m.x", "m.force"), 1 / (100.0 - np.array([0.0, 25.0])))
    True
    """
    if _is_kinematic_loop(system) or _is_spatial_loop(system):
        if solver != "riccati" or fields not in (None, "modal"):
            raise ModelError(f"frequency_response: solver={solver!r} and fields={fields!r} are for chains and planar "
                             "models; a kinematic loop model is answered through its linearisation (leave the defaults)")
        from .planar.loop_verbs import frequency_response_loops
        from .spatial.closed_loop_verbs import frequency_response_spatial_loops

        respond = frequency_response_spatial_loops if _is_spatial_loop(system) else frequency_response_loops
        return respond(system, omega, input=input, output=output, operating_point=operating_point)
    if _is_spatial(system):
        if solver != "riccati" or fields not in (None, "modal", "exact"):
            raise ModelError(f"frequency_response: solver={solver!r} and fields={fields!r}: a spatial model takes "
                             "fields='modal' (its linearisation, the default) or 'exact' (ctmm.spatial_exact_fields)")
        if fields == "exact":
            return spatial_exact_fields.frequency_response(system, omega, input=input, output=output,
                                                           operating_point=operating_point)
        return spatial_frequency.frequency_response(system, omega, input=input, output=output,
                                                    operating_point=operating_point)
    if is_planar_system(system):
        if solver != "riccati":
            raise ModelError(f"frequency_response: solver={solver!r} is a chain solver; a planar model is answered "
                             "through its linearisation (ctmm.linearize), pass no solver")
        return planar_frequency.frequency_response(system, omega, input=input, output=output,
                                                   operating_point=operating_point, fields=fields or "modal")
    if fields is not None:
        raise ModelError(f"frequency_response: fields={fields!r} is for planar models; a chain's beam fields are "
                         "already exact")
    if operating_point is not None:
        raise ModelError(f"frequency_response: operating_point is for planar models; a chain is linear, got "
                         f"operating_point={operating_point!r}")
    require_chain(system, "frequency_response")
    system = require_system(system)
    inputs = validation.names("input", input)
    outputs = validation.names("output", output)
    solver = validation.option("solver", solver, SOLVERS)
    s = laplace_variables(omega)
    points = sorted({system.signal(o).point for o in outputs})
    resolved = [system.input(i) for i in inputs]
    response = np.empty((len(outputs), len(inputs), s.size), dtype=complex)
    started = time.perf_counter()
    kernels = set()
    for k, inp in enumerate(resolved):
        amps = {inp.position: {inp.input: 1.0}}
        sol = solve(system, s, amps, solver=solver, points=points)
        kernels.add(sol.kernel)
        for j, o in enumerate(outputs):
            response[j, k] = _output_value(system, sol, s, o, amps)
    units = {name: signal_unit(name, system) for name in (*inputs, *outputs)}
    info = {"solver": solver, "wall_time_s": time.perf_counter() - started, "n_frequencies": int(s.size),
            "kernel": "/".join(sorted(kernels))}
    return FrequencyResponse(np.imag(s), response, inputs, outputs, system.name, info=info, units=units)


def steady_state_response(system: Chain, omega: float, *, outputs: Sequence[str] | None = None,
                          solver: str = "riccati") -> dict[str, complex]:
    """Steady-state phasors of outputs under the elements' own harmonic/constant loads at ``omega``.

    Every load signal must be constant (used at ``omega = 0``) or
    :class:`~ctmm.signals.Harmonic` with frequency ``omega`` [rad/s].  A controlled chain is
    answered with its loops closed (loop references 0).  Displacements are measured from the
    unstretched configuration (as every frequency-domain output): free lengths, support
    positions and elastic anchors are static offsets that are not included; add
    :func:`ctmm.timestep.rest_positions` for absolute positions as :func:`ctmm.simulate` reports them.

    Parameters
    ----------
    system : Chain or ControlledChain
        The model.
    omega : float
        One angular frequency [rad/s], >= 0 (a sequence is refused: call once per frequency).
    outputs : sequence of str, optional
        Output signal names (default: every signal).
    solver : {"riccati", "plain"}
        Chain solver.
    """
    require_chain(system, "steady_state_response")
    system = require_system(system)
    s = 1j * validation.frequencies("omega", omega, scalar=True)
    solver = validation.option("solver", solver, SOLVERS)
    names = None if outputs is None else validation.names("outputs", outputs)
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
    names = names or system.signal_names()
    return {n: complex(_output_value(system, sol, s, n)[0]) for n in names}


def characteristic_function(system, s: Any, *, normalize: bool = True) -> np.ndarray:
    """Characteristic function ``Delta(s)`` of a (controlled) chain, vectorised over ``s``.

    ``Delta`` is the determinant of the boundary equations accumulated by the Riccati sweep
    (product of the ``det G_j`` and of the end matrix), multiplied by the factors that clear the
    poles of the element matrices (connectors ``k + c s``, controller denominators), so that it
    is entire in ``s`` and vanishes exactly at the (closed-loop) characteristic roots, including
    exact delays ``e^{-s tau}``.  Where the sweep itself fails although ``Delta`` is finite (a
    connector without spring at ``s = 0``, a substructure resonance), the value is the certified
    mean of ``Delta`` on a small circle (:func:`ctmm.entire_values.entire_logs`).

    Parameters
    ----------
    system : Chain or ControlledChain
    s : array_like
        Complex Laplace variables [1/s].
    normalize : bool
        Divide by ``Delta`` at ``s = 1`` (a constant) to keep magnitudes near one.
    """
    require_chain(system, "characteristic_function")
    system = require_system(system)
    s_arr = np.atleast_1d(validation.complex_array("s", s))
    validation.flag("normalize", normalize)
    shape = s_arr.shape
    flat = s_arr.ravel()
    log_delta = entire_logs(lambda z: _log_delta(system, z), flat)[0]
    if normalize:
        log_delta = log_delta - entire_logs(lambda z: _log_delta(system, z), np.array([1.0 + 0j]))[0, 0]
    return np.exp(log_delta).reshape(shape)


def _log_delta(system, s: np.ndarray) -> np.ndarray:
    """``log Delta(s)`` by one Riccati sweep (NaN or ``LinAlgError`` where the sweep fails: at a
    zero of a connector's stiffness, e.g. s = 0 for a pure damper, or a substructure resonance;
    :func:`ctmm.entire_values.entire_logs` then evaluates the finite value by a circle mean)."""
    with np.errstate(divide="ignore", invalid="ignore"):
        Us, us, start, end = assemble(system, s, subdivide=True)     # long beams: exact pieces
        sol = SOLVERS["riccati"](Us, us, start, end, want_states=False)
        return sol.log_det + np.log(_scale(system, s).astype(complex))


def _scale(system, s: np.ndarray) -> np.ndarray:
    if hasattr(system, "characteristic_scale"):
        return system.characteristic_scale(s)
    scale = np.ones(s.shape, dtype=complex)
    for e in system.body:
        if isinstance(e, AxialJoint):
            scale = scale * e.connector_stiffness(s)
    return scale



def _is_spatial(system: Any) -> bool:
    return spatial_frequency.is_spatial_system(system)


def _is_kinematic_loop(system: Any) -> bool:
    from .planar.closed_loops import KinematicLoopModel

    return isinstance(system, KinematicLoopModel) or isinstance(getattr(system, "plant", None), KinematicLoopModel)


def _is_spatial_loop(system: Any) -> bool:
    from .spatial.closed_loops import SpatialKinematicLoopModel     # spatial cut joints: docs/closed_loops.md §8

    return isinstance(system, SpatialKinematicLoopModel) or isinstance(getattr(system, "plant", None),
                                                                       SpatialKinematicLoopModel)


def natural_frequencies(system: Any, **options: Any) -> np.ndarray:
    """Undamped natural frequencies [rad/s] of a chain, a planar or a spatial model.

    A :class:`~ctmm.system.Chain` is answered by :func:`ctmm.natural.natural_frequencies`
    (options ``n_modes``, ``omega_max``, ``rtol``); a ``PlanarModel`` through its undamped
    linearisation by :func:`ctmm.planar_frequency.natural_frequencies` (options ``n_modes``,
    ``omega_max``, ``operating_point``, ``fields="exact"`` for the exact-field form of a straight
    chain with beams, :mod:`ctmm.exact_fields`); a ``SpatialModel`` by
    :func:`ctmm.spatial_frequency.natural_frequencies` (options ``n_modes``, ``omega_max``,
    ``operating_point``; ``fields="exact"`` for the exact spatial beam fields of a straight chain,
    :mod:`ctmm.spatial_exact_fields`).  Damped systems and systems with loops are refused.
    """
    if _is_spatial_loop(system):
        from .spatial.closed_loop_verbs import natural_frequencies_spatial_loops

        return natural_frequencies_spatial_loops(system, **options)
    if _is_kinematic_loop(system):
        from .planar.loop_verbs import natural_frequencies_loops

        return natural_frequencies_loops(system, **options)
    if is_planar_system(system):
        return planar_frequency.natural_frequencies(system, **options)
    if _is_spatial(system):
        fields = options.pop("fields", "modal")
        if fields == "exact":
            return spatial_exact_fields.natural_frequencies(system, **options)
        if fields != "modal":
            raise ModelError(f"natural_frequencies: fields must be 'modal' or 'exact', got {fields!r}")
        return spatial_frequency.natural_frequencies(system, **options)
    if "fields" in options:
        raise ModelError(f"natural_frequencies: fields={options['fields']!r} is for planar models; a chain's beam "
                         "fields are already exact")
    return natural.natural_frequencies(system, **options)


def eigenvalue_count(system: Any, omega: Any, **options: Any) -> np.ndarray:
    """Number of undamped natural frequencies strictly below each ``omega`` [rad/s].

    Chains: :func:`ctmm.natural.eigenvalue_count`; planar models (rigid or flexible):
    :func:`ctmm.planar_frequency.eigenvalue_count` (option ``operating_point``); spatial models:
    :func:`ctmm.spatial_frequency.eigenvalue_count`.
    """
    if _is_spatial_loop(system):
        from .spatial.closed_loop_verbs import eigenvalue_count_spatial_loops

        return eigenvalue_count_spatial_loops(system, omega, **options)
    if _is_kinematic_loop(system):
        from .planar.loop_verbs import eigenvalue_count_loops

        return eigenvalue_count_loops(system, omega, **options)
    if is_planar_system(system):
        return planar_frequency.eigenvalue_count(system, omega, **options)
    if _is_spatial(system):
        return spatial_frequency.eigenvalue_count(system, omega, **options)
    return natural.eigenvalue_count(system, omega, **options)


def mode_shapes(system: Any, **options: Any):
    """Natural frequencies and mode shapes of a chain or a planar model.

    Chains: :func:`ctmm.natural.mode_shapes` (states at the connection points); planar models:
    :func:`ctmm.planar_frequency.mode_shapes` (shapes in the generalised coordinates); spatial models:
    :func:`ctmm.spatial_frequency.mode_shapes` (shapes in the tangent coordinates); kinematic loop models:
    :func:`ctmm.planar.loop_verbs.mode_shapes_loops` (tree coordinates) and
    :func:`ctmm.spatial.closed_loop_verbs.mode_shapes_spatial_loops` (the tree's tangent coordinates).
    """
    if _is_spatial_loop(system):
        from .spatial.closed_loop_verbs import mode_shapes_spatial_loops

        return mode_shapes_spatial_loops(system, **options)
    if _is_kinematic_loop(system):
        from .planar.loop_verbs import mode_shapes_loops

        return mode_shapes_loops(system, **options)
    if is_planar_system(system):
        return planar_frequency.mode_shapes(system, **options)
    if _is_spatial(system):
        return spatial_frequency.mode_shapes(system, **options)
    return natural.mode_shapes(system, **options)
