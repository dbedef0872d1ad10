"""Exact derivatives of planar RK4 simulations: forward sensitivities of the generated step.

For a planar model (rigid bodies, hinges; compilable, :func:`ctmm.compiled_parameters.compile_refusal`)
without open-loop actuator inputs, alone or closed by loops (a ``ControlledModel``), the RK4 step
``y_{k+1} = Phi(y_k, p, t_k)`` of ``y = [q, qdot]`` (with loops ``[q, qdot, z, ring]``: controller
states and the delayed loops' samples, :class:`ctmm.compiled_loops.ClosedLoops`) is stated on casadi
symbols with the model's numbers ``p`` as an input (the expression the generated kernels compile,
:func:`ctmm.compiled_scene.symbolic_accelerations_with_inputs`). The forward sensitivities
``S_k = dy_k/dp`` follow the fold exactly:

    S_{k+1} = dPhi/dy (y_k) S_k + dPhi/dp (y_k),     S_0 = 0,

with both Jacobians by casadi's algorithmic differentiation of the step (no differences). The result
is the derivative of the RK4 solution ``ctmm.simulate(model, ..., method="rk4")`` computes, to
round-off (not of the exact ODE solution; the two differ by the RK4 error, O(dt^4)).

Parameters: ``"<body>.mass"`` [kg], ``"<body>.inertia"`` (about the centre of mass) [kg m^2],
``"<hinge>.stiffness"`` [N m/rad], ``"<hinge>.damping"`` [N m s/rad].  A number that is zero in
the model is a constant of the generated expression and is refused (give it a nonzero value).
Loop numbers -- ``"<loop>.gain"``, the sensor weights ``"<loop>.<sensor>"`` and an LTI controller's
realisation entries -- are entries (directions) of the step's parameter column
(:mod:`ctmm.sensitivity_loop_numbers`); delays are refused (a whole number of steps of the ring).
Spatial models: :mod:`ctmm.sensitivity_time_spatial`.
"""
from __future__ import annotations

from dataclasses import dataclass
from typing import Any, Mapping, Sequence

import numpy as np

from . import validation
from .errors import ModelError, unknown_name

__all__ = ["TimeSensitivity", "chain_forced", "chain_loads", "chain_prestressed", "chain_simulation_sensitivity",
           "forward_sensitivities", "parameter_index", "planar_simulation_sensitivity", "simulation_start"]


@dataclass(frozen=True)
class TimeSensitivity:
    """Outputs of an RK4 run and their parameter derivatives.

    Attributes
    ----------
    time : ndarray, shape (n_t,)
        [s], from 0 (the initial state included).
    outputs : tuple of str
        Coordinate names (``"upper.theta"``) and rates (``"upper.theta_dot"``).
    parameters : tuple of str
    values : ndarray, shape (n_outputs, n_t)
        [rad, m, rad/s, m/s].
    derivative : ndarray, shape (n_parameters, n_outputs, n_t)
        ``d value / d parameter``.
    """

    time: np.ndarray
    outputs: tuple[str, ...]
    parameters: tuple[str, ...]
    values: np.ndarray
    derivative: np.ndarray

    @property
    def final(self) -> np.ndarray:
        """Values at ``t_final``, shape (n_outputs,)."""
        return self.values[:, -1]

    @property
    def final_derivative(self) -> np.ndarray:
        """Derivatives at ``t_final``, shape (n_parameters, n_outputs)."""
        return self.derivative[:, :, -1]


def parameter_index(model: Any, name: str, values: np.ndarray) -> int:
    """Index of a named number (module docstring) in ``values``, the model's
    :func:`ctmm.compiled_parameters.parameter_vector`; a zero number is refused."""
    nb = model.n_bodies
    ends = sum(len(points) for points in model.ends)
    stiffness = 4 * nb + 2 * ends + 2
    head, _, tail = str(name).partition(".")
    if tail in ("mass", "inertia"):
        if head not in model.body_names:
            raise unknown_name(f"body (parameter {name!r})", head, model.body_names)
        index = model.body_names.index(head) + (0 if tail == "mass" else nb)
    elif tail in ("stiffness", "damping"):
        if head not in model.joint_names:
            raise unknown_name(f"hinge (parameter {name!r})", head, model.joint_names)
        index = stiffness + model.joint_names.index(head) + (0 if tail == "stiffness" else nb)
    else:
        raise ModelError(f"planar sensitivity: parameter {name!r} is not supported; allowed: '<body>.mass', "
                         "'<body>.inertia', '<hinge>.stiffness', '<hinge>.damping'")
    if values[index] == 0.0:
        raise ModelError(f"planar sensitivity: parameter {name!r} is 0 in the model, a constant of the generated "
                         "expression; give it a nonzero value to differentiate with respect to it")
    return index


