"""The linearisation terms of a spatial model and their derivatives, built once per model structure.

:class:`~ctmm.sensitivity_spatial.SpatialCharacteristicMatrix` needs, at a static equilibrium ``q*``, the
Jacobians of the accelerations ``f(q* (+) a (+) b, v, u, p)`` and their second derivatives (casadi's algorithmic
differentiation of the one articulated sweep, :func:`ctmm.compiled_spatial_loops.loop_acceleration` with the
model's numbers ``p`` as inputs), and the rows of its sensors.  Building these expressions costs about a second for
a small model; evaluating them, milliseconds.  :class:`SpatialTerms` states them as ``casadi.Function`` of the
equilibrium ``q*``, the numbers ``p`` and the time, so one build serves every model of the same structure: a
design loop (:func:`ctmm.control.tune`) or a difference check that changes gains, masses or stiffnesses pays the
build once and evaluates it with the new numbers.

:func:`spatial_terms` keeps the built terms in a small least-recently-used memo (a pure function of the structure;
no result depends on whether it was hit), keyed on :func:`structure_description`: the model described exactly
(:func:`ctmm.model_description.describe`, every number, the geometry, axes, loads, driven motions and zeros) with
the entries of its parameter layout (:func:`~ctmm.compiled_spatial_parameters.spatial_parameter_layout`, the
inputs ``p``) replaced by a marker, and the actuators (their port records).  Two models with one key state the
same expression of ``(q*, p, t)``; a model that cannot be described (``None``) is built every time.  Sensor rows are
kept per sensor record (name and its exact description) and stated with the ports of the system that asks.
"""
from __future__ import annotations

import collections
import copy
import threading
from typing import Any, Sequence

import numpy as np

from .sensitivity_planar import selection

__all__ = ["SpatialTerms", "spatial_terms", "structure_description", "symbolic_retraction"]

MEMO_SIZE = 8
"""Structures whose built terms :func:`spatial_terms` keeps (least recently used dropped first)."""


def _marked(element: Any, attribute: str, entry: tuple | None = None) -> Any:
    """A shallow copy of a frozen element with ``attribute`` (or its entry ``entry``) set to NaN (no validation:
    the copy is only described, never used)."""
    out = copy.copy(element)
    if entry is None:
        value: Any = float("nan")
    else:
        value = np.array(getattr(element, attribute), dtype=float)
        shape = value.shape
        value = value.reshape(-1) if len(entry) == 1 else value
        for index in ([entry] if len(entry) == 1 else [entry, entry[::-1]]):
            value[index] = float("nan")
        value = value.reshape(shape)
    object.__setattr__(out, attribute, value)
    return out


def structure_description(model: Any) -> bytes | None:
    """The exact description of a spatial model without the numbers of its parameter layout (module docstring):
    equal for models that differ only in entries of ``p``, ``None`` when some part cannot be described."""
    from .compiled_spatial_beam_numbers import BEAM_NUMBERS
    from .compiled_spatial_parameters import INERTIA_ENTRIES, spatial_parameter_layout
    from .model_description import describe

    beam_kinds = {kind for kind, _ in BEAM_NUMBERS}
    layout = spatial_parameter_layout(model)
    bodies, joints = list(model.bodies), list(model.joints)
    gravity = np.array(model.gravity, dtype=float)
    for entry in layout:
        j = entry.index
        if entry.kind in beam_kinds or entry.kind == "mass":
            bodies[j] = _marked(bodies[j], entry.kind)
        elif entry.kind == "inertia":
            _, a, b = INERTIA_ENTRIES[entry.entry]
            bodies[j] = _marked(bodies[j], "inertia", (a, b))
        elif entry.kind == "gravity":
            gravity[entry.entry] = float("nan")
        else:
            joints[j] = _marked(joints[j], entry.kind, (entry.entry,))
    return describe((type(model), model.name, bodies, joints, list(model.loads), gravity,
                     [entry.name for entry in layout]))


