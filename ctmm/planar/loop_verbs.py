"""The library verbs on closed kinematic loops (:class:`~ctmm.planar.closed_loops.KinematicLoopModel`).

:func:`ctmm.simulate`, :func:`ctmm.linearize`, :func:`ctmm.natural_frequencies`, :func:`ctmm.mode_shapes`,
:func:`ctmm.eigenvalue_count` and :func:`ctmm.frequency_response` hand a kinematic loop model to the
functions of this module, which call the model's own mechanism (the cut forces as boundary unknowns,
``docs/closed_loops.md`` §2):

* time: ``"rk4"`` (fixed step, projection onto the constraints after every step) and the ``solve_ivp``
  methods (Baumgarte only) through :func:`~ctmm.planar.closed_loops.simulate_kinematic_loops`; every
  DT-TMM scheme through the tree's implicit stepper (:func:`ctmm.planar.implicit.simulate_implicit`)
  with the cut forces re-solved from the boundary compliance at every Newton iterate
  (:meth:`KinematicLoopModel.cut_inputs`; their state dependence enters the Newton tangent by
  directional differences), projected onto the cut joints after every step
  (:func:`ctmm.planar.implicit_kinematic_loops.simulate_loop_scheme`).  Every result holds the tree coordinates and rates, the
  cut forces ``"<cut>.force_x"``, ``"<cut>.force_y"`` [N] (on the child point, global axes) and the
  constraint drift ``"drift"`` [m] and ``"drift_rate"`` [m/s].
* frequency: the linearisation on the constraint manifold (:meth:`KinematicLoopModel.linearize`) in
  the independent coordinates ``z = N^T (q - q0)`` (states ``"z1"``, ..., ``"z1_dot"``, ...; ``N`` the
  orthonormal null space of the constraint Jacobian at ``q0``), with the tree's actuators as inputs and
  its sensors and the cut forces as outputs.

Feedback loops (``ctmm.control.with_feedback(model, loops)``) close around the same linearisation
(:func:`linearize_loops`, :func:`frequency_response_loops`; delays exact); in time they run in the loop driver
(:mod:`ctmm.kinematic_loop_time`).
"""
from __future__ import annotations

import contextlib
import time
from typing import Any, Callable, Iterator, Mapping, Sequence

import numpy as np

from .. import validation
from ..controlled_linearization import delayed_loop_response
from ..errors import ModelError, SimulationError
from ..linearized import LinearizedSystem, OperatingPoint, control_name
from ..ode import output_grid
from ..results import FrequencyResponse, ModalResult, SimulationResult
from ..schemes import SCHEMES, Scheme, as_scheme
from ..signal_results import SignalSystem, signal_result
from ..loop_integration import check_consistent
from ..loop_manifold import at_equilibrium, input_output_matrices, require_equilibrium, undamped_modes
from ..loop_model_feedback import linearize_with_feedback
from .closed_loops import KinematicLoopModel, KinematicLoopSimulation, simulate_kinematic_loops
from .equilibrium import hanging_configuration
from .integrate import SCIPY_METHODS, coordinate_values, model_signals
from .loop_ports import KinematicLoopPorts, loop_sensor_signals, tree_outputs
from .ports import actuator_names

__all__ = ["initial_state", "simulate_loops", "linearize_loops", "natural_frequencies_loops", "mode_shapes_loops",
           "eigenvalue_count_loops", "frequency_response_loops", "cut_signal_names"]

_DEFAULTS: dict[str, Any] = {"inputs": None, "controllers": [], "references": {}, "coupling": "hold",
                             "solver": "riccati", "fast": None, "force_hook": None, "progress": None, "t0": 0.0,
                             "compiled": None}


def cut_signal_names(model: KinematicLoopModel) -> tuple[str, ...]:
    """``"<cut>.force_x"``, ``"<cut>.force_y"`` of every cut joint (force on the child point, global axes [N])."""
    return tuple(f"{cut.name}.force_{axis}" for cut in model.cuts for axis in "xy")