def forward_sensitivities(step: Any, first: np.ndarray, p0: np.ndarray, directions: np.ndarray, n_steps: int,
                          h: float, what: str) -> tuple[np.ndarray, np.ndarray]:
    """States ``(n_steps + 1, size)`` and their derivatives ``(n_steps + 1, size, m)`` along the ``m`` columns of
    ``directions`` (``(p0.size, m)``) of the generated ``step(y, u, h, p, t0, k)`` (no held inputs) from
    ``first`` with ``p = p0``: ``S_{k+1} = dPhi/dy S_k + dPhi/dp directions`` by casadi's AD.

    Raises
    ------
    ModelError
        A non-finite state (the run diverged).
    """
    import casadi as ca

    size, m = first.size, directions.shape[1]
    n_inputs = step.size1_in(1)
    Y, S, d, k = ca.MX.sym("y", size), ca.MX.sym("S", size, m), ca.MX.sym("d", m), ca.MX.sym("k")
    y_next = step(Y, ca.DM.zeros(n_inputs), h, ca.DM(p0) + ca.DM(directions) @ d, 0.0, k)
    S_next = ca.jacobian(y_next, Y) @ S + ca.jacobian(y_next, d)
    forward = ca.Function("forward", [Y, S, d, k], [y_next, S_next]).expand()
    states = np.empty((n_steps + 1, size))
    tangents = np.empty((n_steps + 1, size, m))
    states[0] = first
    tangents[0] = 0.0
    zero = np.zeros(m)
    for index in range(n_steps):
        y_new, S_new = forward(states[index], tangents[index], zero, float(index))
        states[index + 1] = np.asarray(y_new).reshape(-1)
        tangents[index + 1] = np.asarray(S_new).reshape(size, m)
        if not np.all(np.isfinite(states[index + 1])):
            raise ModelError(f"{what}: the run diverged at t = {(index + 1) * h:g} s (non-finite state); reduce dt")
    return states, tangents