def _quaternion_exp(r: Any) -> list:
    """``exp(r)`` as ``[w, x, y, z]`` to third order in ``r`` (exact value, first and second derivatives at 0)."""
    theta2 = r[0] * r[0] + r[1] * r[1] + r[2] * r[2]
    half = 0.5 * (1.0 - theta2 / 24.0)
    return [1.0 - theta2 / 8.0, half * r[0], half * r[1], half * r[2]]


def _quaternion_product(a: Sequence[Any], b: Sequence[Any]) -> list:
    wa, xa, ya, za = a
    wb, xb, yb, zb = b
    return [wa * wb - xa * xb - ya * yb - za * zb, wa * xb + wb * xa + ya * zb - za * yb,
            wa * yb + wb * ya + za * xb - xa * zb, wa * zb + wb * za + xa * yb - ya * xb]


def symbolic_retraction(model: Any, q0: Any, delta: Any) -> Any:
    """``q0 (+) delta`` of :func:`ctmm.spatial_linearization.retract` on casadi symbols (columns ``nq``,
    ``nv``), the quaternion exponential to third order (module docstring)."""
    import casadi as ca

    from .ops import CASADI
    from .spatial.frames import quaternion_rotation

    q = [q0[i] for i in range(model.n_positions)]
    for joint, layout in zip(model.joints, model.layout):
        if joint.driven or joint.kind == "weld":
            continue
        start, d = layout.position.start, [delta[i] for i in range(layout.velocity.start, layout.velocity.stop)]
        if joint.kind == "spherical":
            q[start:start + 4] = _quaternion_product(q[start:start + 4], _quaternion_exp(d))
        elif joint.kind in ("free", "elastic6"):
            rotation = quaternion_rotation(CASADI, *q[start + 3:start + 7])
            moved = ca.mtimes(rotation, ca.vertcat(*d[:3]))
            q[start:start + 3] = [q[start + i] + moved[i] for i in range(3)]
            q[start + 3:start + 7] = _quaternion_product(q[start + 3:start + 7], _quaternion_exp(d[3:]))
        else:
            q[start:start + len(d)] = [q[start + i] + d[i] for i in range(len(d))]
    for layout in model.modal:                      # beams' modal coordinates: plain increments
        if layout is not None:
            q[layout.position] = [q[i] + delta[k] for i, k in zip(range(layout.position.start, layout.position.stop),
                                                                  range(layout.velocity.start, layout.velocity.stop))]
    return ca.vertcat(*q)