def cut_moment_signals(model: KinematicLoopModel, t: np.ndarray, q: np.ndarray, qdot: np.ndarray,
                       inputs: Sequence[Any] | None = None) -> dict[str, np.ndarray]:
    """``"<cut>.moment"`` [N m] of every cut with a law, a torque or a drive (:meth:`KinematicLoopModel.cut_moments`:
    the moment on the child side) at the stored rows, with each row's tree actuator ``inputs`` if given."""
    loaded = [k for k, cut in enumerate(model.cuts) if cut.has_moment or cut.driven]
    rows = [None] * len(t) if inputs is None else list(inputs)
    values = np.array([model.cut_moments(q[i], qdot[i], float(t[i]), rows[i]) for i in range(len(t))]
                      ).reshape(len(t), len(model.cuts))
    return {f"{model.cuts[k].name}.moment": values[:, k] for k in loaded}


def initial_state(model: KinematicLoopModel, x0: Any, v0: Any) -> tuple[np.ndarray, np.ndarray]:
    """Tree coordinates and rates from ``x0``, ``v0`` (arrays or ``{coordinate: value}``, others 0), checked
    against the cut joints (:func:`ctmm.loop_integration.check_consistent`: ``|Phi|``, ``|Phi'| <= 1e-8``)."""
    q0, v0 = coordinate_values(model.tree, "x0", x0), coordinate_values(model.tree, "v0", v0)
    check_consistent(model, q0, v0, "x0, v0")
    return q0, v0


def _history_result(model: KinematicLoopModel, run: KinematicLoopSimulation, outputs: Sequence[str],
                    info: dict) -> SimulationResult:
    ports = KinematicLoopPorts(model)
    signals, units = model_signals(model.tree, run.t, run.q, run.qdot, tree_outputs(ports, outputs))
    cut_signals, cut_units = loop_sensor_signals(ports, run.t, run.q, run.qdot, outputs)
    signals.update(cut_signals)
    units.update(cut_units)
    for k, cut in enumerate(model.cuts):
        for axis, column in (("x", 0), ("y", 1)):
            signals[f"{cut.name}.force_{axis}"] = run.cut_force[:, k, column]
            units[f"{cut.name}.force_{axis}"] = "N"
    signals.update(cut_moment_signals(model, run.t, run.q, run.qdot))
    units.update({name: "N m" for name in cut_moment_signals(model, run.t[:0], run.q[:0], run.qdot[:0])})
    signals["drift"], units["drift"] = run.drift, "m"
    signals["drift_rate"], units["drift_rate"] = run.drift_rate, "m/s"
    details = {"method": run.method, "wall_time_s": float(run.wall_time_s), "n_evaluations": int(run.n_evaluations),
               "baumgarte": model.baumgarte, "max_drift_m": float(np.max(run.drift))}
    details.update(info)
    return signal_result(SignalSystem(model, units), run.t, signals, run.method, details)


@contextlib.contextmanager
def _partial_as_result(model: KinematicLoopModel, outputs: Sequence[str], info: dict) -> Iterator[None]:
    """Turn the partial :class:`KinematicLoopSimulation` of a failed run into the :class:`SimulationResult` a whole run
    returns (the same signals, cut forces and drift included; ``info["failed"]``)."""
    try:
        yield
    except SimulationError as exc:
        if isinstance(exc.partial_result, KinematicLoopSimulation):
            exc.partial_result = _history_result(model, exc.partial_result, outputs, {**info, "failed": True})
        raise