def planar_simulation_sensitivity(model: Any, parameters: str | Sequence[str], *, t_final: float, dt: float,
                                  q0: Any, qdot0: Any = None,
                                  outputs: str | Sequence[str] | None = None) -> TimeSensitivity:
    """RK4 run of a planar model with the exact derivatives of its outputs (module docstring).

    Parameters
    ----------
    model : PlanarModel or ControlledModel (planar plant)
        Compilable; no open-loop actuator inputs; loops closed in the step (references 0).
    parameters : str or sequence of str
    t_final, dt : float
        [s]; ``t_final / dt`` whole (as :func:`ctmm.simulate`, ``method="rk4"``).
    q0 : array_like
        Initial coordinates (:attr:`PlanarModel.coordinates` order) [rad, m].
    qdot0 : array_like, optional
        Initial rates (default: at rest).
    outputs : str or sequence of str, optional
        Coordinate names and ``"<coordinate>_dot"``; default every coordinate.

    Returns
    -------
    TimeSensitivity

    Raises
    ------
    ModelError
        Not a planar model, not compilable, unknown or zero parameters, unknown outputs.
    """
    import casadi as ca

    from .compiled_loops import ClosedLoops
    from .compiled_parameters import compile_refusal, compiled_actuators, parameter_vector
    from .compiled_scene import symbolic_accelerations_with_inputs
    from .control.controlled_model import ControlledModel
    from .generated_loop import rk4_step_function
    from .planar.integrate import initial_coordinates, step_total
    from .planar.model import PlanarModel
    from .sensitivity_loop_numbers import is_loop_number, loop_directions, split_loops

    controlled = model if isinstance(model, ControlledModel) else None
    if controlled is not None:
        model = controlled.plant
    if not isinstance(model, PlanarModel):
        raise ModelError(f"planar_simulation_sensitivity: model must be a ctmm.planar.PlanarModel or a "
                         f"ControlledModel on one, got {type(model).__name__}")
    reason = compile_refusal(model)     # moving drives: not here (the generated RK4 and schemes take them)
    if reason:
        raise ModelError(f"planar_simulation_sensitivity: {reason}")
    names = validation.names("parameters", parameters)
    original, loop_list = controlled, (controlled.loops if controlled else ())
    if controlled is not None:
        controlled = split_loops(controlled, names, "planar_simulation_sensitivity")
    p0 = parameter_vector(model)
    indices = {k: parameter_index(model, name, p0) for k, name in enumerate(names)
               if not is_loop_number(loop_list, name)}
    n = model.n_coordinates
    labels = list(model.coordinates) + [f"{c}_dot" for c in model.coordinates]
    wanted = list(model.coordinates) if outputs is None else list(validation.names("outputs", outputs))
    for name in wanted:
        if name not in labels:
            raise unknown_name("output (coordinate or '<coordinate>_dot')", name, labels)
    rows = [labels.index(name) for name in wanted]
    q, v = initial_coordinates(model, q0, np.zeros(n) if qdot0 is None else qdot0)
    n_steps = step_total(t_final, dt)
    h = t_final / n_steps

    actuators = compiled_actuators(model)
    loops = None if controlled is None else ClosedLoops(controlled, actuators, h, numbers="inputs")
    acceleration = symbolic_accelerations_with_inputs(model, actuators,
                                                      [unit for _, unit in loops.channels] if loops else ())
    if loops is None:
        y_sx, u_sx, p_sx, t_sx = ca.SX.sym("y", 2 * n), ca.SX.sym("u", len(actuators)), ca.SX.sym("p", p0.size), \
            ca.SX.sym("t")
        rate = ca.Function("rate", [y_sx, u_sx, p_sx, t_sx],
                           [ca.vertcat(y_sx[n:], acceleration(y_sx[:n], y_sx[n:], u_sx, p_sx, t_sx))])
        step = rk4_step_function(rate)
        size, first = 2 * n, np.concatenate([q, v])
    else:           # the loops closed at every stage, delayed ones from the ring in the state (as generated)
        step = loops.step(acceleration, len(actuators), p0.size)
        size, first = loops.state_size, loops.initial_state(q, v)
    directions = np.zeros((p0.size, len(names)))
    for column, index in indices.items():
        directions[index, column] = 1.0
    if loops is not None:
        size_p = p0.size + loops.parameter_values.size
        directions = np.vstack([directions, np.zeros((loops.parameter_values.size, len(names)))]) + loop_directions(
            original, controlled, loops.parameter_layout, names, p0.size, size_p)
        p0 = np.concatenate([p0, loops.parameter_values])
    states, tangents = forward_sensitivities(step, first, p0, directions, n_steps, h, "planar_simulation_sensitivity")
    time = h * np.arange(n_steps + 1)
    values = states[:, rows].T
    derivative = np.transpose(tangents[:, rows, :], (2, 1, 0))
    return TimeSensitivity(time, tuple(wanted), tuple(names), values, derivative)


def chain_loads(chain: Any) -> list[str]:
    """Names of the elements of a plain :class:`~ctmm.system.Chain` that carry a load: a time signal, or a
    constant other than 0 (:class:`ctmm.chain_ode.ChainDynamics` ``loads``)."""
    from .chain_ode import ChainDynamics
    from .signals import Constant

    return [element.name for _, _, signal, element in ChainDynamics(chain).loads
            if not (isinstance(signal, Constant) and signal.value == 0.0)]


def chain_prestressed(chain: Any) -> bool:
    """Whether the rest positions (every connector at its free length) of a plain :class:`~ctmm.system.Chain` are not
    its equilibrium: free lengths that do not fit between held ends leave forces [N] at rest (the accelerations of the
    unloaded chain there are not zero).  False for a chain whose affine form is not defined (massless points, a
    prescribed motion: :func:`chain_simulation_sensitivity` refuses those by name)."""
    from .compiled_chain import affine_form
    from .control.chain_plant import ChainPlant

    try:
        rest = affine_form(ChainPlant(chain).dynamics).a0
    except ModelError:
        return False
    return bool(np.any(rest != 0.0))


