"""Frequency responses of planar models with feedback loops, exact in the delays.

A planar model (rigid or with modal beams) is linearised about an operating point
(:func:`ctmm.linearize`: ``x' = A x + B a``, sensors ``y_s = C x + D a`` with ``a`` the actuator
values).  Its plant response from actuators to sensors at ``s = i omega`` is
``P(s) = C (s I - A)^{-1} B + D``.  The loops of a :class:`~ctmm.control.ControlledModel` act on
deviations from the operating point (small-signal convention: references are deviations too):

    u = -K(s) (W y_s - r),      a = B_l u + a_ext,      K(s) = diag(C_j(s) e^{-s tau_j}),

with ``W`` the loops' sensor weights and ``B_l`` their actuator weights, so the loop forces are

    u = (I + K W P B_l)^{-1} K (r - W P a_ext)

and every output follows from ``a``: sensors ``P a``, ``"<loop>.y" = W P a``, ``"<loop>.u" = u``.
The delays stay exact factors ``e^{-s tau}`` (no Pade approximation); the only approximation is
the linearisation itself.
"""
from __future__ import annotations

import time
from typing import Any, Sequence

import numpy as np

from .. import validation
from ..errors import ModelError
from ..planar.model import PlanarModel
from ..results import FrequencyResponse
from .controlled_model import ControlledModel

__all__ = ["model_frequency_response", "plant_response"]


def plant_response(state_space: Any, s: np.ndarray) -> np.ndarray:
    """``C (s I - A)^{-1} B + D`` at every Laplace variable ``s``, shape (n_out, n_in, n_s)."""
    A, B, C, D = (np.asarray(m, dtype=float) for m in (state_space.A, state_space.B, state_space.C, state_space.D))
    n = A.shape[0]
    s = np.asarray(s, dtype=complex).reshape(-1)
    if n == 0:
        return np.repeat(D[:, :, None], s.size, axis=2).astype(complex)
    stack = s[:, None, None] * np.eye(n) - A[None, :, :]
    try:
        X = np.linalg.solve(stack, np.broadcast_to(B, (s.size,) + B.shape))
    except np.linalg.LinAlgError as exc:
        raise ModelError(f"s I - A is singular at one of the frequencies (a pole on the imaginary axis, e.g. a "
                         f"rigid-body mode at omega = 0): {exc}") from exc
    return np.transpose(C[None] @ X + D[None], (1, 2, 0))


def model_frequency_response(system: PlanarModel | ControlledModel, omega: Any, *, input: str | Sequence[str],  # noqa: A002
                             output: str | Sequence[str], operating_point: Any = None) -> FrequencyResponse:
    """Frequency response of a planar model, open or with its loops closed (exact delays).

    Parameters
    ----------
    system : PlanarModel or ControlledModel
    omega : array_like
        Angular frequencies [rad/s], >= 0.
    input : str or sequence of str
        Actuator names (``"motor.torque"``, ``"hub.force_x"``, ``"arm.q1.force"``) or loop
        references ``"<loop>.reference"``.
    output : str or sequence of str
        Sensor names (``"fore.out.y"``, ``"motor.angle"``, ...) or ``"<loop>.y"``, ``"<loop>.u"``.
    operating_point : optional
        Where to linearise (:func:`ctmm.linearize`); default the plant's static equilibrium.

    Returns
    -------
    FrequencyResponse
        ``response[i_out, i_in, k]``; units from the ports.
    """
    from ..linearize import linearize

    started = time.perf_counter()
    if isinstance(system, ControlledModel):
        plant, loops, ports = system.plant, system.loops, system.ports
    elif isinstance(system, PlanarModel):
        from ..planar.ports import PlanarPorts

        plant, loops, ports = system, (), PlanarPorts(system)
    else:
        raise ModelError(f"system must be a ctmm.planar.PlanarModel or a ctmm.control.ControlledModel, got {system!r}")
    inputs = validation.names("input", input)
    outputs = validation.names("output", output)
    loop_names = [loop.name for loop in loops]
    references, actuators_in = [], []
    for name in inputs:
        if name.endswith(".reference") and name[:-len(".reference")] in loop_names:
            references.append(name)
        else:
            actuators_in.append(ports.check_actuator(name, "input"))
    loop_outputs = {f"{loop}.{part}" for loop in loop_names for part in ("y", "u")}
    sensors_out = [ports.check_sensor(name, "output") for name in outputs if name not in loop_outputs]
    actuators = list(dict.fromkeys(actuators_in + [a for loop in loops for a, _ in loop.actuator_terms]))
    sensors = list(dict.fromkeys(sensors_out + [y for loop in loops for y, _ in loop.terms]))
    s = 1j * validation.frequencies("omega", omega)
    linear = linearize(plant, operating_point, inputs=actuators, outputs=sensors)
    P = plant_response(linear.state_space, s)                     # (n_sensors, n_actuators, n_s)
    n_l, n_s = len(loops), s.size
    W = np.zeros((n_l, len(sensors)))
    Bl = np.zeros((len(actuators), n_l))
    for j, loop in enumerate(loops):
        for name, weight in loop.terms:
            W[j, sensors.index(name)] += weight
        for name, weight in loop.actuator_terms:
            Bl[actuators.index(name), j] += weight
    K = np.array([loop.loop_gain(s) for loop in loops]).reshape(n_l, n_s)
    # unit inputs as columns: external actuator values E_a, references E_r
    n_in = len(inputs)
    Ea = np.zeros((len(actuators), n_in))
    Er = np.zeros((n_l, n_in))
    for i, name in enumerate(inputs):
        if name in references:
            Er[loop_names.index(name[:-len(".reference")]), i] = 1.0
        else:
            Ea[actuators.index(name), i] = 1.0
    Pk = np.moveaxis(P, 2, 0)                                      # (n_s, n_sensors, n_actuators)
    WP = W[None] @ Pk                                              # (n_s, n_l, n_act)
    if n_l:
        Kd = np.moveaxis(K, 1, 0)[:, :, None]                      # (n_s, n_l, 1)
        matrix = np.eye(n_l)[None] + Kd * (WP @ Bl[None])
        rhs = Kd * (Er[None] - WP @ Ea[None])
        try:
            U = np.linalg.solve(matrix, rhs)                       # (n_s, n_l, n_in)
        except np.linalg.LinAlgError as exc:
            raise ModelError(f"the closed loop has a pole on the imaginary axis at one of the frequencies: {exc}") from exc
        Aall = Bl[None] @ U + Ea[None]
    else:
        U = np.zeros((n_s, 0, n_in), dtype=complex)
        Aall = np.broadcast_to(Ea[None], (n_s,) + Ea.shape)
    Y = Pk @ Aall                                                  # sensors (n_s, n_sensors, n_in)
    response = np.empty((len(outputs), n_in, n_s), dtype=complex)
    for k, name in enumerate(outputs):
        if name in loop_outputs:
            loop, part = name.rsplit(".", 1)
            j = loop_names.index(loop)
            response[k] = (U[:, j, :] if part == "u" else (W[None, j:j + 1] @ Y)[:, 0, :]).T
        else:
            response[k] = Y[:, sensors.index(name), :].T
    units = {name: ports.sensor_unit(name) for name in outputs if name not in loop_outputs}
    units.update({name: ports.actuator_unit(name) for name in inputs if name not in references})
    info = {"method": "linearisation about the operating point, exact delays", "wall_time_s": time.perf_counter() - started,
            "operating_point": repr(getattr(linear, "operating_point", None))}
    return FrequencyResponse(np.imag(s), response, tuple(inputs), tuple(outputs), plant.name, info, units)
