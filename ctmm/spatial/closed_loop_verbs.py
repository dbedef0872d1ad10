"""The library's frequency verbs on spatial kinematic loop models (:class:`SpatialKinematicLoopModel`).

``ctmm.linearize``, ``ctmm.natural_frequencies``, ``ctmm.mode_shapes``, ``ctmm.eigenvalue_count`` and
``ctmm.frequency_response`` call
the tangent on the constraint manifold about an equilibrium (:mod:`ctmm.spatial.closed_loop_linear`); the time verb
is :func:`ctmm.spatial_loop_time.simulate_spatial_loop_system`.  Inputs are the model's actuator ports
(:class:`~ctmm.spatial.closed_loop_ports.SpatialLoopPorts`: the tree's joint torques, body forces and moments, the
revolute and prismatic cuts' ``"<cut>.torque"`` / ``"<cut>.force"``), outputs its sensors (the cuts' coordinates
and rates among them) and the cut forces ``"<cut>.force_x|y|z"`` [N] (on the child, world axes).  ``docs/closed_loops.md`` section 8.
"""
from __future__ import annotations

import time
from typing import Any, Mapping

import numpy as np

from .. import validation
from ..controlled_linearization import delayed_loop_response
from ..errors import ModelError
from ..linearized import LinearizedSystem, OperatingPoint, control_name
from ..results import FrequencyResponse, ModalResult
from ..loop_manifold import input_output_matrices, undamped_modes
from ..loop_model_feedback import linearize_with_feedback
from .closed_loop_linear import tangent, tangent_error
from .closed_loops import SpatialKinematicLoopModel
from .closed_loop_ports import SpatialLoopPorts

__all__ = ["operating_configuration", "linearize_spatial_loops", "natural_frequencies_spatial_loops",
           "mode_shapes_spatial_loops", "eigenvalue_count_spatial_loops", "frequency_response_spatial_loops",
           "cut_force_names"]



def cut_force_names(model: SpatialKinematicLoopModel) -> tuple[str, ...]:
    """``"<cut>.force_x|y|z"`` of every cut joint (force on its child, world axes [N])."""
    return tuple(f"{cut.name}.force_{axis}" for cut in model.cuts for axis in "xyz")


def _plain(model: Any, verb: str) -> SpatialKinematicLoopModel:
    if not isinstance(model, SpatialKinematicLoopModel):
        raise ModelError(f"{verb} of a spatial kinematic loop model with feedback loops is not available: use "
                         f"ctmm.linearize (the closed-loop state space, delayed loops beside it) or ctmm.simulate, or "
                         f"pass the open SpatialKinematicLoopModel (model.plant); got {model!r:.80}")
    return model


def operating_configuration(model: SpatialKinematicLoopModel, operating_point: Any) -> tuple[np.ndarray, float]:
    """The tree coordinates ``q`` [rad, m, quaternions] and time of an operating point at rest: an array ``q``, a
    mapping ``{coordinate: value}``, ``(q, v)`` with ``v = 0``, ``{"q": ..., "t": ...}`` or an
    :class:`~ctmm.linearized.OperatingPoint`.  ``None`` is refused: give an equilibrium
    (:func:`ctmm.spatial.closed_loop_linear.equilibrium`)."""
    if operating_point is None:
        raise ModelError(f"operating_point=None: the spatial kinematic loop model {model.name!r} has no default "
                         "configuration on its cut joints; give operating_point=q at an equilibrium (e.g. "
                         "ctmm.spatial.closed_loop_linear.equilibrium(model, q_guess))")
    t, v = 0.0, None
    if isinstance(operating_point, OperatingPoint):
        q, v, t = operating_point.q, operating_point.qdot, operating_point.t
    elif isinstance(operating_point, Mapping) and "q" in operating_point:
        q, v, t = operating_point["q"], operating_point.get("v"), operating_point.get("t", 0.0)
    elif isinstance(operating_point, tuple) and len(operating_point) == 2:
        q, v = operating_point
    else:
        q = operating_point
    q, v = model.state(q, v)
    if np.max(np.abs(v), initial=0.0) > 0.0:
        raise ModelError(f"operating_point of {model.name!r}: the velocities must be zero (a kinematic loop is "
                         f"linearised about a resting equilibrium), got v={v.tolist()}")
    return q, validation.finite("operating_point t", t)