def simulation_start(system: Any, q0: Any, qdot0: Any, x0: Any, v0: Any, planar: bool) -> tuple[Any, Any]:
    """``(q0, qdot0)`` of :func:`ctmm.sensitivity.simulation_sensitivity`: a planar run starts from the arrays
    ``q0``, ``qdot0`` or from ``x0``, ``v0`` as :func:`ctmm.simulate` takes them (``{coordinate: value}`` or
    arrays, 0 where left out); chains and spatial models start from ``x0``, ``v0`` only (``(None, None)``).

    Raises
    ------
    ModelError
        ``q0`` or ``qdot0`` for a chain or a spatial model, or both forms for a planar model (one would be
        dropped).
    """
    given = {label: value for label, value in (("q0", q0), ("qdot0", qdot0)) if value is not None}
    if given and not planar:
        raise ModelError(f"simulation_sensitivity: q0 and qdot0 are the coordinate arrays of a planar model; a "
                         f"{type(system).__name__} starts from x0 and v0 (as ctmm.simulate takes them), got "
                         + ", ".join(f"{label}={value!r:.60}" for label, value in given.items()))
    if given and (x0 is not None or v0 is not None):
        raise ModelError(f"simulation_sensitivity: give the start as x0, v0 (as ctmm.simulate) or as the arrays q0, "
                         f"qdot0, not both; got {' and '.join(given)} with x0={x0!r:.60}, v0={v0!r:.60}")
    if given or not planar:
        return q0, qdot0
    from .planar.integrate import coordinate_values

    plant = getattr(system, "plant", system)
    return coordinate_values(plant, "x0", x0), coordinate_values(plant, "v0", v0)


def chain_forced(chain: Any) -> bool:
    """Whether a plain :class:`~ctmm.system.Chain` is not free about its rest positions: it carries loads
    (:func:`chain_loads`) or is prestressed (:func:`chain_prestressed`)."""
    return bool(chain_loads(chain)) or chain_prestressed(chain)


