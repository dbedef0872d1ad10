"""Exact derivatives of RK4 simulations of controlled lumped chains in their element and loop numbers.

A :class:`~ctmm.control.loops.ControlledChain` is stepped as its generated kernel states it
(:mod:`ctmm.compiled_chain`): the chain's exact affine rate ``a = Ax x + Av v + B u + a0``
(:func:`ctmm.compiled_chain.affine_form`, certified there against the Python sweep) closed by the loops of
:class:`ctmm.compiled_loops.ClosedLoops` on :class:`ctmm.compiled_chain.ChainSymbols` (real-time loops at every
RK4 stage, LTI controller states, delayed loops from the ring of samples), with the loops' numbers as entries of
the step's parameter column and the named loop numbers as directions in it (:mod:`ctmm.sensitivity_loop_numbers`:
``"<loop>.gain"``, the sensor weights ``"<loop>.<sensor>"``, an LTI controller's realisation entries).

The chain's own numbers (``"<point>.mass"``, ``"<point>.stiffness"``, ``"<point>.damping"``,
``"<connector>.stiffness"``, ``"<connector>.damping"``) are entries of the same column ahead of the loops'.  Over
the nodes with inertia the rate is ``M a = F``, ``F = Fx x + Fv v + Fb u + F0`` (``Fx = M Ax``, ...), with ``M``
the nodes' masses (:class:`ctmm.sensitivity_model.LoopCharacteristicMatrix`'s mass matrix, its degrees of freedom
matched to the nodes by the ``"<point>.x"`` sensors).  The element forces are linear in each number, so

    M(p) = M0 + sum_i (p_i - p_i0) dM/dp_i,    F(p) = F(p0) + sum_i (p_i - p_i0) dF/dp_i,

``dFx/dk = -dK/dk``, ``dFv/dc = -dC/dc``, ``dM/dm`` the patterns of the characteristic matrix (each certified
against the affine form of the chain rebuilt with that number changed), and ``dF0/dp_i`` (a spring's rest length,
a prestressed end) the exact secant of the ``M a0`` of the two forms.  The rate ``a = M(p)^{-1} F(p)`` is stated on
casadi symbols and the forward sensitivities are folded with the state by casadi's AD
(:func:`ctmm.sensitivity_time.forward_sensitivities`): the exact derivative of the RK4 solution
``ctmm.simulate(system, ..., method="rk4")`` computes (the Python and generated RK4 agree to round-off).

Outputs are the chain's sensors, affine in the node state: ``y = R(p) [x; v] + c(p)``; a connector's law force
``"<connector>.f"`` depends on that connector's stiffness and damping directly, so ``dy/dp = R S + dR/dp [x; v] +
dc/dp`` (``dR/dp``, ``dc/dp`` the central secants of the sensors of the chain rebuilt with the number changed: exact,
the law force being linear in the number; certified by the one-sided secants agreeing, else refused).

Time-varying loads with a symbolic form (:mod:`ctmm.signals` Constant, Harmonic, Step, SquareWave) are force
columns ``Fl_j s_j(t)`` of ``F`` (each certified independent of the numbers) on the step's time, as the generated
chain RK4 states them.  Refused (:class:`~ctmm.errors.ModelError`, by name): loop delays, load signals that are
Python callables, massless points, element numbers of a chain with an inerter between two moving points (its nodes'
mass matrix not diagonal), what :class:`~ctmm.compiled_loops.ClosedLoops` refuses.
"""
from __future__ import annotations

import copy
from dataclasses import dataclass
from typing import Any, Mapping, Sequence

import numpy as np

from . import validation
from .errors import ModelError
from .sensitivity_time import TimeSensitivity

__all__ = ["ElementForces", "controlled_chain_simulation_sensitivity"]