class SpatialTerms:
    """The linearisation terms of one spatial structure as casadi Functions of ``(q*, p, t)``.

    Parameters
    ----------
    model : SpatialModel
        Compilable, rigid bodies and modal beams (:func:`ctmm.sensitivity_spatial.check_differentiable`).
    ports : SpatialPorts
        Its sensors and actuators.
    actuators : sequence of str
        The port actuators, the columns of ``B`` (their order).
    indices : sequence of int
        Positions in the parameter layout of the differentiated numbers (``-1``: a loop number, zero column).
    """

    def __init__(self, model: Any, ports: Any, actuators: Sequence[str], indices: Sequence[int]) -> None:  # noqa: D107
        import casadi as ca

        from .compiled_spatial_loops import loop_acceleration
        from .compiled_spatial_parameters import spatial_parameter_layout

        nq, nv = model.n_positions, model.n_velocities
        layout = spatial_parameter_layout(model)
        m, k = len(actuators), len(indices)
        q0, p, t = ca.SX.sym("q0", nq), ca.SX.sym("p", len(layout)), ca.SX.sym("t")
        a, b, v, u, d = (ca.SX.sym(label, size) for label, size in (("a", nv), ("b", nv), ("v", nv), ("u", m),
                                                                  ("d", k)))
        q = symbolic_retraction(model, symbolic_retraction(model, q0, a), b)
        f = loop_acceleration(model, ports, tuple(actuators), layout)(q, v, u, p + ca.DM(selection(len(layout),
                                                                                                    indices)) @ d, t)
        x = ca.vertcat(b, v)
        J, Ju = ca.jacobian(f, x), ca.jacobian(f, u)
        self.terms = ca.Function("terms", [q0, p, t, a, b, v, u, d], [
            J, Ju, ca.jacobian(f, a), ca.jacobian(f, d), ca.jacobian(ca.vec(J), a), ca.jacobian(ca.vec(J), d),
            ca.jacobian(ca.vec(Ju), a), ca.jacobian(ca.vec(Ju), d)])
        self.sizes = (nv, m, k)
        self.model, self.symbols = model, (q0, q, a, x, v)
        self.rows: dict[Any, Any] = {}
        self.lock = threading.Lock()

    def linearisation(self, q: np.ndarray, p: np.ndarray, t: float) -> tuple[np.ndarray, ...]:
        """``J = df/dx``, ``Ju = df/du``, ``df/da``, ``df/dd``, ``d vec(J)/da``, ``d vec(J)/dd``, ``d vec(Ju)/da``,
        ``d vec(Ju)/dd`` at ``q* = q`` (positions), numbers ``p`` (the layout's values), time ``t`` [s]
        (``x = [b ; v]``, ``d`` the differentiated numbers; every increment zero)."""
        nv, m, k = self.sizes
        with self.lock:
            values = self.terms(q, p, t, np.zeros(nv), np.zeros(nv), np.zeros(nv), np.zeros(m), np.zeros(k))
        return tuple(np.asarray(value, dtype=float) for value in values)

    def sensor(self, name: str, ports: Any, q: np.ndarray) -> tuple[np.ndarray, np.ndarray]:
        """``(row, d row / da)`` of sensor port ``name`` of ``ports`` (the asking system's; its record is part of the
        memo key) at ``q* = q``: ``(2 nv,)``, ``(2 nv, nv)``.  A sensor is kinematic: the numbers of ``p`` do not
        enter it."""
        import casadi as ca

        from .compiled_spatial_loops import SpatialSymbols
        from .model_description import describe

        key = (name, describe(ports.sensors[name]))
        q0, q_symbol, a, x, v = self.symbols
        with self.lock:
            if key[1] is None or key not in self.rows:
                row = ca.jacobian(SpatialSymbols(self.model, ports).sensor(name, q_symbol, v), x)
                self.rows[key] = ca.Function("row", [q0, a, x], [row, ca.jacobian(row, a)])
            value, slope = self.rows[key](q, np.zeros(a.size1()), np.zeros(x.size1()))
        return np.asarray(value, dtype=float).reshape(-1), np.asarray(slope, dtype=float).reshape(-1, a.size1())


_MEMO: collections.OrderedDict = collections.OrderedDict()
_MEMO_LOCK = threading.Lock()


def spatial_terms(model: Any, ports: Any, actuators: Sequence[str], indices: Sequence[int]) -> SpatialTerms:
    """The :class:`SpatialTerms` of ``model``'s structure, built now or taken from the memo (module docstring)."""
    from .model_description import describe

    structure = structure_description(model)
    described = describe([ports.actuators[ports.check_actuator(name)] for name in actuators])
    if structure is None or described is None:
        return SpatialTerms(model, ports, actuators, indices)
    key = (structure, described, tuple(actuators), tuple(int(i) for i in indices))
    with _MEMO_LOCK:
        hit = _MEMO.get(key)
        if hit is not None:
            _MEMO.move_to_end(key)
            return hit
    built = SpatialTerms(model, ports, actuators, indices)
    with _MEMO_LOCK:
        _MEMO[key] = built
        while len(_MEMO) > MEMO_SIZE:
            _MEMO.popitem(last=False)
    return built
