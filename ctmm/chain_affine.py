"""The affine explicit rates of a lumped 1-D chain, read once from the sweep and certified (issue 13).

For the lumped families (mass, spring, damper, spring-damper, inerter, grounded spring and damper,
boundaries with a given force or motion) the accelerations of the nodes with inertia that the one
articulated sweep returns (:func:`ctmm.lumped_forms.explicit_accelerations`) are affine in everything
they depend on:

    a_I = Sx x_I + Sv v_I + a_0 + sum_j L_j s_j(t) + H m(t) + sum_k b_k u_k

with ``x_I, v_I`` the positions [m] and velocities [m/s] of those nodes, ``s_j(t)`` the time-varying
loads of the chain's elements [N] (constant loads are in ``a_0``), ``m(t) = (x_s, v_s, a_s, x_w, v_w,
a_w)`` the motion of the start's held points and of the end's wall [m, m/s, m/s^2], and ``u_k`` the
actuator inputs of loops, controllers or open-loop inputs [N] on the element inputs ``k``.

:class:`LinearRates` reads every matrix exactly from unit probes of the sweep (``Sx``, ``Sv`` banded:
three interleaved probes give the three diagonals of a chain whose nodes are coupled to their
neighbours only; a chain with inerters couples every node through its mass matrix, its matrices are
read column by column up to :data:`DENSE_LIMIT` nodes) and then **certifies** them against the
sweep at random states and inputs at the run's start time (relative 1e-10): a family whose terms are not affine, or a
coupling the probes did not see, is never used -- :func:`linear_rates` returns ``None`` and the
caller keeps the sweep.  A rate evaluation is then one sparse mat-vec, ``O(n)`` with no Python loop
over elements (:mod:`ctmm.chain_ode`, ``benchmarks/chain_ode_speed.py``).

Massless nodes (whose positions follow from a force balance, :mod:`ctmm.chain_ode`) keep the sweep.
"""
from __future__ import annotations

from typing import Any, Mapping, Sequence

import numpy as np
import scipy.sparse

from .signals import Constant

__all__ = ["LinearRates", "linear_rates", "DENSE_LIMIT"]

DENSE_LIMIT = 1500
"""Largest number of moving nodes whose coupled (inerter) rates are read column by column [-]."""

CERTIFY_TOLERANCE = 1e-10
"""Relative agreement of the affine form with the sweep required at every certification point [-]."""


