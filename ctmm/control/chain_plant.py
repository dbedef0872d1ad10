"""A lumped 1-D chain as a :class:`~ctmm.control.plants.Plant` of the one loop-closing time driver.

:class:`ChainPlant` puts the explicit context of a plain lumped chain (:class:`ctmm.chain_ode.ChainDynamics`:
one articulated sweep per rate, massless nodes condensed) behind the plant protocol, so that
``ctmm.simulate(controlled_chain, method="rk4" | <solve_ivp method>)`` closes its loops, co-simulated
controllers and open-loop inputs in :func:`ctmm.control.planar_time.simulate_closed_loop` -- the same
driver as planar and spatial models.

State
    ``q = x_I`` (positions [m] of the nodes with inertia), ``v = [v_I, z_r]`` (their velocities
    [m/s], then the first-order part [m] of the massless nodes next to a damper,
    :mod:`ctmm.chain_ode`): ``q_dot = v_I`` and the "accelerations" are ``[a_I, z_r']``.  The
    first-order part rides with the velocities because its rate comes from the force balance
    (with the loads), as the accelerations do.

Sensors (:class:`ChainPorts`, the names :class:`~ctmm.control.loops.Feedback` uses for chains)
    ``"<element>[.in|.out].x"`` [m] and ``".v"`` / ``".x_dot"`` [m/s] of every connection point,
    and ``"<connector>[.in|.out].f"`` [N], the force of a lumped connector without inertance from its
    law (``-k (dx - free length) - c dv``).  Not sensors on this path: accelerations and point
    forces next to point elements (they depend on the accelerations: an algebraic loop through the
    sweep), the force of a connector that an actuator drives (direct feedthrough of its own
    input), and the force of an inerter.  The DT-TMM schemes (``method="newmark"``, ...) embed
    those implicitly.
Actuators
    ``"<element>.<input>"`` or ``"<element>"`` (its first input) of every element between the
    boundaries: a force [N] on a point element, or across a connector.  An actuator at a node
    without inertia is refused (its rate would be needed in closed form).
"""
from __future__ import annotations

from dataclasses import dataclass
from typing import Any, Callable, Mapping, Sequence

import numpy as np

from ..chain_ode import ChainDynamics
from ..chain_start import point_labels, rest_positions
from ..errors import ModelError, SimulationError, unknown_name
from ..guard import DivergenceGuard
from ..named_ports import NamedPorts
from ..system import Chain

__all__ = ["ChainPorts", "ChainPlant"]

_UNITS = {0: "m", 1: "m/s"}


@dataclass(frozen=True)
class ChainSensor:
    """One resolved chain sensor: a point's position (``derivative = 0``) or velocity (``1``), or
    the law force of the connector at element ``position`` (``force = True``)."""

    name: str
    point: int
    derivative: int
    force: bool
    position: int
    unit: str


@dataclass(frozen=True)
class ChainActuator:
    """One resolved chain actuator: input ``input`` of the element at ``position`` [N]."""

    name: str
    position: int
    input: str
    unit: str = "N"