def linearize_spatial_loops(model: Any, operating_point: Any = None, *, inputs: Any = None, outputs: Any = None,
                            allow_nonequilibrium: bool = False) -> LinearizedSystem:
    """:func:`ctmm.linearize` of a spatial kinematic loop model about an equilibrium.

    Parameters
    ----------
    model : SpatialKinematicLoopModel
    operating_point : array, mapping, (q, v) or OperatingPoint
        An equilibrium at rest (:func:`operating_configuration`), projected onto the cut joints.
    inputs : str or sequence of str, optional
        Actuators of the tree's ports (default: the joint actuators ``model.tree.inputs`` of one component) and the
        loads along revolute and prismatic cuts ``"<cut>.torque"`` [N m] / ``"<cut>.force"`` [N]
        (:attr:`SpatialKinematicLoopModel.actuation_names`).
    outputs : str or sequence of str, optional
        Sensors of the model's ports (the tree's; ``"<cut>.angle"`` / ``".position"``, ``".rate"`` of revolute and
        prismatic cuts) and the cut forces ``"<cut>.force_x|y|z"`` [N] (default: the cut forces).
    allow_nonequilibrium : bool
        Must be False: the chart of :mod:`ctmm.spatial.closed_loop_linear` is exact about equilibria only.

    Returns
    -------
    LinearizedSystem
        States ``z1..zf``, ``z1_dot..zf_dot`` (independent coordinates in the tree's velocity space); ``B`` and the
        cut forces' ``D`` exact (the sweep is affine in the inputs), ``C`` by central differences; no delays.
    """
    import control

    if not isinstance(model, SpatialKinematicLoopModel) and isinstance(getattr(model, "plant", None),
                                                                        SpatialKinematicLoopModel):
        return _linearize_controlled(model.plant, tuple(model.loops), operating_point, inputs=inputs,
                                     outputs=outputs, allow_nonequilibrium=allow_nonequilibrium)
    model = _plain(model, "linearize")
    if validation.flag("allow_nonequilibrium", allow_nonequilibrium):
        raise ModelError(f"allow_nonequilibrium=True is not available for the spatial kinematic loop model "
                         f"{model.name!r}: its tangent is taken about an equilibrium only; leave it False")
    tree = model.tree
    ports = SpatialLoopPorts(model)
    q_rest, t = operating_configuration(model, operating_point)
    default_inputs = [name for joint in tree.joints for name in joint.inputs if joint.velocity_count == 1]
    input_names = default_inputs if inputs is None else list(validation.names("input", inputs))
    forces = cut_force_names(model)
    output_names = list(forces) if outputs is None else list(validation.names("output", outputs))
    for name in input_names:
        ports.check_actuator(name, "input (actuator)")
    sensor_names = [name for name in output_names if name not in forces]
    sensors = ports.resolve([ports.check_sensor(name, "output (sensor)") for name in sensor_names])
    A, basis, q0 = tangent(model, q_rest, t)
    jacobian_error = tangent_error(model, q_rest, t)
    f = basis.shape[1]
    rest = np.zeros(tree.n_velocities)

    def output(q: np.ndarray, v: np.ndarray, lam: np.ndarray) -> np.ndarray:
        values = dict(zip(sensor_names, ports.values(sensors, q, v, t))) if sensor_names else {}
        loads = model.cut_loads(q, lam, t)
        values.update(zip(forces, np.concatenate([force for force, _ in loads])))
        return np.array([values[name] for name in output_names], dtype=float)

    B, C, D = input_output_matrices(model, q0, basis, t, output,
                                    [model.actuation_inputs(name, q0, t) if name in model.actuation_names else
                                     ports.inputs({name: 1.0}) for name in input_names])
    if not input_names and len(output_names) == 1:
        raise ModelError(f"linearize: inputs={inputs!r} leaves {model.name!r} with no input and one output, a state "
                         "space python-control cannot hold; name an input or a second output")
    states = [f"z{k + 1}" for k in range(f)] + [f"z{k + 1}_dot" for k in range(f)]
    state_space = control.ss(A, B, C, D, inputs=[control_name(x) for x in input_names],
                             outputs=[control_name(x) for x in output_names], states=states,
                             name=control_name(model.name))
    return LinearizedSystem(state_space, (), OperatingPoint(q0, rest, t, tuple(tree.coordinates), True, jacobian_error))


