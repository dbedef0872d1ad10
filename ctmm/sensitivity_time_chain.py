"""Exact derivatives of RK4 simulations of controlled lumped chains in their loop numbers.

A :class:`~ctmm.control.loops.ControlledChain` is stepped as its generated kernel states it
(:mod:`ctmm.compiled_chain`): the chain's exact affine rate ``a = Ax x + Av v + B u + a0``
(:func:`ctmm.compiled_chain.affine_form`, certified there against the Python sweep) closed by the loops of
:class:`ctmm.compiled_loops.ClosedLoops` on :class:`ctmm.compiled_chain.ChainSymbols` (real-time loops at every RK4 stage, LTI controller states, delayed
loops from the ring of samples), here with the loops' numbers as entries of the step's parameter column
and the named loop numbers as directions in it (:mod:`ctmm.sensitivity_loop_numbers`: ``"<loop>.gain"``,
the sensor weights ``"<loop>.<sensor>"``, an LTI controller's realisation entries).  The forward
sensitivities are folded with the state by casadi's AD (:func:`ctmm.sensitivity_time.forward_sensitivities`):
the exact derivative of the RK4 solution ``ctmm.simulate(system, ..., method="rk4")`` computes (the Python and
generated RK4 agree to round-off).

Refused (:class:`~ctmm.errors.ModelError`, by name): the chain's own numbers (their affine form is read
numerically; free chains: :func:`ctmm.sensitivity_time.chain_simulation_sensitivity`; controlled chains:
the frequency-domain, margin and abscissa derivatives), loop delays, time-varying loads, what
:class:`~ctmm.compiled_loops.ClosedLoops` refuses.
"""
from __future__ import annotations

from typing import Any, Mapping, Sequence

import numpy as np

from . import validation
from .errors import ModelError
from .sensitivity_time import TimeSensitivity

__all__ = ["controlled_chain_simulation_sensitivity"]


def controlled_chain_simulation_sensitivity(system: Any, parameters: str | Sequence[str], *, t_final: float,
                                            dt: float, x0: Mapping[str, float] | None = None,
                                            v0: Mapping[str, float] | None = None,
                                            outputs: str | Sequence[str] | None = None) -> TimeSensitivity:
    """RK4 run of a controlled lumped chain with the exact derivatives of its outputs in loop numbers.

    Parameters
    ----------
    system : ControlledChain
        Lumped elements, every point with inertia; references 0.
    parameters : str or sequence of str
        Loop numbers (module docstring).
    t_final, dt : float
        [s]; ``t_final / dt`` whole, delays whole multiples of ``dt``.
    x0, v0 : mapping, optional
        Initial absolute positions [m] and velocities [m/s] by point element name (as :func:`ctmm.simulate`).
    outputs : str or sequence of str, optional
        ``"<point>.x"`` [m], ``"<point>.v"`` [m/s] (any sensor of the chain's ports); default every point's ``.x``.

    Returns
    -------
    TimeSensitivity
    """
    import casadi as ca

    from .compiled_chain import ChainSymbols, affine_form
    from .compiled_loops import ClosedLoops
    from .control.chain_plant import ChainPlant
    from .planar.integrate import step_total
    from .sensitivity_loop_numbers import is_loop_number, loop_directions, split_loops
    from .sensitivity_time import forward_sensitivities

    what = "controlled_chain_simulation_sensitivity"
    names = validation.names("parameters", parameters)
    plant_numbers = [name for name in names if not is_loop_number(system.loops, name)]
    if plant_numbers:
        raise ModelError(f"{what}: {plant_numbers} are numbers of the chain; in time a controlled chain is "
                         "differentiated in its loop numbers ('<loop>.gain', '<loop>.<sensor>', realisation entries): "
                         "use ctmm.sensitivity's frequency-domain, margin and abscissa derivatives for its element "
                         "numbers, or simulation_sensitivity on the free chain")
    saturated = [loop.name for loop in system.loops if loop.saturation is not None]
    if saturated:
        raise ModelError(f"{what}: loops {saturated} saturate; the generated chain step closes unsaturated loops")
    split = split_loops(system, names, what)
    plant = ChainPlant(split)
    actuators = tuple(dict.fromkeys(name for loop in split.loops for name, _ in loop.actuator_terms))
    form = affine_form(plant.dynamics, [plant.ports.inputs({name: 1.0}) for name in actuators])
    if form.loads:
        raise ModelError(f"{what}: chain {plant.chain.name!r} has time-varying loads; the free response under its "
                         "loops is differentiated (constant loads are fine)")
    n_steps = step_total(t_final, dt)
    h = t_final / n_steps
    m = plant.n_positions
    loops = ClosedLoops(split, actuators, h, symbols=ChainSymbols(plant), numbers="inputs")   # loop numbers in p
    q, v, u, p, t = ca.MX.sym("q", m), ca.MX.sym("v", m), ca.MX.sym("u", len(actuators)), ca.MX.sym("p", 0), \
        ca.MX.sym("t")
    rate = ca.mtimes(ca.DM(form.Ax), q) + ca.mtimes(ca.DM(form.Av), v) + ca.DM(form.a0)
    if actuators:
        rate += ca.mtimes(ca.DM(form.B), u)
    step = loops.step(ca.Function("acceleration", [q, v, u, p, t], [rate]), len(actuators), 0)
    first = loops.initial_state(*plant.start(x0, v0))
    size = loops.parameter_values.size
    directions = loop_directions(system, split, loops.parameter_layout, names, 0, size)
    states, tangents = forward_sensitivities(step, first, loops.parameter_values, directions, n_steps, h, what)
    points = [e.name for e in plant.chain.body if e.is_point and getattr(e, "mass", 0.0) > 0.0]
    wanted = [f"{name}.x" for name in points] if outputs is None else list(validation.names("outputs", outputs))
    rows, offsets = [], []
    for name in wanted:
        plant.ports.check_sensor(name, "output")
        sensor = plant.ports.resolve([name])

        def value(state: np.ndarray, sensor: Any = sensor) -> float:
            return float(plant.ports.values(sensor, state[:m], state[m:], 0.0)[0])

        zero = np.zeros(2 * m)
        offsets.append(value(zero))
        rows.append([value(row) - offsets[-1] for row in np.eye(2 * m)])   # sensors are affine in the state
    rows = np.array(rows)
    values = rows @ states[:, :2 * m].T + np.array(offsets)[:, None]
    derivative = np.einsum("ox,kxm->mok", rows, tangents[:, :2 * m, :])
    return TimeSensitivity(h * np.arange(n_steps + 1), tuple(wanted), tuple(names), values, derivative)
