"""Affine rates of 1-D chains with massless points and prescribed boundary motion, for the generated RK4 (issue 13).

:func:`ctmm.compiled_chain.affine_form` reads the accelerations of a chain whose every moving point has a mass and
whose supports stand still.  :func:`condensed_affine_form` reads the whole rate of the Python ODE path
(:meth:`ctmm.chain_ode.ChainDynamics.swept_rate`) of any plain lumped chain on that path: the state is that path's
``y = [x_I, v_I, z_r]`` (positions and velocities of the masses, the first-order part ``z_r`` of the massless
nodes next to dampers), and

``[a_I; z_r'] = Ax x_I + Av [v_I; z_r] + a0 + sum_j L_j s_j(t)``

with the condensation of the massless nodes inside (:meth:`~ctmm.chain_ode.ChainDynamics.condense`: the same
call, on unit probes) and the time terms ``s_j`` the varying loads and the prescribed motion of the start and
the end wall -- position, velocity and acceleration, in closed form as the Python path needs them
(:func:`ctmm.closed_form_rates.signal_derivatives`: a :class:`~ctmm.signals.Constant` or
:class:`~ctmm.signals.Harmonic` motion; the velocity and acceleration of ``a sin(w t + p)`` are the harmonics
``a w sin(w t + p + pi/2)`` and ``a w^2 sin(w t + p + pi)``; a :class:`~ctmm.signals.Ramp` from ``start <= 0``
moves at its constant slope, without acceleration).  The probes are exact because every step is affine
in the state and the time terms; :class:`ctmm.compiled_chain.CompiledChain` certifies the form against the Python
sweep at random states and times before generating anything.  Without massless nodes the form is that of the
certified rates of the ODE path (:mod:`ctmm.chain_affine`: tridiagonal, sparse, ``O(n)`` probes; the motion's
columns ``H`` carry the time slots); with them, one probe of the condensation and sweep per state (``O(n)`` sweeps,
the condensation itself dense).

Refused (:class:`~ctmm.errors.ModelError`, named): a prescribed motion without closed-form rates (a
:class:`~ctmm.signals.Step`, :class:`~ctmm.signals.SquareWave`, a ramp starting after t = 0 or a user callable), a
varying load on a massless node (its rate enters the balance).
"""
from __future__ import annotations

import math
from dataclasses import dataclass
from typing import Any, Mapping, Sequence

import numpy as np
import scipy.sparse

from .chain_affine import LinearRates
from .chain_ode import ChainDynamics
from .errors import ModelError
from .signals import Constant, Harmonic, Ramp

__all__ = ["AffineRates", "condensed_affine_form", "needs_condensed_form"]


@dataclass(frozen=True)
class AffineRates:
    """``a = Ax x_I + Av v + B u + a0 + sum_j L_j s_j(t)`` of a lumped chain
    (:func:`ctmm.compiled_chain.affine_form`, :func:`condensed_affine_form`): ``Ax`` [1/s^2] (r, m), ``Av``
    [1/s] (r, r), ``B`` (r, actuators) [1/kg], ``a0`` [m/s^2] (r,), ``loads`` ``[(L_j (r,), signal s_j)]``;
    ``m`` masses, ``r = m`` (or ``m + n_r`` with first-order massless parts: ``v = [v_I; z_r]``).  ``certified``:
    ``Ax``, ``Av``, ``a0`` and the loads were already certified against the sweep at random states and times
    (:func:`ctmm.chain_affine.linear_rates`); ``B`` is certified by the callers."""

    Ax: Any
    Av: Any
    B: np.ndarray
    a0: np.ndarray
    loads: list
    certified: bool = False


def needs_condensed_form(dynamics: ChainDynamics) -> bool:
    """Whether the chain has massless nodes or a prescribed (signal) start or end motion."""
    chain = dynamics.chain
    moving = any(hasattr(boundary, "displacement") for boundary in (chain.start, chain.end))
    return bool(dynamics.index_Q.size) or moving