def simulate_loops(model: KinematicLoopModel, t_final: float, dt: float | None, *, method: Any, x0: Any, v0: Any,
                   outputs: Sequence[str], rtol: float, atol: float, max_step: float | None, store_every: int,
                   divergence_bound: float | None, stability_check: str | None,
                   other_options: Mapping[str, Any] | None = None,
                   generated: Callable[..., KinematicLoopSimulation] | None = None) -> SimulationResult:
    """:func:`ctmm.simulate` of a kinematic loop model (module docstring).

    Parameters
    ----------
    model : KinematicLoopModel
    t_final, dt : float
        End time and step [s] (``dt``: the output grid of a ``solve_ivp`` method).
    method : str or Scheme
        ``"rk4"``, a ``solve_ivp`` method or a DT-TMM scheme.
    x0, v0 : mapping or array
        A consistent initial state of the tree coordinates (:meth:`KinematicLoopModel.consistent_state`);
        checked against the cut joints (``|Phi| <= 1e-8`` m, ``|Phi'| <= 1e-8`` m/s).
    outputs : sequence of str
        Sensor names of the tree (:mod:`ctmm.planar.ports`) and of the cut joints (:mod:`ctmm.planar.loop_ports`)
        to store.
    rtol, atol, max_step, store_every, divergence_bound, stability_check
        As for :func:`ctmm.simulate`; ``divergence_bound`` and ``stability_check`` apply to the DT-TMM schemes.
    other_options : mapping, optional
        The other options of :func:`ctmm.simulate` as given (``inputs``, ``controllers``, ``references``,
        ``coupling``, ``solver``, ``fast``, ``force_hook``, ``progress``, ``t0``, ``compiled``): each must be at
        its default (refused by name otherwise; inputs, controllers and loops run in :mod:`ctmm.kinematic_loop_time`),
        but ``compiled=True`` with ``method="rk4"`` and ``generated``.
    generated : callable, optional
        The generated RK4 with projection that ``compiled=True`` runs
        (:func:`ctmm.compiled_kinematic_loops.simulate_kinematic_loops_generated`, handed in by the caller: this
        subpackage does not import the generated kernels).

    Returns
    -------
    SimulationResult
        Coordinates, rates, outputs, cut forces [N], ``drift`` [m], ``drift_rate`` [m/s].
    """
    options = dict(other_options or {})
    compiled = validation.flag("compiled", options.pop("compiled", None), optional=True)
    if compiled and (method != "rk4" or generated is None):
        raise ModelError(f"compiled=True runs the generated RK4 with projection of a kinematic loop model "
                         f"{model.name!r} (method='rk4'), got method={method!r}; leave compiled at None")
    for name, value in options.items():
        default = _DEFAULTS[name]
        if value is not default and value != default:
            raise ModelError(f"{name}={value!r} is not available for a kinematic loop model {model.name!r} (no "
                             f"fast runs through cut joints; runs start at t = 0); "
                             f"leave {name} at {default!r}")
    if isinstance(outputs, (str, Mapping)) or not isinstance(outputs, (list, tuple)):
        raise ModelError(f"outputs must be a list or tuple of sensor names (str), got {outputs!r}")
    ports = KinematicLoopPorts(model)
    for name in outputs:
        ports.check_sensor(name, "output (sensor)")
    q0, v0 = initial_state(model, x0, v0)
    store_every = validation.integer("store_every", store_every, minimum=1)
    t_final = validation.positive("t_final", t_final)
    if isinstance(method, Scheme) or method in SCHEMES:
        for name, (value, default) in {"rtol": (rtol, 1e-8), "atol": (atol, 1e-10), "max_step": (max_step, None)
                                       }.items():
            if value != default:
                raise ModelError(f"{name}={value!r} applies to solve_ivp methods, not to the DT-TMM scheme {method!r}")
        if dt is None:
            raise ModelError(f"dt is required with the DT-TMM scheme {method!r} (a fixed step [s], > 0), got None")
        from .implicit_kinematic_loops import simulate_loop_scheme

        policy = "warn" if stability_check is None else validation.option("stability_check", stability_check,
                                                                           ("warn", "error", "ignore"))
        with _partial_as_result(model, outputs, {"dt": dt}):
            run, info = simulate_loop_scheme(model, q0, v0, t_final=t_final, dt=dt, scheme=as_scheme(method),
                                             store_every=store_every, divergence_bound=divergence_bound,
                                             stability_check=policy)
        return _history_result(model, run, outputs, info)
    for name, value in (("divergence_bound", divergence_bound), ("stability_check", stability_check)):
        if value is not None:
            raise ModelError(f"{name}={value!r} applies to the DT-TMM schemes on a kinematic loop model, not to "
                             f"method={method!r} (its drift is reported instead); leave {name} at None")
    if method == "rk4":
        for name, (value, default) in {"rtol": (rtol, 1e-8), "atol": (atol, 1e-10), "max_step": (max_step, None)
                                       }.items():
            if value != default:
                raise ModelError(f"{name}={value!r} applies to solve_ivp methods {SCIPY_METHODS}, not to 'rk4'")
        if dt is None:
            raise ModelError("dt is required with method='rk4' (a fixed step [s], > 0), got None")
        if compiled:
            with _partial_as_result(model, outputs, {"dt": dt, "projection": True, "compiled": True}):
                run = generated(model, q0, v0, t_final=t_final, dt=dt, store_every=store_every)
            return _history_result(model, run, outputs, {"dt": dt, "projection": True, "compiled": True})
        with _partial_as_result(model, outputs, {"dt": dt, "projection": True}):
            run = simulate_kinematic_loops(model, q0, v0, t_final=t_final, dt=dt, method="rk4",
                                           store_every=store_every)
        return _history_result(model, run, outputs, {"dt": dt, "projection": True})
    if method not in SCIPY_METHODS:
        raise ModelError(f"method must be 'rk4', a solve_ivp method {SCIPY_METHODS} or a DT-TMM scheme "
                         f"{tuple(sorted(SCHEMES))}, got {method!r}")
    if store_every != 1:
        raise ModelError(f"store_every={store_every!r} applies to fixed-step methods; with {method!r} give dt to "
                         "store the result on the grid k dt")
    grid = None
    if dt is not None:
        h = validation.positive("dt", dt)
        grid = output_grid(0.0, t_final, h)
    with _partial_as_result(model, outputs, {"dt": dt, "projection": False}):
        run = simulate_kinematic_loops(model, q0, v0, t_final=t_final, method=method, rtol=rtol, atol=atol,
                                       t_eval=grid, max_step=np.inf if max_step is None else
                                       validation.positive("max_step", max_step))
    return _history_result(model, run, outputs, {"dt": dt, "projection": False})


