"""ODE integrators for plain 1-D chains: the state equations from the explicit context of the one sweep.

``ctmm.simulate(chain, t_final, dt, method="rk4" | <solve_ivp method>)`` integrates a plain
:class:`~ctmm.system.Chain` of lumped elements as a first-order system built from the element terms
(:mod:`ctmm.lumped_forms`, ``d = 1``): the accelerations of the nodes with inertia are
:func:`~ctmm.lumped_forms.explicit_accelerations`, read once as certified affine rates (:mod:`ctmm.chain_affine`:
one sparse mat-vec per rate) where the chain has them, else one articulated sweep per rate evaluation.

Nodes (:class:`~ctmm.lumped_forms.LumpedTree`) fall in three kinds:

* **held** -- welded to a displacement-type start (``Fixed``: at rest at its ``position``;
  ``PrescribedDisplacement``: moving with its signal) or the ground of a displacement-type end;
* **inertial** -- a mass, or an inerter next to it (:func:`~ctmm.lumped_forms.node_inertia` > 0):
  position and velocity are states, the acceleration comes from the sweep;
* **massless** (``Q``) -- a connection point between connectors without inertance (or a zero-mass
  point element).  Its force balance ``F_Q(x, v, t) = 0`` is affine; its tangents
  ``Jx = dF_Q/dx_Q``, ``Jv = dF_Q/dv_Q = -C_QQ`` are read once from the terms (unit probes of the
  sweep, exact for these affine families).  With ``C_QQ = [P_r P_n] diag(c_r, 0) [P_r P_n]^T``
  (damping range and null space), the null part ``z_n = P_n^T x_Q`` is **algebraic** (``P_n^T
  F_Q = 0``, solved from ``P_n^T Jx P_n``: a node between springs) and the range part ``z_r =
  P_r^T x_Q`` is a **first-order state** (``z_r' = -(P_r^T Jv P_r)^-1 P_r^T F_Q(x, v_Q = 0)``: a
  node next to a damper).  Nodes with inertia never see ``P_n^T v_Q`` (``C_mQ P_n = 0``), so this is
  an index-1 system solved exactly, not a penalty or a small fictitious mass.

State ``y = [x_I, v_I, z_r]``.  The start is consistent (:meth:`ChainDynamics.consistent_start`):
massless nodes not given in ``x0`` start at the static balance under the given positions of their
neighbours (the chain held at ``x0`` and released at ``t0``), their velocities from the force
balance.  Stored accelerations of massless nodes are ``NaN`` (they are not states of the ODE).
"""
from __future__ import annotations

import time as clock
from typing import Any, Callable, Mapping, Sequence

import numpy as np

from . import validation
from .chain_start import initial_forces, initial_state, point_labels, point_of_element, rest_positions
from .elements.base import Element
from .errors import ModelError, SimulationError
from .guard import DivergenceGuard
from .lumped_forms import LumpedTree, explicit_accelerations, lumped_tree, massless_nodes
from .ode import output_grid, rk4_step
from .chain_affine import LinearRates, linear_rates
from .chain_point_rows import point_values_rows
from .closed_form_rates import signal_derivatives
from .results import SimulationResult
from .signals import Constant

__all__ = ["ChainDynamics", "chain_result", "simulate_chain_ode", "SCIPY_METHODS"]

SCIPY_METHODS = ("RK45", "RK23", "DOP853", "Radau", "BDF", "LSODA")
"""``solve_ivp`` methods accepted for chains (as for planar models)."""


