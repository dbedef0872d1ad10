"""``ctmm.linearize`` of a kinematic loop model with feedback loops, planar and spatial: the loops closed around the
plant's tangent on the constraint manifold (:mod:`ctmm.loop_manifold`), with the cut forces as outputs and sensors.

The plant (:class:`ctmm.planar.closed_loops.KinematicLoopModel` or
:class:`ctmm.spatial.closed_loops.SpatialKinematicLoopModel`) is linearised with the needed actuators as inputs and
the needed sensors and cut forces as outputs; :func:`ctmm.controlled_linearization.close_model_loops` closes the
loops (real-time loops inside ``A``, LTI controller states appended, delayed loops beside it; the loops act on the
deviations of their sensors from the operating point).  Cut-force outputs feed through from the actuators (the
plant's ``D``): their rows are ``C_f x + D_f u`` with the actuator values ``u`` of the closed system (exogenous
actuator inputs, the real-time loops' forces, the delayed loops' force inputs).  A loop may sense a cut force: its
row carries the plant's feedthrough ``D`` into the closure (``close_model_loops(output_feedthrough=...)``), which
solves a real-time loop on it as the algebraic loop it is and keeps a delayed one's ``D`` beside ``A`` (a neutral
delay loop when ``|K D|`` is not small: the stability tools say so).  ``docs/closed_loops.md`` §3c, §8.
"""
from __future__ import annotations

from typing import Any, Callable, Sequence

import numpy as np

from . import validation
from .controlled_linearization import close_model_loops, exogenous_inputs
from .linearized import LinearizedSystem, control_name

__all__ = ["linearize_with_feedback"]


def linearize_with_feedback(linearize_plant: Callable[[list[str], list[str]], LinearizedSystem], loops: Sequence[Any],
                            ports: Any, *, inputs: Any, outputs: Any, actuators: Sequence[str],
                            default_inputs: Sequence[str], default_outputs: Sequence[str],
                            cut_outputs: Sequence[str], name: str) -> LinearizedSystem:
    """The closed-loop :class:`LinearizedSystem` of a kinematic loop model with feedback ``loops`` (module docstring).

    Parameters
    ----------
    linearize_plant : callable
        ``(input names, output names) -> LinearizedSystem`` of the open plant about the operating point.
    loops : sequence of Feedback
        The loops on the plant's ports.
    ports : PlanarPorts or SpatialPorts
        The tree's ports (``sensors``, ``check_actuator``, ``check_sensor``).
    inputs, outputs : as for :func:`ctmm.linearize`
        ``None``: ``default_inputs`` / ``default_outputs``; outputs may name cut forces (``cut_outputs``) [N].
    actuators : sequence of str
        The plant inputs to linearise with: the default and given exogenous actuators and the loops' actuators.
    default_inputs, default_outputs : sequence of str
        The default exogenous actuators and outputs (sensor names).
    cut_outputs : sequence of str
        The names of the cut-force outputs (``"<cut>.force_x"``, ...).
    name : str
        The model's name.
    """
    import control

    actuators = list(actuators)
    forces = tuple(cut_outputs)
    empty = outputs is None or (isinstance(outputs, (list, tuple)) and not outputs)
    requested = [] if empty else list(validation.names("outputs", outputs))
    cut = [name for name in requested if name in forces]
    sensors = set(ports.sensors)
    needed = list(dict.fromkeys([name for name in list(default_outputs) + requested
                                 if name in sensors and name not in forces]
                                + [name for lp in loops for name, _ in lp.terms]))
    plant = linearize_plant(actuators, needed + cut)
    ss = plant.state_space
    B, C, D = (np.asarray(m, dtype=float) for m in (ss.B, ss.C, ss.D))

    def columns(names: list[str]) -> np.ndarray:
        return B[:, [actuators.index(ports.check_actuator(name, "input (actuator)")) for name in names]]

    def rows(names: list[str]) -> np.ndarray:
        for name in names:
            ports.check_sensor(name, "output (sensor)")
        return C[[needed.index(name) for name in names], :]

    def feedthrough(names: list[str], inputs_of_plant: list[str]) -> np.ndarray:
        """The plant's ``D`` rows of the loop sensors: nonzero for the cut forces, which respond to the actuators."""
        return D[np.ix_([needed.index(name) for name in names], [actuators.index(name) for name in inputs_of_plant])]

    real_time = [lp for lp in loops if lp.delay == 0.0]
    others = [name for name in requested if name not in forces]
    helpers = [f"{lp.name}.u" for lp in real_time if f"{lp.name}.u" not in others] if cut else []
    closed = close_model_loops(np.asarray(ss.A, dtype=float), loops, inputs=inputs,
                               outputs=outputs if not cut else others + helpers, default_inputs=list(default_inputs),
                               default_outputs=list(default_outputs), input_columns=columns, output_rows=rows,
                               states=list(ss.state_labels), name=name, point=plant.operating_point,
                               output_feedthrough=feedthrough)
    if not cut:
        return closed
    # the cut forces: C_f x + D_f u, u the actuator values of the closed system (module docstring of close_model_loops)
    lin = closed.state_space
    A_cl, B_cl, C_cl, D_cl = (np.asarray(m, dtype=float) for m in (lin.A, lin.B, lin.C, lin.D))
    exo, _ = exogenous_inputs(loops, inputs, list(default_inputs))
    delayed = [lp for lp in loops if lp.delay > 0.0]
    U_x, U_in = np.zeros((len(actuators), A_cl.shape[0])), np.zeros((len(actuators), B_cl.shape[1]))
    for k, name in enumerate(exo):
        if name in actuators:
            U_in[actuators.index(name), k] += 1.0
    listed = others + helpers
    for lp in real_time:
        row = listed.index(f"{lp.name}.u")
        for name, weight in lp.actuator_terms:
            U_x[actuators.index(name)] += weight * C_cl[row]
            U_in[actuators.index(name)] += weight * D_cl[row]
    for j, lp in enumerate(delayed):
        for name, weight in lp.actuator_terms:
            U_in[actuators.index(name), len(exo) + j] += weight
    C_f, D_f = C[len(needed):], D[len(needed):]
    force_rows = np.hstack([C_f, np.zeros((len(cut), A_cl.shape[0] - C_f.shape[1]))]) + D_f @ U_x
    force_feed = D_f @ U_in
    C_new = np.vstack([force_rows[cut.index(name)] if name in forces else C_cl[listed.index(name)]
                       for name in requested] + [C_cl[len(listed):]])
    D_new = np.vstack([force_feed[cut.index(name)] if name in forces else D_cl[listed.index(name)]
                       for name in requested] + [D_cl[len(listed):]])
    labels = [control_name(x) for x in requested] + list(lin.output_labels)[len(listed):]
    state_space = control.ss(A_cl, B_cl, C_new, D_new, inputs=list(lin.input_labels), outputs=labels,
                             states=list(lin.state_labels), name=lin.name)
    return LinearizedSystem(state_space, closed.delays, closed.operating_point)