def _operating_q(model: KinematicLoopModel, operating_point: Any) -> tuple[np.ndarray, float]:
    """Tree coordinates of the operating point (at rest) and its time; ``None``: the static equilibrium
    reached by Newton (:meth:`KinematicLoopModel.equilibrium`) from the tree's hanging configuration
    assembled onto the cut joints (elastic coordinates held at zero while assembling)."""
    tree = model.tree
    n = tree.n_coordinates
    if operating_point is None:
        guess = np.asarray(hanging_configuration(tree), dtype=float)
        elastic = [tree.coordinates[k] for index in tree.modal_index for k in index]   # held straight
        try:
            guess, _ = model.consistent_state(guess, np.zeros(n), keep=elastic)
            return model.equilibrium(guess), 0.0
        except ModelError as exc:
            raise ModelError(f"no static equilibrium of {model.name!r} found from the hanging configuration ({exc}); "
                             "give operating_point=(q, qdot) (e.g. KinematicLoopModel.equilibrium(q_guess), rates 0)"
                             ) from None
    t = 0.0
    if isinstance(operating_point, OperatingPoint):
        q, qdot, t = operating_point.q, operating_point.qdot, operating_point.t
    elif isinstance(operating_point, Mapping) and "q" in operating_point:
        q, qdot, t = operating_point["q"], operating_point.get("qdot", np.zeros(n)), operating_point.get("t", 0.0)
    elif isinstance(operating_point, Mapping):
        q, qdot = coordinate_values(model.tree, "operating_point", operating_point), np.zeros(n)
    elif isinstance(operating_point, (tuple, list)) and len(operating_point) == 2:
        q, qdot = operating_point
    else:
        raise ModelError(f"operating_point must be None, (q, qdot), {{'q': ..., 'qdot': ..., 't': ...}} or a mapping "
                         f"of coordinate names, got {operating_point!r}")
    q, qdot = tree.state(q, qdot)
    if np.max(np.abs(qdot), initial=0.0) > 0.0:
        raise ModelError(f"operating_point of {model.name!r}: the rates must be zero (a kinematic loop is linearised "
                         f"about a resting state), got qdot={np.asarray(qdot).tolist()}")
    return np.array(q, dtype=float), validation.finite("operating_point t", t)