class ChainDynamics:
    """The first-order system of a plain lumped chain (module docstring).

    Parameters
    ----------
    chain : Chain
        A plain chain of lumped 1-D elements (no loops, no beams).
    affine : bool
        Use the certified affine rates where the chain has them (:mod:`ctmm.chain_affine`); ``False``
        keeps one sweep per rate (:meth:`swept_rate`, the reference).
    balance_only : bool
        Skip the massless tangents (nonlinear connectors allowed): only :meth:`forces`, :meth:`inputs` and the nodes.

    Raises
    ------
    ModelError
        A chain that is not on the ``d = 1`` protocol, or massless nodes whose balance does not
        determine them (no spring and no damper holds them).  A prescribed motion (or a force on a
        massless node) without closed-form rates is refused when its rates are needed.
    """

    def __init__(self, chain, affine: bool = True, *, balance_only: bool = False) -> None:
        self.chain = chain
        self.tree: LumpedTree = lumped_tree(chain)
        tree = self.tree
        n = tree.n_nodes
        self.held = np.asarray(tree.grounded, dtype=bool)
        self.massless = massless_nodes(tree)
        self.inertial = ~self.held & ~self.massless
        self.index_I, self.index_Q = np.flatnonzero(self.inertial), np.flatnonzero(self.massless)
        self.loads = self._load_signals()
        start = chain.start
        self._start_motion = None
        if start.known == "displacement":
            self._start_motion = (signal_derivatives(start.name, "displacement", start.displacement)
                                  if hasattr(start, "displacement") else (lambda t, p=start.position: (p, 0.0, 0.0)))
        end = chain.end
        self.wall_motion = lambda t: (0.0, 0.0, 0.0)
        if end.known == "displacement":
            self.wall_motion = (signal_derivatives(end.name, "displacement", end.displacement)
                                 if hasattr(end, "displacement") else (lambda t, p=end.position: (p, 0.0, 0.0)))
        self.node_of_point = np.array([tree.node[b] if b >= 0 else -1 for b in tree.point_body])
        self._linear: LinearRates | None | bool = False if affine else None      # read on first use
        self.start_time = 0.0         # [s] of the run (consistent_start): user loads are called there, not before
        q = self.index_Q
        self.n_r = 0
        if q.size and not balance_only:   # balance_only: forces, inputs, nodes (massless_points.balanced_start)
            laws = [e.name for e in chain.body if hasattr(e, "law") and not e.is_point]
            if laws:                                # their tangents are read once below (affine families only)
                raise ModelError(f"chain {chain.name!r}: the ODE methods and compiled=True condense the massless "
                                 f"points with constant tangents, which the nonlinear connectors {laws} do not have; "
                                 "give the points next to them a mass, or use a DT-TMM scheme with compiled=False")
            self.Jx, self.Jv = self._massless_tangents()                   # rows: equations, columns: nodes
            damping = -0.5 * (self.Jv + self.Jv.T)
            values, vectors = np.linalg.eigh(damping)
            scale = float(np.max(np.abs(values), initial=0.0))
            in_range = values > 1e-10 * scale if scale > 0.0 else np.zeros(q.size, dtype=bool)
            self.P_r, self.P_n = vectors[:, in_range], vectors[:, ~in_range]
            self.n_r = int(in_range.sum())
            names = ", ".join(self.node_name(k) for k in q)
            S_n = self.P_n.T @ self.Jx @ self.P_n
            S_r = self.P_r.T @ self.Jv @ self.P_r
            for label, matrix in (("stiffness", S_n), ("damping", S_r)):
                if matrix.size and np.linalg.cond(matrix) > 1e12:
                    raise ModelError(f"chain {chain.name!r}: the massless nodes ({names}) are not determined by "
                                     f"their force balance (singular {label} of the massless part); give them a "
                                     "mass, or a spring or damper to a neighbour")
            self._S_n_inv = np.linalg.inv(S_n) if S_n.size else S_n
            self._S_r_inv = np.linalg.inv(S_r) if S_r.size else S_r
            self._check_massless_loads()

    # -- pieces -----------------------------------------------------------------------------
    def _massless_tangents(self) -> tuple[np.ndarray, np.ndarray]:
        """``dF_Q/dx_Q`` and ``dF_Q/dv_Q`` by unit probes of the sweep (the families are affine).

        A node's force depends on its own and its two neighbours' motion only (a serial tree), so three
        probes (nodes ``k = c mod 3`` moved together) give every column: 7 sweeps, batched.
        """
        n, q = self.tree.n_nodes, self.index_Q
        colours = np.arange(n) % 3
        probes = np.zeros((3, n))
        for c in range(3):
            probes[c, colours == c] = 1.0
        zero = np.zeros((1, n))
        x = np.concatenate([zero, probes, np.zeros((3, n))])
        v = np.concatenate([zero, np.zeros((3, n)), probes])
        forces = self.forces(x, v, 0.0, {}, (0.0, 0.0, 0.0))
        base = forces[0, q]
        row_of = {int(k): row for row, k in enumerate(q)}
        Jx, Jv = np.zeros((q.size, q.size)), np.zeros((q.size, q.size))
        for column, k in enumerate(q):
            c = colours[k]
            for j in (k - 1, k, k + 1):
                row = row_of.get(int(j))
                if row is not None:
                    Jx[row, column] = forces[1 + c, j] - base[row]
                    Jv[row, column] = forces[4 + c, j] - base[row]
        return Jx, Jv

    def node_name(self, k: int) -> str:
        """Names of the elements at node ``k`` (``"a/b"``)."""
        return "/".join(self.tree.bodies[j].name for j in range(len(self.tree.bodies)) if self.tree.node[j] == k)

    def _load_signals(self) -> list[tuple[int, str, Any, Element]]:
        """``(position, input name, signal, element)`` of every load the chain's elements carry."""
        chain, out = self.chain, []
        for position, element in enumerate(chain.elements):
            if position in (0, len(chain.elements) - 1):
                if element.known == "force" and hasattr(element, "force"):
                    out.append((position, "force", element.force, element))
            elif element.is_point and getattr(element, "inputs", ()):
                signal = getattr(element, "force", None)
                if signal is not None:
                    out.append((position, element.inputs[0], signal, element))
        return out

    def _check_massless_loads(self) -> None:
        """A varying force on a massless node: its velocity needs the force's rate (closed form)."""
        q, tree = set(self.index_Q.tolist()), self.tree
        self._load_rates = []
        for position, name, signal, element in self.loads:
            if isinstance(signal, Constant):
                continue
            if position == 0:
                body = 0
            elif position == len(self.chain.elements) - 1:
                body = len(tree.bodies) - 1
            else:
                body = tree.positions.index(position) if position in tree.positions else -1
            if body >= 0 and tree.node[body] in q:
                self._load_rates.append((position, name, signal_derivatives(element.name, name, signal)))

    def inputs(self, t: float, extra: Mapping[int, Mapping[str, float]] | None = None) -> dict[int, dict[str, float]]:
        """``{position: {input: value}}`` at ``t`` [s] for the explicit context (prescribed start: acceleration),
        with the ``extra`` actuator values [N] (loops, controllers; :mod:`ctmm.control.chain_plant`) added."""
        out: dict[int, dict[str, float]] = {}
        for position, name, signal, _ in self.loads:
            out.setdefault(position, {})[name] = float(signal(t))
        for position, values in (extra or {}).items():
            slot = out.setdefault(position, {})
            for name, value in values.items():
                slot[name] = slot.get(name, 0.0) + float(value)
        if self._start_motion is not None and hasattr(self.chain.start, "displacement"):
            out.setdefault(0, {})["displacement"] = self._start_motion(t)[2]
        return out

    def forces(self, x: np.ndarray, v: np.ndarray, t: float, inputs: Mapping, wall) -> np.ndarray:
        """Accelerations of the inertial nodes, forces [N] on the massless ones (explicit context)."""
        return explicit_accelerations(self.tree, x, v, t, inputs, wall=wall, massless="residual")

    def hold(self, t: float, x: np.ndarray, v: np.ndarray) -> None:
        """Put the held nodes of ``x``, ``v`` (``(..., n_nodes)``, in place) on the start's motion at ``t`` [s]."""
        if self._start_motion is not None:
            position, rate, _ = self._start_motion(t)
            x[..., self.held] = position
            v[..., self.held] = rate

    # -- the massless nodes ----------------------------------------------------------------
    def condense(self, t: float, x: np.ndarray, v: np.ndarray, inputs: Mapping, wall) -> None:
        """Fill the massless nodes of ``x``, ``v`` (shape ``(n_nodes,)``) in place: ``x_Q`` from its
        first-order part ``P_r P_r^T x_Q`` and the balance, ``v_Q`` from the balance and its rate."""
        q = self.index_Q
        if not q.size:
            return
        x[q] = self.P_r @ (self.P_r.T @ x[q])
        v[q] = 0.0
        residual = self.forces(x[None], v[None], t, inputs, wall)[0, q]
        if self.P_n.shape[1]:
            z_n = -self._S_n_inv @ (self.P_n.T @ residual)
            x[q] += self.P_n @ z_n
            residual = residual + self.Jx @ (self.P_n @ z_n)
        if self.n_r:
            v[q] = self.P_r @ (-self._S_r_inv @ (self.P_r.T @ residual))
        if self.P_n.shape[1]:
            v[q] += self.P_n @ self._algebraic_rate(t, x, v, wall)

    def _algebraic_rate(self, t: float, x: np.ndarray, v: np.ndarray, wall) -> np.ndarray:
        """``z_n'`` from ``d/dt P_n^T F_Q = 0``: the affine part of the forces at ``x = v`` (everything
        but the algebraic part), plus the rates of the loads on the massless nodes."""
        q = self.index_Q
        rate = v.copy()
        rate[q] = self.P_r @ (self.P_r.T @ v[q])
        rates_in: dict[int, dict[str, float]] = {}
        for position, name, derivatives in self._load_rates:
            rates_in.setdefault(position, {})[name] = derivatives(t)[1]
        pair_x = np.stack([rate, np.zeros_like(rate)])
        zero = np.zeros_like(pair_x)
        _, wall_rate, wall_second = wall
        walls = (np.array([wall_rate, 0.0]), np.zeros(2), np.zeros(2))
        forces = self.forces(pair_x, zero, t, {}, walls)
        linear = forces[0, q] - forces[1, q]
        if rates_in:
            loaded = self.forces(np.zeros((1, len(x))), np.zeros((1, len(x))), t, rates_in, (0.0, 0.0, 0.0))
            unloaded = self.forces(np.zeros((1, len(x))), np.zeros((1, len(x))), t, {}, (0.0, 0.0, 0.0))
            linear = linear + (loaded - unloaded)[0, q]
        return -self._S_n_inv @ (self.P_n.T @ linear)

    # -- the ODE -------------------------------------------------------------------------------
    def kinematics(self, t: float, y: np.ndarray, extra: Mapping[int, Mapping[str, float]] | None = None
                   ) -> tuple[np.ndarray, np.ndarray, dict, tuple]:
        """Node positions [m] and velocities [m/s] from the state ``y`` (massless nodes from their
        balance), with the inputs and the wall motion at ``t`` [s] they were computed with."""
        n, I, q = self.tree.n_nodes, self.index_I, self.index_Q
        x, v = np.zeros(n), np.zeros(n)
        x[I], v[I] = y[:I.size], y[I.size:2 * I.size]
        if self.n_r:
            x[q] = self.P_r @ y[2 * I.size:]
        self.hold(t, x, v)
        inputs, wall = self.inputs(t, extra), self.wall_motion(t)
        self.condense(t, x, v, inputs, wall)
        return x, v, inputs, wall

    def nodes(self, t: float, y: np.ndarray, extra: Mapping[int, Mapping[str, float]] | None = None,
              condensed: tuple[np.ndarray, np.ndarray] | None = None) -> tuple[np.ndarray, np.ndarray, np.ndarray]:
        """Node positions, velocities and accelerations (``NaN`` at massless nodes) from the state ``y``
        (``extra``: actuator values ``{position: {input: value}}`` [N] on top of the chain's own loads;
        ``condensed``: the node positions and velocities of :meth:`kinematics` at ``(t, y)`` without ``extra``,
        where no actuator of ``extra`` touches a massless node, whose balance then does not read them)."""
        q = self.index_Q
        if condensed is None:
            x, v, inputs, wall = self.kinematics(t, y, extra)
        else:
            x, v = condensed[0].copy(), condensed[1].copy()
            inputs, wall = self.inputs(t, extra), self.wall_motion(t)
        a = self.forces(x[None], v[None], t, inputs, wall)[0]
        a[q] = np.nan
        if self._start_motion is not None:
            a[self.held] = self._start_motion(t)[2]
        return x, v, a

    def rate(self, t: float, y: np.ndarray, extra: Mapping[int, Mapping[str, float]] | None = None,
             condensed: tuple[np.ndarray, np.ndarray] | None = None) -> np.ndarray:
        """``y' = [v_I, a_I, z_r']`` at ``t`` [s] (``extra`` and ``condensed`` as in :meth:`nodes`): the certified
        affine form (:mod:`ctmm.chain_affine`, one sparse mat-vec) where the chain has one, else :meth:`swept_rate`."""
        linear = self.linear
        if linear is not None:
            m = self.index_I.size
            return np.concatenate([y[m:2 * m], linear.accelerations(t, y[:m], y[m:2 * m], extra)])
        return self.swept_rate(t, y, extra, condensed)

    @property
    def linear(self) -> LinearRates | None:
        """The certified affine rates (:func:`ctmm.chain_affine.linear_rates`), ``None`` where the sweep stays."""
        if self._linear is False:
            self._linear = linear_rates(self, self.start_time)
        return self._linear

    def boundary_motion(self, t: float) -> tuple[float, float, float, float, float, float]:
        """Position [m], velocity [m/s], acceleration [m/s^2] of the held start points, then of the end's wall."""
        start = self._start_motion(t) if self._start_motion is not None else (0.0, 0.0, 0.0)
        return (*start, *self.wall_motion(t))

    def swept_rate(self, t: float, y: np.ndarray, extra: Mapping[int, Mapping[str, float]] | None = None,
                   condensed: tuple[np.ndarray, np.ndarray] | None = None) -> np.ndarray:
        """:meth:`rate` by one articulated sweep of the element terms (the reference of the affine form)."""
        I, q = self.index_I, self.index_Q
        x, v, a = self.nodes(t, y, extra, condensed)
        parts = [v[I], a[I]]
        if self.n_r:
            parts.append(self.P_r.T @ v[q])
        return np.concatenate(parts)

    def consistent_start(self, t0: float, x0: Mapping[str, float] | None, v0: Mapping[str, float] | None, *,
                         held_from_signals: bool = True) -> np.ndarray:
        """The state ``y`` at ``t0`` from ``x0``/``v0`` by element name (:func:`ctmm.chain_start.initial_state`).

        Massless nodes start at the static balance of the massless part under the given positions of
        the other nodes (velocities left out: the chain held at ``x0`` and released), least-squares
        minimal change where only dampers hold a node; their velocities then follow from the balance.
        ``held_from_signals=False`` keeps the held points where :func:`~ctmm.chain_start.initial_state`
        puts them (the DT-TMM paths start a prescribed support there).
        """
        x_points, v_points = initial_state(self.chain, x0, v0)
        n, I, q, self.start_time = self.tree.n_nodes, self.index_I, self.index_Q, float(t0)
        x, v = np.zeros(n), np.zeros(n)
        for p, k in enumerate(self.node_of_point):
            if k >= 0:
                x[k], v[k] = x_points[p, 0], v_points[p, 0]
        if held_from_signals:
            self.hold(t0, x, v)
        if q.size:
            inputs, wall = self.inputs(t0), self.wall_motion(t0)
            given = {name: int(self.node_of_point[point_of_element(self.chain, name)]) for name in (x0 or {})}
            given = {name: k for name, k in given.items() if k >= 0 and self.massless[k]}
            values = {k: x[k] for k in given.values()}
            still = np.zeros(n)
            residual = self.forces(x[None], still[None], t0, inputs, (wall[0], 0.0, 0.0))[0, q]
            x[q] += np.linalg.lstsq(self.Jx, -residual, rcond=None)[0]
            for k, value in values.items():                   # a given first-order part is an initial value
                x[k] = value
            if given:
                self._check_given(t0, x, v, given, values, inputs, wall)
        parts = [x[I], v[I]]
        if self.n_r:
            parts.append(self.P_r.T @ x[q])
        return np.concatenate(parts)

    def _check_given(self, t0: float, x: np.ndarray, v: np.ndarray, given: Mapping[str, int],
                     values: Mapping[int, float], inputs: Mapping, wall) -> None:
        """Refuse an ``x0`` of a massless point that its balance does not allow (its algebraic part)."""
        settled, rates = x.copy(), v.copy()
        self.condense(t0, settled, rates, inputs, wall)
        for name, k in given.items():
            if abs(settled[k] - values[k]) > 1e-9 * max(1.0, abs(values[k])):
                raise ModelError(f"x0[{name!r}] = {float(values[k])!r}: the point of {name!r} has no mass and its "
                                 "position follows from the force balance of the elements around it "
                                 f"({settled[k]:.9g} m under the other initial positions); leave it out of x0, or "
                                 "give it a mass")

    def held_points(self) -> list[tuple[np.ndarray, Callable[[float], tuple[float, float, float]]]]:
        """``(points, motion)`` of the displacement-type boundaries: the connection points held by the
        start and those on the end's wall, with ``motion(t) -> (x, v, a)`` (raises :class:`ModelError`
        when the signal has no closed-form rate)."""
        out = []
        if self._start_motion is not None:
            out.append((np.flatnonzero(np.isin(self.node_of_point, np.flatnonzero(self.held))), self._start_motion))
        if self.chain.end.known == "displacement" and np.any(self.node_of_point < 0):
            out.append((np.flatnonzero(self.node_of_point < 0), self.wall_motion))
        return out

    def start_points(self, t0: float, x0: Mapping[str, float] | None, v0: Mapping[str, float] | None
                     ) -> tuple[np.ndarray, np.ndarray]:
        """Positions and velocities ``(n_points, 1)`` of a DT-TMM start: :func:`~ctmm.chain_start.initial_state`
        with the massless points placed consistently (:meth:`consistent_start`, :meth:`condense`)."""
        x_points, v_points = initial_state(self.chain, x0, v0)
        if not self.index_Q.size:
            return x_points, v_points
        try:                                # the balance with a prescribed start where it is at t0 (closed forms)
            held = self._start_motion is not None and self._start_motion(t0) is not None
        except ModelError:
            held = False
        y = self.consistent_start(t0, x0, v0, held_from_signals=held)
        n, I, q = self.tree.n_nodes, self.index_I, self.index_Q
        x, v = np.zeros(n), np.zeros(n)
        for p, k in enumerate(self.node_of_point):
            if k >= 0:
                x[k], v[k] = x_points[p, 0], v_points[p, 0]
        if held:
            self.hold(t0, x, v)
        x[I], v[I] = y[:I.size], y[I.size:2 * I.size]
        if self.n_r:
            x[q] = self.P_r @ y[2 * I.size:]
        wall = self.wall_motion(t0) if self.chain.end.known == "displacement" else (0.0, 0.0, 0.0)
        self.condense(t0, x, v, self.inputs(t0), wall)
        massless_points = np.isin(self.node_of_point, q)
        x_points[massless_points, 0] = x[self.node_of_point[massless_points]]
        v_points[massless_points, 0] = v[self.node_of_point[massless_points]]
        return x_points, v_points

    def point_positions(self, t: float, y: np.ndarray) -> np.ndarray:
        """Positions [m] of the connection points, without a sweep (``(n_points,)``; ``NaN`` at the
        massless points, which the balance places between their neighbours)."""
        n, I, q = self.tree.n_nodes, self.index_I, self.index_Q
        x, v = np.zeros(n), np.zeros(n)
        x[I] = y[:I.size]
        x[q] = np.nan
        self.hold(t, x, v)
        out = x[self.node_of_point]
        out[self.node_of_point < 0] = self.wall_motion(t)[0]
        return out

    def boundary_motion_rows(self, times: np.ndarray) -> np.ndarray:
        """:meth:`boundary_motion` at every time [s] ``(rows,)``: ``(rows, 6)`` (one call when both supports stand
        still)."""
        times = np.asarray(times, dtype=float).reshape(-1)
        if not any(hasattr(boundary, "displacement") for boundary in (self.chain.start, self.chain.end)):
            return np.tile(np.array(self.boundary_motion(0.0), dtype=float), (times.size, 1))
        return np.array([self.boundary_motion(t) for t in times.tolist()], dtype=float).reshape(times.size, 6)

    def point_positions_rows(self, times: np.ndarray, states: np.ndarray) -> np.ndarray:
        """:meth:`point_positions` of stored rows at once: ``(rows, n_points)`` from ``times`` [s] ``(rows,)`` and
        ``states`` ``(rows, >= n_I)`` (the same numbers: copies of the states and the boundary motions)."""
        n, I, q = self.tree.n_nodes, self.index_I, self.index_Q
        motion = self.boundary_motion_rows(times)
        x = np.zeros((len(motion), n))
        x[:, I] = states[:, :I.size]
        x[:, q] = np.nan
        if self._start_motion is not None:
            x[:, self.held] = motion[:, [0]]
        out = x[:, self.node_of_point]
        out[:, self.node_of_point < 0] = motion[:, [3]]
        return out

    def point_values(self, t: float, y: np.ndarray, extra: Mapping[int, Mapping[str, float]] | None = None
                     ) -> tuple[np.ndarray, np.ndarray, np.ndarray, np.ndarray]:
        """Positions, velocities, accelerations and forces at every connection point (``(n_points,)`` each;
        ``extra`` as in :meth:`nodes`, acting on point elements and across connectors)."""
        x, v, a = self.nodes(t, y, extra)
        wall = self.wall_motion(t)
        k = self.node_of_point
        on_wall = k < 0
        xp, vp, ap = x[k], v[k], a[k]
        xp[on_wall], vp[on_wall], ap[on_wall] = wall
        a_for_forces = np.where(np.isnan(ap), 0.0, ap)            # massless: no inertia term
        across = {position: sum(values.values()) for position, values in (extra or {}).items()}
        forces = initial_forces(self.chain, xp[:, None], vp[:, None], across, a_for_forces[:, None], t)
        return xp, vp, ap, forces


    def point_values_rows(self, times: np.ndarray, states: np.ndarray,
                          extras: Sequence[Mapping[int, Mapping[str, float]] | None] | None = None
                          ) -> tuple[np.ndarray, np.ndarray, np.ndarray, np.ndarray]:
        """:meth:`point_values` of many rows (``(rows, n_points)`` each; ``extras`` per row), all at once
        (:func:`ctmm.chain_point_rows.point_values_rows`)."""
        return point_values_rows(self, times, states, extras)