class ChainPorts(NamedPorts):
    """The sensors and actuators of a lumped chain on the ODE path (module docstring).

    Parameters
    ----------
    dynamics : ChainDynamics
        The chain's first-order system.
    """

    def __init__(self, dynamics: ChainDynamics) -> None:
        self.dynamics = dynamics
        self.model = chain = dynamics.chain
        self.sensors: dict[str, ChainSensor] = {}
        self.actuators: dict[str, ChainActuator] = {}
        body = set(range(1, len(chain.elements) - 1))
        for position in sorted(body):
            element = chain.elements[position]
            for k, input_name in enumerate(element.inputs):
                entry = ChainActuator(f"{element.name}.{input_name}", position, input_name)
                self.actuators[entry.name] = entry
                if k == 0:
                    self.actuators[element.name] = entry
        self._massless_points = {p for p, k in enumerate(dynamics.node_of_point) if k >= 0 and dynamics.massless[k]}
        self._sensed_connectors: set[int] = set()
        self._driven_connectors: set[int] = set()
        # the last massless-node condensation of the sensors, (t, y, x, v): the rate at the same (t, y) reuses it
        self._condensed: tuple[float, np.ndarray, np.ndarray, np.ndarray] | None = None

    def check_sensor(self, name: str, what: str = "sensor") -> str:
        """``name`` if it is a sensor of this path, else a :class:`ModelError` naming why."""
        if isinstance(name, str) and name in self.sensors:
            return name
        chain = self.model
        try:
            signal = chain.signal(name)
        except ModelError:
            raise unknown_name(what, name, chain.signal_names()) from None
        if signal.derivative >= 2:
            raise ModelError(f"{what} {name!r}: accelerations are not sensors of the ODE path of a chain (a loop on "
                             "one would close an algebraic loop through the sweep); measure positions or velocities, "
                             "or use a DT-TMM scheme (method='newmark', ...), which embeds them implicitly")
        if signal.component == 0:
            entry = ChainSensor(name, signal.point, signal.derivative, False, -1, _UNITS[signal.derivative])
        else:
            position = self._connector_of(name, signal.point)
            if position in self._driven_connectors:
                raise self._feedthrough(name, what)
            self._sensed_connectors.add(position)
            entry = ChainSensor(name, signal.point, 0, True, position, "N")
        self.sensors[name] = entry
        return name

    def _connector_of(self, name: str, point: int) -> int:
        """Position of the lumped connector (no inertance) whose law gives the force sensed at ``point``."""
        chain = self.model
        element = chain.element(name.split(".")[0])
        position = chain.position(element.name)
        coefficients = element.lumped_coefficients()
        if coefficients is None or not coefficients.connector or coefficients.mass or \
                point not in (position - 1, position):
            raise ModelError(f"sensor {name!r}: on the ODE path of a chain a force sensor is the law force of a "
                             "lumped connector without inertance (a spring, damper or spring-damper); the force "
                             f"at a point element such as {element.name!r} depends on the accelerations (an algebraic "
                             "loop through the sweep): sense the force of the connector beside it, or use a "
                             "DT-TMM scheme (method='newmark', ...)")
        return position

    @staticmethod
    def _feedthrough(name: str, what: str) -> ModelError:
        return ModelError(f"{what} {name!r}: this connector is driven by an actuator, so its force includes the "
                          "actuator's own value (direct feedthrough) on the ODE path of a chain; sense another "
                          "connector, or use a DT-TMM scheme (method='newmark', ...)")

    def check_actuator(self, name: str, what: str = "actuator") -> str:
        """``name`` if it is an actuator, else a :class:`ModelError` listing the actuators."""
        if not isinstance(name, str) or name not in self.actuators:
            raise unknown_name(what, name, list(self.actuators))
        position = self.actuators[name].position
        chain = self.model
        element = chain.elements[position]
        if {position - 1, position} & self._massless_points:
            raise ModelError(f"{what} {name!r}: element {element.name!r} acts on a point without inertia, whose "
                             "position follows from its force balance (the ODE path would need the rate of the "
                             "actuator force); give the point a mass, or use a DT-TMM scheme (method='newmark', ...)")
        if not element.is_point:
            if position in self._sensed_connectors:
                raise self._feedthrough(f"{element.name}.f", f"sensor (driven by {what} {name!r})")
            self._driven_connectors.add(position)
        return name

    def values(self, sensors: list, q: np.ndarray, v: np.ndarray, t: float) -> np.ndarray:
        """Values of resolved ``sensors`` at the plant state ``(q, v)`` and ``t`` [s]."""
        x_nodes, v_nodes = self.point_kinematics(np.concatenate([q, v]), t)
        out = np.empty(len(sensors))
        for k, sensor in enumerate(sensors):
            if sensor.force:
                out[k] = self._law_force(sensor.position, x_nodes, v_nodes)
            else:
                out[k] = (x_nodes, v_nodes)[sensor.derivative][sensor.point]
        return out

    def point_kinematics(self, y: np.ndarray, t: float) -> tuple[np.ndarray, np.ndarray]:
        """Positions [m] and velocities [m/s] of every connection point at chain state ``y``."""
        dynamics = self.dynamics
        if dynamics.index_Q.size:
            x, v, _, wall = dynamics.kinematics(t, y)
            self._condensed = (t, y.copy(), x, v)         # not changed below (indexed copies)
        else:                           # no massless node to condense: the states and the held motion only
            m, n = dynamics.index_I.size, dynamics.tree.n_nodes
            x, v = np.zeros(n), np.zeros(n)
            x[dynamics.index_I], v[dynamics.index_I] = y[:m], y[m:2 * m]
            dynamics.hold(t, x, v)
            wall = dynamics.wall_motion(t)
        k = dynamics.node_of_point
        xp, vp = x[k], v[k]
        on_wall = k < 0
        xp[on_wall], vp[on_wall] = wall[0], wall[1]
        return xp, vp

    def condensed_at(self, t: float, y: np.ndarray) -> tuple[np.ndarray, np.ndarray] | None:
        """The node positions and velocities [m, m/s] of the massless-node condensation :meth:`point_kinematics` made
        at time ``t`` [s] and chain state ``y`` (the same numbers), else ``None``."""
        last = self._condensed
        if last is None or last[0] != t or not np.array_equal(last[1], y):
            return None
        return last[2], last[3]

    def _law_force(self, position: int, xp: np.ndarray, vp: np.ndarray) -> float:
        c = self.model.elements[position].lumped_coefficients()
        return -c.stiffness * (xp[position] - xp[position - 1] - c.free_length) - c.damping * (vp[position] - vp[position - 1])

    def inputs(self, values: Mapping[str, float]) -> dict[int, dict[str, float]]:
        """Actuator ``values`` ``{name: value}`` [N] as ``{element position: {input: value}}`` (summed)."""
        out: dict[int, dict[str, float]] = {}
        for name, value in values.items():
            actuator = self.actuators[self.check_actuator(name)]
            slot = out.setdefault(actuator.position, {})
            slot[actuator.input] = slot.get(actuator.input, 0.0) + float(value)
        return out