def linearize_loops(model: KinematicLoopModel, operating_point: Any = None, *, inputs: Any = None, outputs: Any = None,
                    allow_nonequilibrium: bool = False) -> LinearizedSystem:
    """:func:`ctmm.linearize` of a kinematic loop model: the tangent on the constraint manifold.

    Parameters
    ----------
    model : KinematicLoopModel
    operating_point : None, (q, qdot), mapping or OperatingPoint
        A resting state (rates zero), projected onto the cut joints; ``None``: the static equilibrium
        (:func:`_operating_q`).
    inputs : str or sequence of str, optional
        Actuators of the tree (:func:`ctmm.planar.ports.actuator_names`; default: all of them) and the cut torques
        ``"<cut>.torque"`` [N m] (:mod:`ctmm.planar.loop_ports`).
    outputs : str or sequence of str, optional
        Sensors of the tree and of the cut joints (``"<cut>.angle"``, ``".rate"``, ``".moment"``) and the cut forces
        ``"<cut>.force_x|y"`` [N] (default: the tree coordinates).
    allow_nonequilibrium : bool
        Accept a resting state that is not an equilibrium (the constant term is then dropped).

    Returns
    -------
    LinearizedSystem
        States ``z1..zf`` [rad] and ``z1_dot..zf_dot`` (``z = N^T (q - q0)``); no delays.
    """
    validation.flag("allow_nonequilibrium", allow_nonequilibrium)
    import control

    if not isinstance(model, KinematicLoopModel):          # a ControlledModel on a kinematic loop model
        return _linearize_controlled(model.plant, tuple(model.loops), operating_point, inputs=inputs,
                                     outputs=outputs, allow_nonequilibrium=allow_nonequilibrium)
    tree = model.tree
    ports = KinematicLoopPorts(model)
    model.require_static("linearize")
    q_rest, t = _operating_q(model, operating_point)
    input_names = list(actuator_names(tree)) if inputs is None else list(validation.names("input", inputs))
    output_names = list(tree.coordinates) if outputs is None else list(validation.names("output", outputs))
    for name in input_names:
        ports.check_actuator(name, "input (actuator)")
    forces = cut_signal_names(model)
    sensor_names = [name for name in output_names if name not in forces]
    sensors = ports.resolve([ports.check_sensor(name, "output (sensor)") for name in sensor_names])
    A, basis, q0, jacobian_error = model.resting_tangent(q_rest, t)
    n, f = tree.n_coordinates, basis.shape[1]
    rest = np.zeros(n)
    qdd0 = model.solve(q0, rest, t)[0]
    equilibrium = at_equilibrium(A, basis, qdd0)
    if not equilibrium and not allow_nonequilibrium:
        raise ModelError(f"linearize: the operating point of {model.name!r} is not an equilibrium (largest "
                         f"acceleration {np.max(np.abs(qdd0)):.3e}); give operating_point=None (the static "
                         "equilibrium) or allow_nonequilibrium=True")

    def output(q: np.ndarray, qdot: np.ndarray, lam: np.ndarray) -> np.ndarray:
        values = dict(zip(sensor_names, ports.values(sensors, q, qdot, t))) if sensor_names else {}
        values.update(zip(forces, lam.reshape(-1)))
        return np.array([values[name] for name in output_names], dtype=float)

    B, C, D = input_output_matrices(model, q0, basis, t, output,
                                    [ports.inputs({name: 1.0}) for name in input_names])
    states = [f"z{k + 1}" for k in range(f)] + [f"z{k + 1}_dot" for k in range(f)]
    if not input_names and len(output_names) == 1:
        raise ModelError(f"linearize: inputs={inputs!r} leaves {model.name!r} with no input and one output, a state "
                         "space python-control cannot hold; name an input or a second output")
    state_space = control.ss(A, B, C, D, inputs=[control_name(x) for x in input_names],
                             outputs=[control_name(x) for x in output_names], states=states,
                             name=control_name(model.name))
    point = OperatingPoint(q0, rest, t, tuple(tree.coordinates), equilibrium, jacobian_error)
    return LinearizedSystem(state_space, (), point)