def chain_simulation_sensitivity(chain: Any, parameters: str | Sequence[str], *, t_final: float, dt: float,
                                 x0: Mapping[str, float] | None = None, v0: Mapping[str, float] | None = None,
                                 outputs: str | Sequence[str] | None = None) -> TimeSensitivity:
    """RK4 run of a lumped 1-D chain (free response) with the exact derivatives of its outputs.

    The explicit form of a chain whose every free point has a mass, ``M u'' + C u' + K u = 0`` over
    the displacements ``u`` from the rest positions (:func:`ctmm.interop.assemble_matrices`), is the
    linear rate ``y' = E(p) y``, ``y = [u, u']``; RK4 is stepped with its stages differentiated
    exactly (``dk_i = dE y_i + E dy_i``, ``dE`` from ``dM``, ``dC``, ``dK`` of
    :class:`ctmm.sensitivity_model.LoopCharacteristicMatrix` and ``d(M^-1) = -M^-1 dM M^-1``): the
    derivative of the RK4 solution ``ctmm.simulate(chain, ..., method="rk4")`` computes (the same
    RK4 of the same ODE; its rates come from the sweep, equal to round-off).

    Parameters
    ----------
    chain : Chain
        Lumped elements; every point that is not held has a mass (massless points are condensed
        in the explicit form: refused here); no inputs, no loads (:func:`chain_loads`) and rest positions that are
        its equilibrium (:func:`chain_prestressed`) (both refused here: :func:`ctmm.sensitivity.simulation_sensitivity`
        differentiates such a chain as a ``ControlledChain`` without loops, :mod:`ctmm.sensitivity_time_chain`).
    parameters : str or sequence of str
        ``"<point>.mass"``, ``"<point>.damping"``, ``"<point>.stiffness"``, ``"<connector>.stiffness"``,
        ``"<connector>.damping"``.
    t_final, dt : float
        [s]; ``t_final / dt`` whole.
    x0, v0 : mapping, optional
        Initial absolute positions [m] and velocities [m/s] by point element name (as :func:`ctmm.simulate`).
    outputs : str or sequence of str, optional
        ``"<point>.x"`` (absolute position [m]) and ``"<point>.v"`` [m/s]; default every mass's ``.x``.

    Returns
    -------
    TimeSensitivity
    """
    from .chain_start import point_of_element, rest_positions
    from .planar.integrate import step_total
    from .sensitivity_model import LoopCharacteristicMatrix

    from .system import Chain

    if not isinstance(chain, Chain):
        raise ModelError("chain_simulation_sensitivity: a plain ctmm.Chain is differentiated in time; controlled "
                         f"chains: ctmm.sensitivity_time_chain (loop numbers); got {type(chain).__name__}")
    loaded = chain_loads(chain)
    if loaded:
        raise ModelError(f"chain_simulation_sensitivity: chain {chain.name!r} carries loads on {loaded}; the "
                         "explicit form here is the free response about the rest positions; "
                         "ctmm.sensitivity.simulation_sensitivity differentiates a loaded chain as a ControlledChain "
                         "without loops (ctmm.sensitivity_time_chain)")
    model = LoopCharacteristicMatrix(chain, validation.names("parameters", parameters))
    n = model.n
    if np.any(np.diag(model.M) <= 0.0):
        raise ModelError(f"chain_simulation_sensitivity: chain {chain.name!r} has massless free points (condensed in "
                         "its explicit form); time histories are differentiated for chains whose every free point "
                         "has a mass")
    if chain_prestressed(chain):
        raise ModelError(f"chain_simulation_sensitivity: the rest positions of chain {chain.name!r} (its connectors at "
                         "their free lengths) are not its equilibrium (the free lengths do not fit between its held "
                         "ends); the explicit form here is the free response about them; "
                         "ctmm.sensitivity.simulation_sensitivity differentiates it as a ControlledChain without loops "
                         "(ctmm.sensitivity_time_chain)")
    rest = rest_positions(chain)
    masses = [e.name for e in chain.body if e.is_point and getattr(e, "mass", 0.0) > 0.0]
    wanted = [f"{name}.x" for name in masses] if outputs is None else list(validation.names("outputs", outputs))
    rows = np.array([np.concatenate([model.output_row(name, 1.0).real, np.zeros(n)]) if name.endswith(".x") else
                     np.concatenate([np.zeros(n), model.output_row(name[:-2] + ".x", 1.0).real])
                     if name.endswith(".v") else _refuse_output(name) for name in wanted])
    offsets = np.array([rest[point_of_element(chain, name[:-2])] if name.endswith(".x") else 0.0 for name in wanted])
    y = np.zeros(2 * n)
    for label, values, half in ("x0", x0, 0), ("v0", v0, n):
        for name, value in validation.number_mapping(label, values).items():
            if name not in masses:
                raise unknown_name(f"{label} entry (a mass element)", name, masses)
            row = model.output_row(f"{name}.x", 1.0).real
            base = rest[point_of_element(chain, name)] if half == 0 else 0.0
            y[half:half + n] += row * (value - base)
    Minv = np.linalg.inv(model.M)
    E = np.block([[np.zeros((n, n)), np.eye(n)], [-Minv @ model.K, -Minv @ model.C]])
    dE = []
    for p in model.parameters:
        dM, dC, dK = (p.pattern if p.kind == kind else np.zeros((n, n)) for kind in ("mass", "damping", "stiffness"))
        dE.append(np.block([[np.zeros((n, n)), np.zeros((n, n))],
                            [Minv @ (dM @ Minv @ model.K - dK), Minv @ (dM @ Minv @ model.C - dC)]]))
    n_steps = step_total(t_final, dt)
    h = t_final / n_steps
    m = len(dE)
    S = np.zeros((m, 2 * n))
    values = np.empty((len(wanted), n_steps + 1))
    derivative = np.empty((m, len(wanted), n_steps + 1))
    for k in range(n_steps + 1):
        values[:, k] = rows @ y + offsets
        derivative[:, :, k] = S @ rows.T
        if k == n_steps:
            break
        stages, tangents = [], []
        for c in (0.0, 0.5, 0.5, 1.0):
            ys = y + c * h * stages[-1] if stages else y
            Ss = S + c * h * tangents[-1] if tangents else S
            stages.append(E @ ys)
            tangents.append(np.array([dE[i] @ ys for i in range(m)]).reshape(m, 2 * n) + Ss @ E.T)
        y = y + h / 6.0 * (stages[0] + 2 * stages[1] + 2 * stages[2] + stages[3])
        S = S + h / 6.0 * (tangents[0] + 2 * tangents[1] + 2 * tangents[2] + tangents[3])
    return TimeSensitivity(h * np.arange(n_steps + 1), tuple(wanted), tuple(p.name for p in model.parameters),
                           values, derivative)


def _refuse_output(name: str) -> np.ndarray:
    raise ModelError(f"chain_simulation_sensitivity: output {name!r} is not supported; allowed: '<point>.x', "
                     "'<point>.v'")