def controlled_chain_simulation_sensitivity(system: Any, parameters: str | Sequence[str], *, t_final: float,
                                            dt: float, x0: Mapping[str, float] | None = None,
                                            v0: Mapping[str, float] | None = None,
                                            outputs: str | Sequence[str] | None = None) -> TimeSensitivity:
    """RK4 run of a controlled lumped chain with the exact derivatives of its outputs in element and loop numbers.

    Parameters
    ----------
    system : ControlledChain
        Lumped elements, every point with inertia; references 0.
    parameters : str or sequence of str
        Element numbers (``"<point>.mass"`` [kg], ``"<point>.stiffness"`` [N/m], ``"<connector>.damping"``
        [N s/m], ...) and loop numbers (module docstring).
    t_final, dt : float
        [s]; ``t_final / dt`` whole, delays whole multiples of ``dt``.
    x0, v0 : mapping, optional
        Initial absolute positions [m] and velocities [m/s] by point element name (as :func:`ctmm.simulate`).
    outputs : str or sequence of str, optional
        ``"<point>.x"`` [m], ``"<point>.v"`` [m/s], ``"<connector>.f"`` [N] (any sensor of the chain's ports; a law
        force's own dependence on its connector's numbers included); default every point's ``.x``.

    Returns
    -------
    TimeSensitivity

    Raises
    ------
    ModelError
        Unknown numbers, loop delays, saturated loops, user-callable load signals, massless points, a chain whose affine
        form does not match its mass, stiffness and damping matrices (certified), a diverging run.
    """
    import casadi as ca

    from .compiled_chain import ChainSymbols, affine_form
    from .compiled_loops import ClosedLoops
    from .control.chain_plant import ChainPlant
    from .planar.integrate import step_total
    from .sensitivity_loop_numbers import is_loop_number, loop_directions, split_loops
    from .sensitivity_time import forward_sensitivities
    from .signals import signal_parameters

    what = "controlled_chain_simulation_sensitivity"
    names = validation.names("parameters", parameters)
    plant_numbers = [name for name in names if not is_loop_number(system.loops, name)]
    saturated = [loop.name for loop in system.loops if loop.saturation is not None]
    if saturated:
        raise ModelError(f"{what}: loops {saturated} saturate; the generated chain step closes unsaturated loops")
    split = split_loops(system, names, what)
    plant = ChainPlant(split)
    actuators = tuple(dict.fromkeys(name for loop in split.loops for name, _ in loop.actuator_terms))
    form = affine_form(plant.dynamics, [plant.ports.inputs({name: 1.0}) for name in actuators])
    callables = [repr(signal) for _, signal in form.loads if signal_parameters(signal) is None]
    if callables:
        raise ModelError(f"{what}: chain {plant.chain.name!r} has load signals that are Python callables of time "
                         f"({', '.join(callables)}), which the generated step cannot state; give ctmm.signals "
                         "Constant, Harmonic, Step or SquareWave")
    forces = _element_forces(plant, form, plant_numbers, what)
    n_steps = step_total(t_final, dt)
    h = t_final / n_steps
    m = plant.n_positions
    k = len(plant_numbers)
    symbols = ChainSymbols(plant)
    symbols.parameter_count = k                        # the element numbers lead the step's parameter column
    loops = ClosedLoops(split, actuators, h, symbols=symbols, numbers="inputs")
    q, v, u, p, t = (ca.MX.sym(label, size) for label, size in (("q", m), ("v", m), ("u", len(actuators)),
                                                                ("p", k), ("t", 1)))
    step = loops.step(ca.Function("acceleration", [q, v, u, p, t], [forces.rate(q, v, u, p, t)]), len(actuators), k)
    first = loops.initial_state(*plant.start(x0, v0))
    size = k + loops.parameter_values.size
    directions = loop_directions(system, split, loops.parameter_layout, names, k, size)
    for i, name in enumerate(plant_numbers):
        directions[i, names.index(name)] = 1.0
    values0 = np.concatenate([forces.values, loops.parameter_values])
    states, tangents = forward_sensitivities(step, first, values0, directions, n_steps, h, what)
    points = [e.name for e in plant.chain.body if e.is_point and getattr(e, "mass", 0.0) > 0.0]
    wanted = [f"{name}.x" for name in points] if outputs is None else list(validation.names("outputs", outputs))
    rows, offsets = _affine_sensors(plant, wanted)
    values = rows @ states[:, :2 * m].T + offsets[:, None]
    derivative = np.einsum("ox,kxm->mok", rows, tangents[:, :2 * m, :])
    for i, name in enumerate(plant_numbers):            # the outputs' own dependence (a connector's law force)
        slope_rows, slope_offsets = _sensor_slopes(plant, wanted, name, float(forces.values[i]), rows, offsets, what)
        derivative[names.index(name)] += slope_rows @ states[:, :2 * m].T + slope_offsets[:, None]
    return TimeSensitivity(h * np.arange(n_steps + 1), tuple(wanted), tuple(names), values, derivative)