def _motion(boundary: Any) -> tuple[list[float], list[tuple[int, Any]]]:
    """``(constant (3,), [(slot, signal)])`` of a displacement-type boundary's position, velocity, acceleration."""
    signal = getattr(boundary, "displacement", None)
    if signal is None:
        return [float(boundary.position), 0.0, 0.0], []
    if isinstance(signal, Constant):
        return [float(signal.value), 0.0, 0.0], []
    if isinstance(signal, Harmonic):
        a, w, p = signal.amplitude, signal.omega, signal.phase
        return [0.0, 0.0, 0.0], [(0, signal), (1, Harmonic(a * w, w, p + 0.5 * math.pi)),
                                 (2, Harmonic(a * w * w, w, p + math.pi))]
    if isinstance(signal, Ramp) and signal.start <= 0.0:
        return [0.0, 0.0, 0.0], [(0, signal), (1, signal.rate())]
    raise ModelError(f"{boundary.name}: the displacement signal {signal!r} has no closed-form velocity and "
                     "acceleration, which the generated RK4 needs (as the Python ODE path); give a Constant, "
                     "Harmonic or Ramp signal (a ramp with start <= 0), or use a DT-TMM scheme (method='newmark', ...)")


def _check_massless_loads(dynamics: ChainDynamics) -> None:
    """Refuse a varying load on a massless node (the balance's rate needs the load's rate)."""
    chain, tree = dynamics.chain, dynamics.tree
    massless = set(dynamics.index_Q.tolist())
    for position, name, signal, element in dynamics.loads:
        if isinstance(signal, Constant):
            continue
        if position == 0:
            body = 0
        elif position == len(chain.elements) - 1:
            body = len(tree.bodies) - 1
        else:
            body = tree.positions.index(position) if position in tree.positions else -1
        if body >= 0 and tree.node[body] in massless:
            raise ModelError(f"chain {chain.name!r}: the varying {name!r} load {signal!r} of {element.name!r} acts on "
                             "a point without inertia, whose balance needs the load's rate; generated kernels do not "
                             "take it: give the point a mass, or use compiled=False")


class _Probe:
    """The rate of :meth:`ChainDynamics.swept_rate` with the time terms given as numbers (``slots``: the loads'
    values, then the start's and the end wall's position, velocity, acceleration)."""

    def __init__(self, dynamics: ChainDynamics) -> None:
        self.dynamics = dynamics
        self.n_loads = len(dynamics.loads)
        chain = dynamics.chain
        self.start = chain.start.known == "displacement"
        self.start_input = hasattr(chain.start, "displacement")
        self.wall = chain.end.known == "displacement"

    def rate(self, y: np.ndarray, slots: np.ndarray, extra: Mapping[int, Mapping[str, float]]) -> np.ndarray:
        dynamics = self.dynamics
        n, I, q = dynamics.tree.n_nodes, dynamics.index_I, dynamics.index_Q
        m, L = I.size, self.n_loads
        x, v = np.zeros(n), np.zeros(n)
        x[I], v[I] = y[:m], y[m:2 * m]
        if dynamics.n_r:
            x[q] = dynamics.P_r @ y[2 * m:]
        if self.start:                                        # as ChainDynamics.hold
            x[dynamics.held], v[dynamics.held] = slots[L], slots[L + 1]
        inputs: dict[int, dict[str, float]] = {}              # as ChainDynamics.inputs
        for j, (position, name, _, _) in enumerate(dynamics.loads):
            inputs.setdefault(position, {})[name] = float(slots[j])
        for position, values in extra.items():
            slot = inputs.setdefault(position, {})
            for name, value in values.items():
                slot[name] = slot.get(name, 0.0) + float(value)
        if self.start_input:
            inputs.setdefault(0, {})["displacement"] = float(slots[L + 2])
        wall = tuple(float(value) for value in slots[L + 3:L + 6]) if self.wall else (0.0, 0.0, 0.0)
        dynamics.condense(0.0, x, v, inputs, wall)
        a = dynamics.forces(x[None], v[None], 0.0, inputs, wall)[0]
        parts = [a[I]]
        if dynamics.n_r:
            parts.append(dynamics.P_r.T @ v[q])
        return np.concatenate(parts)