class ChainPlant:
    """A plain lumped :class:`~ctmm.system.Chain` (explicit context, :mod:`ctmm.chain_ode`) as a plant.

    Parameters
    ----------
    model : Chain or ControlledChain
        The chain; a :class:`~ctmm.control.loops.ControlledChain` is kept as :attr:`model` (the result's
        system) and integrated through its plant (the driver closes the loops it is given).
    """

    label = "chain"
    schemes = False
    signals_need_inputs = True

    def __init__(self, model: Any) -> None:
        chain = getattr(model, "plant", model)
        if not isinstance(chain, Chain):
            raise ModelError(f"model must be a ctmm.Chain or a ControlledChain, got {model!r}")
        self.model = model
        self.chain = chain
        self.dynamics = dynamics = ChainDynamics(chain)
        self.ports = ChainPorts(dynamics)
        self.n_positions = int(dynamics.index_I.size)
        self.n_velocities = self.n_positions + dynamics.n_r
        self.element_names = tuple(e.name for e in chain.elements)

    def start(self, x0: Mapping[str, float] | None, v0: Mapping[str, float] | None) -> tuple[np.ndarray, np.ndarray]:
        """``(q0, v0)`` at ``t = 0`` from initial positions / velocities by element name
        (:meth:`ctmm.chain_ode.ChainDynamics.consistent_start`)."""
        y = self.dynamics.consistent_start(0.0, x0, v0)
        return y[:self.n_positions], y[self.n_positions:]

    def position_rates(self, q: np.ndarray, v: np.ndarray) -> np.ndarray:
        return v[:self.n_positions]

    def accelerations(self, q: np.ndarray, v: np.ndarray, t: float, inputs: Any) -> np.ndarray:
        """``[a_I, z_r']`` at ``t`` [s] with the actuator ``inputs`` (:meth:`ChainPorts.inputs`); the massless nodes
        condensed by the sensors at the same ``(t, q, v)`` are reused (no actuator touches them, so their balance
        does not read the ``inputs``: :meth:`ChainPorts.check_actuator`)."""
        y = np.concatenate([q, v])
        return self.dynamics.rate(t, y, inputs, self.ports.condensed_at(t, y))[self.n_positions:]

    def signals(self, t: np.ndarray, q: np.ndarray, v: np.ndarray, outputs: Sequence[str],
                inputs: Sequence[Mapping[int, Mapping[str, float]]] | None = None) -> tuple[dict, dict]:
        """Every chain signal (``chain.signal_names()``, positions, forces, velocities, accelerations at
        the points; ``NaN`` accelerations at massless points) and the ``outputs``, with the actuator
        values ``inputs`` of every row (forces and accelerations depend on them)."""
        chain, count = self.chain, len(t)
        q, v = np.reshape(q, (count, self.n_positions)), np.reshape(v, (count, self.n_velocities))
        x, vel, acc, f = self.dynamics.point_values_rows(np.asarray(t, dtype=float), np.concatenate([q, v], axis=1),
                                                         inputs)
        signals, units = {}, {}
        for name in dict.fromkeys([*chain.signal_names(), *outputs]):
            signal = chain.signal(name)
            if signal.component == 0:
                signals[name] = (x, vel, acc)[signal.derivative][:, signal.point]
                units[name] = ("m", "m/s", "m/s^2")[signal.derivative]
            else:
                signals[name], units[name] = f[:, signal.point], "N"
        return signals, units

    def guard(self, q0: np.ndarray, bound: float | None, v0: np.ndarray | None = None, hint: str = ""
              ) -> Callable[[float, np.ndarray, float | None, str], None]:
        """The chain's divergence guard on the points that are states or held, and finiteness (``v0`` is
        accepted for the :class:`~ctmm.control.plants.Plant` protocol; a chain's bound is on positions; ``hint``
        appended to the message, :class:`~ctmm.guard.DivergenceGuard`)."""
        dynamics, chain = self.dynamics, self.chain
        guard, watched, size = self._divergence(q0, bound, hint)

        def check(t: float, y: np.ndarray, step: float | None, method: str) -> None:
            state = y[:size]
            if not np.isfinite(state).all():
                raise SimulationError(f"chain {chain.name!r}: non-finite state at t = {t:.6g} s ({method})",
                                      time=float(t), element=chain.name)
            guard.check(t, dynamics.point_positions(t, state)[watched])
        return check

    def guard_screen(self, q0: np.ndarray, bound: float | None, hint: str = ""
                     ) -> Callable[[np.ndarray, np.ndarray], np.ndarray]:
        """:meth:`guard` as one test of a block of stored rows: ``passes(times, rows)`` is True where the guard
        accepts the row (the rows it refuses go to :meth:`guard`, which raises with its message)."""
        guard, watched, size = self._divergence(q0, bound, hint)

        def passes(times: np.ndarray, rows: np.ndarray) -> np.ndarray:
            states = np.asarray(rows, dtype=float)[:, :size]
            positions = self.dynamics.point_positions_rows(np.asarray(times, dtype=float), states)
            return np.all(np.isfinite(states), axis=1) & guard.passes(positions[:, watched])
        return passes

    def _divergence(self, q0: np.ndarray, bound: float | None, hint: str) -> tuple[DivergenceGuard, np.ndarray, int]:
        """The guard on the watched points (those with a position without a sweep), the mask, the state size."""
        dynamics, chain = self.dynamics, self.chain
        y0 = np.concatenate([q0, np.zeros(self.n_velocities)])
        start = dynamics.point_positions(0.0, y0)
        watched = ~np.isnan(start)
        guard = DivergenceGuard.from_start([name for name, w in zip(point_labels(chain), watched) if w],
                                           rest_positions(chain)[watched], start[watched], bound=bound,
                                           hint=hint)
        return guard, watched, self.n_positions + self.n_velocities

    def check_step(self, q0: np.ndarray, v0: np.ndarray, dt: float, policy: str) -> None:
        """No pre-run step limit for chains on the ODE path (the run's guards apply, as without loops)."""