def _linearize_controlled(model: KinematicLoopModel, loops: tuple, operating_point: Any, *, inputs: Any,
                          outputs: Any, allow_nonequilibrium: bool) -> LinearizedSystem:
    """:func:`linearize_loops` with feedback ``loops`` on the model's ports, every actuator a plant input, the cut
    forces available as outputs (:func:`ctmm.loop_model_feedback.linearize_with_feedback`)."""
    ports = KinematicLoopPorts(model)
    actuators = list(ports.actuators)
    defaults = list(actuator_names(model.tree))
    return linearize_with_feedback(
        lambda lin_in, lin_out: linearize_loops(model, operating_point, inputs=lin_in, outputs=lin_out,
                                                allow_nonequilibrium=allow_nonequilibrium),
        loops, ports, inputs=inputs, outputs=outputs, actuators=actuators, default_inputs=defaults,
        default_outputs=list(model.tree.coordinates), cut_outputs=cut_signal_names(model), name=model.name)


def natural_frequencies_loops(model: KinematicLoopModel, *, n_modes: int | None = None,
                              omega_max: float | None = None, operating_point: Any = None) -> np.ndarray:
    """:func:`ctmm.natural_frequencies` of a kinematic loop model: undamped frequencies [rad/s] about its
    static equilibrium (:meth:`KinematicLoopModel.natural_frequencies`), ascending; at most ``n_modes``,
    those up to ``omega_max`` [rad/s].  A controlled model (feedback loops) is refused: its closed-loop roots are
    the eigenvalues of :func:`linearize_loops` (delays beside it) or the stability tools'."""
    if not isinstance(model, KinematicLoopModel):
        raise ModelError(f"natural_frequencies and eigenvalue_count answer the open kinematic loop model, not "
                         f"{model!r:.80} with feedback loops: use ctmm.linearize (eigenvalues of the closed-loop A, "
                         "delays beside it) or ctmm.stability for the closed-loop roots, or pass model.plant")
    q0, t = _operating_q(model, operating_point)
    omega = model.natural_frequencies(q0, t)
    if omega_max is not None:
        omega = omega[omega <= validation.positive("omega_max", omega_max)]
    if n_modes is not None:
        omega = omega[:validation.integer("n_modes", n_modes, minimum=1)]
    return omega


def mode_shapes_loops(model: KinematicLoopModel, *, n_modes: int | None = None, omega_max: float | None = None,
                      operating_point: Any = None) -> ModalResult:
    """:func:`ctmm.mode_shapes` of a kinematic loop model: the undamped modes about its static equilibrium (or the
    resting ``operating_point``, refused unless an equilibrium) on the constraint manifold, in the tree coordinates.

    ``shapes[k, i, 0]`` is tree coordinate ``i`` (``point_names``: ``model.tree.coordinates``) in mode ``k``: the
    independent-coordinate mode mapped back by the null-space basis, ``N phi`` (:func:`ctmm.loop_manifold.undamped_modes`;
    it satisfies the cut joints to first order), normalised to unit largest entry.  Exactly one of ``n_modes`` and
    ``omega_max`` [rad/s] selects the modes, as for the other models; the frequencies are those of
    :func:`natural_frequencies_loops`.  A controlled model (feedback loops) is refused as there."""
    if not isinstance(model, KinematicLoopModel):
        raise ModelError(f"mode_shapes answers the open kinematic loop model, not {model!r:.80} with feedback loops: "
                         "use ctmm.linearize (eigenvectors of the closed-loop A) or pass model.plant")
    validation.one_mode_limit(n_modes, omega_max)
    q_rest, t = _operating_q(model, operating_point)
    A, basis, q0, error = model.resting_tangent(q_rest, t)
    require_equilibrium(model, A, basis, q0, t, "KinematicLoopModel.equilibrium")
    omega, shapes = undamped_modes(model, A, basis, error)
    keep = validation.selected_modes(omega, n_modes, omega_max,
                                     f"kinematic loop model {model.name!r} (one per degree of freedom)")
    return ModalResult(omega[keep], shapes[:, keep].T[:, :, None], ("amplitude",), tuple(model.tree.coordinates))