@dataclass(frozen=True)
class ElementForces:
    """``M(p) a = F(p)`` over a chain's nodes with inertia (``M`` diagonal), affine in the named element numbers
    (module docstring).

    Attributes
    ----------
    values : ndarray
        The numbers' current values ``p0`` (SI units).
    M0, Fx, Fv, Fb, F0 : ndarray
        ``M`` [kg] and the force form ``F = Fx x + Fv v + Fb u + F0 + sum_j Fl_j s_j(t)`` [N] at ``p0``.
    dM, dFx, dFv, dF0 : list of ndarray
        Their derivatives per number.
    Fl : ndarray, shape (nodes, n_loads)
        The time-varying loads' force columns (independent of the numbers: certified).
    signals : tuple
        Their :mod:`ctmm.signals` (each with a symbolic form).
    """

    values: np.ndarray
    M0: np.ndarray
    Fx: np.ndarray
    Fv: np.ndarray
    Fb: np.ndarray
    F0: np.ndarray
    dM: list
    dFx: list
    dFv: list
    dF0: list
    Fl: np.ndarray
    signals: tuple

    def rate(self, q: Any, v: Any, u: Any, p: Any, t: Any) -> Any:
        """``a = M(p)^{-1} F(p, t)`` on casadi symbols (``p`` the numbers' values; ``q``, ``v``, ``u`` columns;
        ``t`` [s] the loads' time)."""
        import casadi as ca

        from .signals import signal_parameters, symbolic_signal

        M, Fx, Fv, F0 = ca.DM(np.diag(self.M0)), ca.DM(self.Fx), ca.DM(self.Fv), ca.DM(self.F0)
        for i in range(self.values.size):
            d = p[i] - float(self.values[i])
            M, Fx, Fv, F0 = (X + d * ca.DM(dX) for X, dX in zip((M, Fx, Fv, F0), (np.diag(self.dM[i]), self.dFx[i],
                                                                                  self.dFv[i], self.dF0[i])))
        force = ca.mtimes(Fx, q) + ca.mtimes(Fv, v) + F0
        if self.Fb.shape[1]:
            force = force + ca.mtimes(ca.DM(self.Fb), u)
        for column, signal in zip(self.Fl.T, self.signals):
            force = force + ca.DM(column) * symbolic_signal(type(signal), t, signal_parameters(signal))
        return force / M if self.values.size else force          # M diagonal (one mass per node)


def _element_forces(plant: Any, form: Any, names: Sequence[str], what: str) -> ElementForces:
    """The force form of ``plant`` (a ChainPlant) and its derivatives in the element numbers ``names``, certified
    against the affine form ``form`` and against the forms of the chain rebuilt with each number changed."""
    from .compiled_chain import affine_form
    from .control.chain_plant import ChainPlant
    from .sensitivity_model import LoopCharacteristicMatrix

    chain, m = plant.chain, plant.n_positions
    signals = tuple(signal for _, signal in form.loads)
    columns = np.column_stack([column for column, _ in form.loads]) if form.loads else np.zeros((m, 0))
    if not names:                                      # loop numbers only: the affine form as it is
        return ElementForces(np.zeros(0), np.eye(m), form.Ax, form.Av, form.B, form.a0, [], [], [], [], columns,
                             signals)
    model = LoopCharacteristicMatrix(chain, list(names))
    T = np.zeros((m, model.n))                         # nodes <- degrees of freedom of the characteristic matrix
    for element in chain.body:
        if element.is_point and getattr(element, "mass", 0.0) > 0.0:
            sensor = plant.ports.resolve([f"{element.name}.x"])
            node = np.array([plant.ports.values(sensor, row, np.zeros(m), 0.0)[0] for row in np.eye(m)]) - \
                plant.ports.values(sensor, np.zeros(m), np.zeros(m), 0.0)[0]
            T += np.outer(node, model.output_row(f"{element.name}.x", 1.0).real)
    if T.shape[0] != T.shape[1] or not np.allclose(T @ T.T, np.eye(m), atol=1e-12) or \
            np.any(model.M != np.diag(np.diag(model.M))):
        raise ModelError(f"{what}: the nodes of chain {chain.name!r} are not one mass point each (massless points or "
                         "points that share a node); element numbers are differentiated in time for chains whose "
                         "every moving point has its own mass")

    def nodal(X: np.ndarray) -> np.ndarray:
        return T @ np.real(X) @ T.T

    M0 = nodal(model.M)
    scale = max(np.abs(M0 @ form.Ax).max(), np.abs(M0 @ form.Av).max(), 1e-300)
    for X, Y, label in ((M0 @ form.Ax, -nodal(model.K), "stiffness"), (M0 @ form.Av, -nodal(model.C), "damping")):
        if np.abs(X - Y).max() > 1e-9 * scale:
            raise ModelError(f"{what}: chain {chain.name!r}: its affine form does not match its {label} matrix "
                             f"(difference {np.abs(X - Y).max():.3g}); its element numbers cannot be differentiated here")
    dM, dFx, dFv, dF0 = [], [], [], []
    zero = np.zeros((m, m))
    for p in model.parameters:
        pattern = nodal(p.pattern)
        step = 0.5 * abs(p.value) if p.value else 1.0
        other = ChainPlant(_changed(chain, p.name, p.value + step))
        changed = affine_form(other.dynamics)
        M1 = M0 + step * pattern if p.kind == "mass" else M0
        pairs = ((M1 @ changed.Ax - M0 @ form.Ax) / step, -pattern if p.kind == "stiffness" else zero), \
            ((M1 @ changed.Av - M0 @ form.Av) / step, -pattern if p.kind == "damping" else zero)
        if form.loads:                                 # a load's force depends on none of the numbers
            loads = np.column_stack([column for column, _ in changed.loads])
            pairs += ((M1 @ loads - M0 @ columns) / step, np.zeros_like(columns)),
        for secant, expected in pairs:
            if np.abs(secant - expected).max() > 1e-9 * max(scale, np.abs(expected).max()):
                raise ModelError(f"{what}: {p.name!r} of chain {chain.name!r} does not enter its affine form as its "
                                 "pattern in the characteristic matrix; it cannot be differentiated here")
        dM.append(pattern if p.kind == "mass" else zero)
        dFx.append(-pattern if p.kind == "stiffness" else zero)
        dFv.append(-pattern if p.kind == "damping" else zero)
        dF0.append((M1 @ changed.a0 - M0 @ form.a0) / step)       # exact: the forces are affine in the number
    return ElementForces(np.array([p.value for p in model.parameters], dtype=float), M0, M0 @ form.Ax,
                         M0 @ form.Av, M0 @ form.B, M0 @ form.a0, dM, dFx, dFv, dF0, M0 @ columns, signals)