def simulate_chain_ode(chain, t_final: float, dt: float | None, *, method: str = "rk4",
                       x0: Mapping[str, float] | None = None, v0: Mapping[str, float] | None = None,
                       t0: float = 0.0, rtol: float = 1e-8, atol: float = 1e-10, max_step: float | None = None,
                       store_every: int = 1, divergence_bound: float | None = None) -> SimulationResult:
    """Integrate a plain chain with fixed-step RK4 (:func:`ctmm.ode.rk4_step`) or a ``solve_ivp`` method.

    Parameters
    ----------
    chain : Chain
        Plain chain of lumped elements.
    t_final : float
        End time [s] (> ``t0``).
    dt : float or None
        RK4 step [s] (``t_final - t0`` a whole multiple); with a ``solve_ivp`` method the output grid
        ``t0 + k dt`` (``None``: the solver's own steps).
    method : str
        ``"rk4"`` or one of :data:`SCIPY_METHODS`.
    x0, v0 : mapping, optional
        Initial absolute positions [m] / velocities [m/s] by element name (as the DT-TMM path).
    t0 : float
        Start time [s].
    rtol, atol, max_step : float
        ``solve_ivp`` options.
    store_every : int
        RK4: keep every ``store_every``-th step (and the last).
    divergence_bound : float, optional
        Largest allowed distance [m] of any point from its rest position (default as the DT-TMM path).

    Returns
    -------
    SimulationResult
        The signals of the DT-TMM path of the same chain (positions, forces, velocities,
        accelerations at every point; ``NaN`` accelerations at massless points).

    Raises
    ------
    ModelError
        Bad input; SimulationError a non-finite or diverging state or a failed ``solve_ivp`` run, with
        the partial result.
    """
    t0, t_final = validation.finite("t0", t0), validation.finite("t_final", t_final)
    if t_final <= t0:
        raise ModelError(f"t_final must be > t0={t0}, got {t_final!r}")
    if method != "rk4" and method not in SCIPY_METHODS:
        raise ModelError(f"method for an ODE run of a chain must be 'rk4' or a solve_ivp method {SCIPY_METHODS}, "
                         f"got {method!r}")
    store_every = validation.integer("store_every", store_every, minimum=1)
    dynamics = ChainDynamics(chain)
    y = dynamics.consistent_start(t0, x0, v0)
    start_points = dynamics.point_positions(t0, y)
    watched = ~np.isnan(start_points)                              # the points that are states or held
    guard = DivergenceGuard.from_start([name for name, w in zip(point_labels(chain), watched) if w],
                                       rest_positions(chain)[watched], start_points[watched], bound=divergence_bound)
    times: list[float] = []
    states: list[np.ndarray] = []
    info: dict[str, Any] = {"method": method, "path": "ode-explicit-sweep"}

    def result() -> SimulationResult:
        return chain_result(dynamics, times, states, method, info)

    started = clock.perf_counter()
    if method == "rk4":
        if dt is None:
            raise ModelError("dt is required with method='rk4' (a fixed step [s], > 0), got None")
        dt = validation.positive("dt", dt)
        n_steps = int(round((t_final - t0) / dt))
        if n_steps < 1 or abs(n_steps * dt - (t_final - t0)) > 1e-9 * max(1.0, abs(t_final)):
            raise ModelError(f"(t_final - t0) = {t_final - t0!r} s must be a whole number of steps dt={dt!r} (>= 1)")
        validation.step_count(t_final, t0, dt, bytes_per_step=8.0 * len(y) / store_every)
        info["dt"] = dt
        times.append(t0)
        states.append(y.copy())
        for step in range(n_steps):
            t = t0 + step * dt
            try:
                y = rk4_step(dynamics.rate, t, y, dt)
                _check(dynamics, guard, t0 + (step + 1) * dt, y)
            except SimulationError as exc:
                exc.partial_result = exc.partial_result or result()
                raise
            if (step + 1) % store_every == 0 or step == n_steps - 1:
                times.append(t0 + (step + 1) * dt)
                states.append(y.copy())
    else:
        from scipy.integrate import solve_ivp

        if store_every != 1:
            raise ModelError(f"store_every={store_every!r} applies to method='rk4'; with {method!r} give dt as the "
                             "output grid (leave store_every at 1)")
        grid = None
        info.update(rtol=rtol, atol=atol)
        if dt is not None:
            dt = validation.positive("dt", dt)
            grid = output_grid(t0, t_final, dt)
            info["dt"] = dt
        options = {} if max_step is None else {"max_step": validation.positive("max_step", max_step)}
        solution = solve_ivp(dynamics.rate, (t0, t_final), y, method=method, t_eval=grid,
                             rtol=validation.positive("rtol", rtol), atol=validation.positive("atol", atol),
                             **options)
        times.extend(float(t) for t in solution.t)
        states.extend(solution.y.T)
        if not solution.success:
            raise SimulationError(f"chain {chain.name!r}: solve_ivp ({method}) failed: {solution.message}",
                                  time=times[-1] if times else t0, element=chain.name, partial_result=result())
        for i, (t, state) in enumerate(zip(times, states)):
            try:
                _check(dynamics, guard, t, state)
            except SimulationError as exc:
                del times[i:], states[i:]
                exc.partial_result = result()
                raise
    info["wall_time_s"] = clock.perf_counter() - started
    info["n_steps"] = len(times) - 1
    return result()