def _linearize_controlled(model: SpatialKinematicLoopModel, loops: tuple, operating_point: Any, *, inputs: Any,
                          outputs: Any, allow_nonequilibrium: bool) -> LinearizedSystem:
    """:func:`linearize_spatial_loops` with feedback ``loops`` on the tree's ports: the plant's tangent about the
    equilibrium with the default, given and loop actuators as inputs, the cut forces ``"<cut>.force_x|y|z"`` [N]
    available as outputs (:func:`ctmm.loop_model_feedback.linearize_with_feedback`)."""
    ports = SpatialLoopPorts(model)
    default_inputs = [name for joint in model.tree.joints for name in joint.inputs if joint.velocity_count == 1]
    given_inputs = [] if inputs is None or (isinstance(inputs, (list, tuple)) and not inputs) else \
        list(validation.names("inputs", inputs))
    actuators = list(dict.fromkeys([name for name in default_inputs + given_inputs if name in ports.actuators]
                                   + [name for lp in loops for name, _ in lp.actuator_terms]))
    return linearize_with_feedback(
        lambda lin_in, lin_out: linearize_spatial_loops(model, operating_point, inputs=lin_in, outputs=lin_out,
                                                        allow_nonequilibrium=allow_nonequilibrium),
        loops, ports, inputs=inputs, outputs=outputs, actuators=actuators, default_inputs=default_inputs,
        default_outputs=[name for name in model.tree.coordinates if name in ports.sensors],
        cut_outputs=cut_force_names(model), name=model.name)


def natural_frequencies_spatial_loops(model: Any, *, n_modes: int | None = None, omega_max: float | None = None,
                                      operating_point: Any = None) -> np.ndarray:
    """:func:`ctmm.natural_frequencies` of a spatial kinematic loop model: undamped frequencies [rad/s] about the
    equilibrium ``operating_point`` (:func:`ctmm.spatial.closed_loop_linear.natural_frequencies`), ascending; at
    most ``n_modes``, those up to ``omega_max`` [rad/s]."""
    from .closed_loop_linear import natural_frequencies

    model = _plain(model, "natural_frequencies")
    q0, t = operating_configuration(model, operating_point)
    omega = natural_frequencies(model, q0, t)
    if omega_max is not None:
        omega = omega[omega <= validation.positive("omega_max", omega_max)]
    if n_modes is not None:
        omega = omega[:validation.integer("n_modes", n_modes, minimum=1)]
    return omega