class LinearRates:
    """The affine rates of a chain without massless nodes (module docstring).

    Parameters
    ----------
    dynamics : ChainDynamics
        The chain's first-order system (:class:`ctmm.chain_ode.ChainDynamics`), without massless nodes.
    banded : bool
        Read ``Sx``, ``Sv`` as tridiagonal (three probes) or column by column.

    Attributes
    ----------
    stiffness : scipy.sparse.csr_matrix or ndarray, shape (m, 2 m)
        ``[Sx Sv]`` [1/s^2, 1/s].
    constant : ndarray, shape (m,)
        ``a_0`` [m/s^2] with the constant loads.
    loads : list of (ndarray, signal)
        ``(L_j [1/kg], s_j)`` of the time-varying loads.
    motion : ndarray, shape (m, 6)
        ``H`` [1/s^2, 1/s, -, 1/s^2, 1/s, -].
    """

    def __init__(self, dynamics: Any, banded: bool = True) -> None:
        self.dynamics = dynamics
        n, I = dynamics.tree.n_nodes, dynamics.index_I
        self.index = I
        m = self.m = I.size
        self._columns: dict[tuple[int, str], np.ndarray] = {}
        held = dynamics.held.astype(float)
        motion_x = np.zeros((5, n))
        motion_x[0] = held
        motion_v = np.zeros((5, n))
        motion_v[1] = held
        walls = np.zeros((3, 5))
        walls[:, 2:] = np.eye(3)
        if banded:
            probes = np.zeros((3, n))
            colour = np.arange(n) % 3
            for c in range(3):
                probes[c, I[colour[I] == c]] = 1.0
            zeros, zero = np.zeros((3, n)), np.zeros((1, n))       # the base in the same sweep (row 0)
            wall = np.hstack([np.zeros((3, 7)), walls])
            forces = dynamics.forces(np.vstack([zero, probes, zeros, motion_x]),
                                     np.vstack([zero, zeros, probes, motion_v]),
                                     0.0, {}, (wall[0], wall[1], wall[2]))[:, I]
            self._base = forces[0]
            responses = forces[1:] - self._base
            self.stiffness = scipy.sparse.hstack([self._tridiagonal(responses[:3], colour[I]),
                                                  self._tridiagonal(responses[3:6], colour[I])]).tocsr()
            motion = responses[6:]
        else:
            zero_wall = (np.zeros(1), np.zeros(1), np.zeros(1))
            self._base = dynamics.forces(np.zeros((1, n)), np.zeros((1, n)), 0.0, {}, zero_wall)[0, I]
            columns = []
            for offset in range(0, 2 * m, 256):
                rows = np.arange(offset, min(offset + 256, 2 * m))
                x, v = np.zeros((rows.size, n)), np.zeros((rows.size, n))
                x[rows < m, I[rows[rows < m]]] = 1.0
                v[rows >= m, I[rows[rows >= m] - m]] = 1.0
                columns.append(self._responses(x, v, np.zeros((3, rows.size))))
            self.stiffness = np.vstack(columns).T
            motion = self._responses(motion_x, motion_v, walls)
        self.motion = np.zeros((m, 6))
        self.motion[:, [0, 1, 3, 4, 5]] = motion.T
        if held.any() and hasattr(dynamics.chain.start, "displacement"):
            self.motion[:, 2] = self.column(0, "displacement")
        self.constant = self._base.copy()
        varying = [(position, name, signal) for position, name, signal, _ in dynamics.loads
                   if not isinstance(signal, Constant)]
        constant = [(position, name, signal.value) for position, name, signal, _ in dynamics.loads
                    if isinstance(signal, Constant) and signal.value != 0.0]
        keys = [(position, name) for position, name, _ in varying + constant]
        for key, column in zip(keys, self._unit_columns(keys)):
            self._columns[key] = column
        self.loads = [(self._columns[(position, name)], signal) for position, name, signal in varying]
        for position, name, value in constant:
            self.constant += float(value) * self._columns[(position, name)]

    def _responses(self, x: np.ndarray, v: np.ndarray, wall: np.ndarray) -> np.ndarray:
        """Sweep responses minus the base, ``(rows, m)``, of node probes ``x``, ``v`` ``(rows, n)`` and wall
        motions ``wall`` ``(3, rows)`` (position, velocity, acceleration)."""
        return self.dynamics.forces(x, v, 0.0, {}, (wall[0], wall[1], wall[2]))[:, self.index] - self._base

    @staticmethod
    def _tridiagonal(responses: np.ndarray, colour: np.ndarray) -> scipy.sparse.csr_matrix:
        """``S`` from the responses of three interleaved probes: ``S[i, j] = responses[colour[j], i]``
        for ``|i - j| <= 1`` (nodes coupled to their neighbours only; certified afterwards)."""
        m = colour.size
        main = responses[colour, np.arange(m)]
        upper = responses[colour[1:], np.arange(m - 1)]
        lower = responses[colour[:-1], np.arange(1, m)]
        return scipy.sparse.diags([lower, main, upper], [-1, 0, 1], shape=(m, m), format="csr")

    def _unit_columns(self, keys: list[tuple[int, str]]) -> np.ndarray:
        """``(len(keys), m)``: the accelerations of a unit value of each input ``(position, name)``, one
        batched sweep."""
        rows, n = len(keys), self.dynamics.tree.n_nodes
        if not rows:
            return np.zeros((0, self.m))
        inputs: dict[int, dict[str, np.ndarray]] = {}
        for row, (position, name) in enumerate(keys):
            inputs.setdefault(position, {}).setdefault(name, np.zeros(rows))[row] = 1.0
        batched = {position: {name: unit[:, None, None] for name, unit in values.items()}
                   for position, values in inputs.items()}
        wall = (np.zeros(rows), np.zeros(rows), np.zeros(rows))
        return self.dynamics.forces(np.zeros((rows, n)), np.zeros((rows, n)), 0.0, batched, wall)[:, self.index] \
            - self._base

    def column(self, position: int, name: str) -> np.ndarray:
        """``b_k`` [1/kg]: the accelerations of a unit input ``name`` of the element at ``position`` (cached)."""
        key = (int(position), str(name))
        found = self._columns.get(key)
        if found is None:
            found = self._columns[key] = self._unit_columns([key])[0]
        return found

    def motion_values(self, t: float) -> np.ndarray:
        """``m(t)``: position, velocity and acceleration of the held start points and of the end's wall."""
        return np.array(self.dynamics.boundary_motion(t), dtype=float)

    def accelerations(self, t: float, x: np.ndarray, v: np.ndarray,
                      extra: Mapping[int, Mapping[str, float]] | None = None) -> np.ndarray:
        """``a_I`` [m/s^2] at ``t`` [s] from ``x_I``, ``v_I`` with the actuator inputs ``extra``
        ``{position: {input: value}}`` [N]."""
        out = self.stiffness @ np.concatenate([x, v]) + self.constant
        for column, signal in self.loads:
            out += column * float(signal(t))
        if self.motion.any():
            out += self.motion @ self.motion_values(t)
        if extra:
            for position, values in extra.items():
                for name, value in values.items():
                    if value != 0.0:
                        out += float(value) * self.column(position, name)
        return out

    def accelerations_rows(self, times: np.ndarray, states: np.ndarray, motion: np.ndarray,
                           extras: Sequence[Mapping[int, Mapping[str, float]] | None]) -> np.ndarray:
        """:meth:`accelerations` of many rows ``(rows, m)``: states ``[x_I, v_I]`` ``(rows, 2 m)`` at ``times`` [s],
        boundary motions ``m(t)`` ``(rows, 6)`` and the actuator inputs ``extras[i]`` of each row."""
        out = np.asarray((self.stiffness @ states.T).T) + self.constant + motion @ self.motion.T
        for column, signal in self.loads:
            out += np.outer([float(signal(t)) for t in times], column)
        for i, extra in enumerate(extras):
            for position, values in (extra or {}).items():
                for name, value in values.items():
                    out[i] += float(value) * self.column(position, name)
        return out

    def certify(self, trials: int = 2, seed: int = 12, time: float = 0.0) -> bool:
        """Whether the form equals the sweep (relative :data:`CERTIFY_TOLERANCE`) at ``trials`` random
        states and actuator inputs, at ``time`` [s]: the run's start, so that a user's load function is
        called only where the run calls it (random times outside the run once failed functions defined
        on the run's interval alone)."""
        dynamics, m = self.dynamics, self.m
        rng = np.random.default_rng(seed)
        chain = dynamics.chain
        driven = [(position, element.inputs[0]) for position, element in enumerate(chain.elements)
                  if 0 < position < len(chain.elements) - 1 and getattr(element, "inputs", ())]
        chosen = [[driven[int(index)] for index in rng.permutation(len(driven))[:3]] for _ in range(trials)]
        keys = list(dict.fromkeys(key for keys in chosen for key in keys if key not in self._columns))
        for key, column in zip(keys, self._unit_columns(keys)):
            self._columns[key] = column
        for keys in chosen:
            x, v = rng.standard_normal(m) * 0.01, rng.standard_normal(m) * 0.01
            t = time
            extra = {position: {name: float(rng.standard_normal())} for position, name in keys}
            swept = dynamics.swept_rate(t, np.concatenate([x, v]), extra)[m:]
            affine = self.accelerations(t, x, v, extra)
            scale = max(float(np.max(np.abs(swept), initial=0.0)), float(np.max(np.abs(affine), initial=0.0)),
                        1e-300)
            if not np.all(np.abs(swept - affine) <= CERTIFY_TOLERANCE * scale):
                return False
        return True


def linear_rates(dynamics: Any, time: float = 0.0) -> LinearRates | None:
    """The certified :class:`LinearRates` of ``dynamics`` (certified at ``time`` [s], :meth:`LinearRates.certify`),
    or ``None`` where the sweep must stay (massless nodes, connectors with a nonlinear law, rates that are not
    affine, inerter-coupled chains above :data:`DENSE_LIMIT` moving nodes)."""
    if dynamics.index_Q.size or any(hasattr(e, "law") and not e.is_point for e in dynamics.chain.body):
        return None
    for banded in (True, False):
        if not banded and dynamics.index_I.size > DENSE_LIMIT:
            return None
        form = LinearRates(dynamics, banded=banded)
        if form.certify(time=time):
            return form
    return None