def _check(dynamics: ChainDynamics, guard: DivergenceGuard, t: float, y: np.ndarray) -> None:
    """The divergence guard on the positions of the points that are states or held (and finiteness of
    the whole state: a first-order massless part enters through ``y`` too)."""
    positions = dynamics.point_positions(t, y)
    watched = positions[~np.isnan(positions)]
    if not np.all(np.isfinite(y)):
        watched = np.full(watched.shape, np.nan)
    guard.check(t, watched)


def chain_result(dynamics: ChainDynamics, times: Sequence[float], states: Sequence[np.ndarray], method: str,
                 info: dict) -> SimulationResult:
    """The result of a plain chain run (point positions, forces, velocities, accelerations) from its states."""
    chain = dynamics.chain
    n_points = chain.n_points
    count = len(times)
    array = np.zeros((count, n_points, 2))
    velocity, acceleration = np.zeros((count, n_points, 1)), np.zeros((count, n_points, 1))
    if count:
        x, v, a, f = dynamics.point_values_rows(np.asarray(times, dtype=float), np.asarray(states, dtype=float))
        array[:, :, 0], array[:, :, 1], velocity[:, :, 0], acceleration[:, :, 0] = x, f, v, a
    return SimulationResult(np.asarray(times, dtype=float), array, velocity, acceleration, chain, method, dict(info))