def eigenvalue_count_loops(model: KinematicLoopModel, omega: Any, *, operating_point: Any = None) -> np.ndarray:
    """:func:`ctmm.eigenvalue_count` of a kinematic loop model: natural frequencies strictly below each
    ``omega`` [rad/s]."""
    frequencies = natural_frequencies_loops(model, operating_point=operating_point)
    omega = np.asarray(validation.frequencies("omega", omega), dtype=float)
    return np.sum(frequencies[None, :] < omega.reshape(-1, 1), axis=1).reshape(omega.shape)


def frequency_response_loops(model: Any, omega: Any, *, input: Any, output: Any,  # noqa: A002
                             operating_point: Any = None) -> FrequencyResponse:
    """:func:`ctmm.frequency_response` of a kinematic loop model: ``C (s I - A)^-1 B + D`` of
    :func:`linearize_loops` at ``s = i omega`` [rad/s]; inputs: tree actuators, outputs: tree sensors and
    cut forces.  With feedback loops (a ``ControlledModel`` on the model) the real-time loops are closed in the
    linearisation and the delayed ones exactly by ``e^{-s tau}`` at every frequency
    (:func:`ctmm.controlled_linearization.delayed_loop_response`); inputs may be ``"<loop>.reference"``, outputs
    ``"<loop>.y"``, ``"<loop>.u"``."""
    started = time.perf_counter()
    inputs, outputs = list(validation.names("input", input)), list(validation.names("output", output))
    omega = validation.frequencies("omega", omega)
    plant = model if isinstance(model, KinematicLoopModel) else model.plant
    loops = () if plant is model else tuple(model.loops)
    response, lin = delayed_loop_response(          # refuses a frequency at or next to a pole, naming the model
        lambda lin_in, lin_out: linearize_loops(model, operating_point, inputs=lin_in, outputs=lin_out),
        loops, 1j * omega, inputs, outputs, plant.name)
    ports = KinematicLoopPorts(plant)
    units = {name: ports.actuator_unit(name) for name in inputs if name in ports.actuators}
    units.update({name: "N" if name in cut_signal_names(plant) else ports.sensor_unit(name) for name in outputs
                  if name in ports.sensors or name in cut_signal_names(plant)})
    for loop in loops:
        for name, parts in ((f"{loop.name}.y", loop.terms), (f"{loop.name}.reference", loop.terms),
                            (f"{loop.name}.u", loop.actuator_terms)):
            plain = [w for _, w in parts] == [1.0]
            unit = ports.actuator_unit if parts is loop.actuator_terms else ports.sensor_unit
            if name in inputs or name in outputs:
                units[name] = unit(parts[0][0]) if plain else ""
    info = {"method": "linearisation on the constraint manifold (KinematicLoopModel.linearize)"
                      + (", delayed loops exact" if loops else ""),
            "wall_time_s": time.perf_counter() - started, "n_frequencies": int(omega.size),
            "operating_point_q": lin.operating_point.q.tolist(), "jacobian_error": lin.operating_point.jacobian_error}
    return FrequencyResponse(omega, response, tuple(inputs), tuple(outputs), plant.name, info=info, units=units)