def mode_shapes_spatial_loops(model: Any, *, n_modes: int | None = None, omega_max: float | None = None,
                              operating_point: Any = None) -> ModalResult:
    """:func:`ctmm.mode_shapes` of a spatial kinematic loop model: the undamped modes about the equilibrium
    ``operating_point`` on the constraint manifold, in the tree's tangent coordinates.

    ``shapes[k, i, 0]`` is tangent coordinate ``i`` (``point_names``:
    :func:`ctmm.spatial_linearization.tangent_names` of the tree, one per velocity) in mode ``k``: the
    independent-coordinate mode mapped back by the null-space basis, ``N phi``
    (:func:`ctmm.loop_manifold.undamped_modes`), normalised to unit largest entry; a repeated frequency's modes are an
    orthonormal basis of its eigenspace in ``z``.  Exactly one of ``n_modes`` and ``omega_max`` [rad/s], as for the
    other models; the frequencies are those of :func:`natural_frequencies_spatial_loops`."""
    from ..spatial_linearization import tangent_names
    from .closed_loop_linear import tangent, tangent_error

    model = _plain(model, "mode_shapes")
    validation.one_mode_limit(n_modes, omega_max)
    q0, t = operating_configuration(model, operating_point)
    A, basis, _ = tangent(model, q0, t)
    omega, shapes = undamped_modes(model, A, basis, tangent_error(model, q0, t))
    names = tangent_names(model.tree)
    if len(names) != shapes.shape[0]:
        raise ModelError(f"mode_shapes: the tree of {model.name!r} has {shapes.shape[0]} velocities but "
                         f"{len(names)} tangent coordinate names; its modes cannot be named")
    keep = validation.selected_modes(omega, n_modes, omega_max,
                                     f"spatial kinematic loop model {model.name!r} (one per degree of freedom)")
    return ModalResult(omega[keep], shapes[:, keep].T[:, :, None], ("amplitude",), names)


def eigenvalue_count_spatial_loops(model: Any, omega: Any, *, operating_point: Any = None) -> np.ndarray:
    """:func:`ctmm.eigenvalue_count`: natural frequencies strictly below each ``omega`` [rad/s]."""
    frequencies = natural_frequencies_spatial_loops(model, operating_point=operating_point)
    omega = np.asarray(validation.frequencies("omega", omega), dtype=float)
    return np.sum(frequencies[None, :] < omega.reshape(-1, 1), axis=1).reshape(omega.shape)


def frequency_response_spatial_loops(model: Any, omega: Any, *, input: Any, output: Any,  # noqa: A002
                                     operating_point: Any = None) -> FrequencyResponse:
    """:func:`ctmm.frequency_response`: ``C (i omega I - A)^-1 B + D`` of :func:`linearize_spatial_loops` about the
    equilibrium ``operating_point``; with feedback loops (a ``ControlledModel`` on the model) the real-time loops are
    closed in the linearisation and the delayed ones exactly by ``e^{-s tau}``
    (:func:`ctmm.controlled_linearization.delayed_loop_response`); a frequency at or next to a pole is refused."""
    started = time.perf_counter()
    plant = model if isinstance(model, SpatialKinematicLoopModel) else getattr(model, "plant", None)
    if not isinstance(plant, SpatialKinematicLoopModel):
        raise ModelError(f"frequency_response: model must be a SpatialKinematicLoopModel or a ControlledModel on one, "
                         f"got {model!r:.80}")
    loops = () if plant is model else tuple(model.loops)
    inputs, outputs = list(validation.names("input", input)), list(validation.names("output", output))
    omega = validation.frequencies("omega", omega)
    response, lin = delayed_loop_response(
        lambda lin_in, lin_out: linearize_spatial_loops(model, operating_point, inputs=lin_in, outputs=lin_out),
        loops, 1j * np.asarray(omega, dtype=float), inputs, outputs, plant.name)
    ports = SpatialLoopPorts(plant)
    units = {name: ports.actuator_unit(name) for name in inputs if name in ports.actuators}
    units.update({name: "N" if name in cut_force_names(plant) else ports.sensor_unit(name) for name in outputs
                  if name in ports.sensors or name in cut_force_names(plant)})
    info = {"method": "linearisation on the constraint manifold (ctmm.spatial.closed_loop_linear)"
                      + (", delayed loops exact" if loops else ""),
            "wall_time_s": time.perf_counter() - started, "n_frequencies": int(omega.size),
            "operating_point_q": lin.operating_point.q.tolist()}
    return FrequencyResponse(omega, response, tuple(inputs), tuple(outputs), plant.name, info=info, units=units)