def condensed_affine_form(dynamics: ChainDynamics, actuators: Sequence[Mapping[int, Mapping[str, float]]] = ()
                          ) -> AffineRates:
    """The rates ``[a_I; z_r']`` of a plain lumped chain as :class:`AffineRates` on ``x_I`` and ``v = [v_I; z_r]``
    (module docstring): unit probes of the Python path's condensation and sweep, one per state, actuator
    (``actuators``: unit inputs ``{position: {input: 1}}``) and time term.

    Raises
    ------
    ModelError
        A prescribed motion without closed-form rates, a varying load on a massless node.
    """
    chain = dynamics.chain
    _check_massless_loads(dynamics)
    probe = _Probe(dynamics)
    L = probe.n_loads
    constant = np.zeros(L + 6)
    terms: list[tuple[int, Any]] = []
    for j, (_, _, signal, _) in enumerate(dynamics.loads):
        if isinstance(signal, Constant):
            constant[j] = signal.value
        else:
            terms.append((j, signal))
    for offset, boundary, used in ((L, chain.start, probe.start), (L + 3, chain.end, probe.wall)):
        if used:
            values, varying = _motion(boundary)
            constant[offset:offset + 3] = values
            terms += [(offset + slot, signal) for slot, signal in varying]
    m = dynamics.index_I.size
    linear = None if dynamics.index_Q.size else dynamics.linear
    if linear is not None:
        return _from_linear_rates(linear, probe, constant, terms, actuators)
    size = 2 * m + dynamics.n_r
    zero = np.zeros(size)
    base = probe.rate(zero, constant, {})
    columns = []
    for i in range(size):
        unit = zero.copy()
        unit[i] = 1.0
        columns.append(probe.rate(unit, constant, {}) - base)
    Ax = np.array(columns[:m]).reshape(m, size - m).T
    Av = np.array(columns[m:]).reshape(size - m, size - m).T
    B = (np.column_stack([probe.rate(zero, constant, unit) - base for unit in actuators]) if len(actuators)
         else np.zeros((size - m, 0)))
    loads = []
    for slot, signal in terms:
        moved = constant.copy()
        moved[slot] += 1.0
        loads.append((probe.rate(zero, moved, {}) - base, signal))
    return AffineRates(Ax, Av, B, base, loads)


def _from_linear_rates(linear: LinearRates, probe: _Probe, constant: np.ndarray, terms: list[tuple[int, Any]],
                       actuators: Sequence[Mapping[int, Mapping[str, float]]]) -> AffineRates:
    """:func:`condensed_affine_form` of a chain without massless nodes from its certified rates
    (:mod:`ctmm.chain_affine`: ``a = Sx x + Sv v + a_0 + sum_j L_j s_j + H m(t)``, tridiagonal, ``O(n)``): the time
    slots ``constant`` / ``terms`` (loads, then the start's and the wall's position, velocity, acceleration) on
    ``L_j`` and the columns of ``H``."""
    m, L = linear.m, probe.n_loads
    stiffness = scipy.sparse.csc_matrix(linear.stiffness)
    Ax, Av = scipy.sparse.csr_matrix(stiffness[:, :m]), scipy.sparse.csr_matrix(stiffness[:, m:])
    motion = np.zeros(6)
    for offset, used in ((0, probe.start), (3, probe.wall)):
        if used:
            motion[offset:offset + 3] = constant[L + offset:L + offset + 3]
    a0 = linear.constant + linear.motion @ motion
    varying = iter(linear.loads)
    loads = [(next(varying)[0] if slot < L else linear.motion[:, slot - L], signal) for slot, signal in terms]

    def column(inputs: Mapping[int, Mapping[str, float]]) -> np.ndarray:
        return sum((float(value) * linear.column(position, name) for position, values in inputs.items()
                    for name, value in values.items()), np.zeros(m))

    B = np.column_stack([column(unit) for unit in actuators]) if len(actuators) else np.zeros((m, 0))
    return AffineRates(Ax, Av, B, a0, loads, certified=True)