def _affine_sensors(plant: Any, names: Sequence[str]) -> tuple[np.ndarray, np.ndarray]:
    """Rows ``R`` [unit/m, unit s/m] and offsets ``c`` of the sensors ``names`` of a ChainPlant as affine functions
    ``y = R [x; v] + c`` of its node state (sensors are affine in the state).

    Raises
    ------
    ModelError
        A name that is not a sensor the plant can output.
    """
    m = plant.n_positions
    rows, offsets = [], []
    for name in names:
        plant.ports.check_sensor(name, "output")
        sensor = plant.ports.resolve([name])

        def value(state: np.ndarray, sensor: Any = sensor) -> float:
            return float(plant.ports.values(sensor, state[:m], state[m:], 0.0)[0])

        offsets.append(value(np.zeros(2 * m)))
        rows.append([value(row) - offsets[-1] for row in np.eye(2 * m)])
    return np.array(rows).reshape(len(names), 2 * m), np.array(offsets, dtype=float)


def _sensor_slopes(plant: Any, outputs: Sequence[str], name: str, value: float, rows: np.ndarray,
                   offsets: np.ndarray, what: str) -> tuple[np.ndarray, np.ndarray]:
    """``dR/dp``, ``dc/dp`` of the outputs' affine forms (:func:`_affine_sensors`) in the element number ``name``
    (value ``value``): a connector's law force is linear in its stiffness and damping, so the central secant over the
    chain rebuilt at ``value +- value/2`` is exact; certified (the two one-sided secants agree), else refused."""
    from .control.chain_plant import ChainPlant

    step = 0.5 * abs(value) if value else 1.0
    up, up_offsets = _affine_sensors(ChainPlant(_changed(plant.chain, name, value + step)), outputs)
    down, down_offsets = _affine_sensors(ChainPlant(_changed(plant.chain, name, value - step)), outputs)
    for k, output in enumerate(outputs):
        forward = np.append(up[k] - rows[k], up_offsets[k] - offsets[k]) / step
        backward = np.append(rows[k] - down[k], offsets[k] - down_offsets[k]) / step
        if np.abs(forward - backward).max() > 1e-9 * max(np.abs(forward).max(), np.abs(backward).max(), 1e-300):
            raise ModelError(f"{what}: output {output!r} of chain {plant.chain.name!r} is not affine in {name!r} "
                             "(its one-sided secants differ); its derivative in that number is not stated here")
    return (up - down) / (2 * step), (up_offsets - down_offsets) / (2 * step)


def _changed(chain: Any, name: str, value: float) -> Any:
    """``chain`` with the element number ``name`` (``"<element>.<number>"``) set to ``value`` (> 0), as
    :func:`ctmm.sensitivity.with_parameters` sets it (the element's forms derived again)."""
    from .system import Chain

    head, _, tail = name.partition(".")
    elements = list(chain.elements)
    j = chain.position(head)
    element = copy.copy(elements[j])
    element.__dict__[tail] = value
    element.derive_forms()
    elements[j] = element
    return Chain(chain.name, elements)
