"""The closed-loop characteristic matrix of a planar (controlled) model and its exact derivatives.

A planar model (rigid bodies and modal beams; compilable, :func:`ctmm.compiled_parameters.compile_refusal`),
alone or closed by loops (:class:`~ctmm.control.controlled_model.ControlledModel`), is linearised as
:func:`ctmm.linearize` does, about its static equilibrium ``q*`` (``a(q*, 0, 0, p) = 0``, the default
operating point): ``x' = A x + B u``, ``x = [q, qdot]`` deviations, sensors ``y = C x``.  With the loops
``u_l = -K_l(s) c_l^T x``, ``K_l(s) = C_l(s) e^{-s tau_l}``,

    Delta(s) x = b F,      Delta(s) = s I - A + sum_l K_l(s) b_l c_l^T,

``b_l = B w_l`` (the loop's weighted actuators), ``c_l = C^T v_l`` (its weighted sensors), the same
form as a chain's (:mod:`ctmm.sensitivity_model`: ``M = 0``, ``C = I``, ``K = -A``), so every formula of
:mod:`ctmm.sensitivity` applies unchanged.  The plant numbers enter ``A``, ``B`` and (through ``q*``)
``C``:

* ``A``, ``B`` are Jacobians of the accelerations ``a(q, qdot, u, p)`` stated on casadi symbols with the
  model's numbers ``p`` as an input (:func:`ctmm.compiled_scene.symbolic_accelerations_with_inputs`, the
  expression the generated kernels compile); ``dA/dp``, ``dB/dp`` are their second derivatives by casadi's
  algorithmic differentiation -- exact, no differences;
* the operating point moves with ``p``: ``dq*/dp = -(da/dq)^{-1} da/dp`` (implicit function theorem on
  the static equilibrium), so ``dA/dp = partial_p A + partial_q A dq*/dp`` (likewise ``B``); a singular
  ``da/dq`` (a neutral equilibrium) is refused;
* sensor rows that are coordinates, rates or any sensor whose Jacobian does not change with ``q`` are
  constant; another sensor (a point position on a moving arm) is refused when ``q*`` moves with a
  requested parameter.

Parameters: ``"<body>.mass"`` [kg], ``"<body>.inertia"`` [kg m^2] (rigid bodies),
``"<hinge>.stiffness"`` [N m/rad], ``"<hinge>.damping"`` [N m s/rad] (an actuated hinge's ``kp``,
``kd``), and the loops' ``"<loop>.gain"``, ``"<loop>.delay"``, ``"<loop>.<sensor>"`` as for chains.
"""
from __future__ import annotations

import dataclasses
from typing import Any, Mapping, Sequence

import numpy as np

from . import validation
from .errors import ModelError, unknown_name
from .sensitivity_model import LoopCharacteristicMatrix, ParameterDerivative, controller_polynomials, loop_parameter

__all__ = ["PlanarCharacteristicMatrix", "equilibrium_motion", "is_planar_system", "selection",
           "planar_parameter_values", "planar_with_parameters"]


def is_planar_system(system: Any) -> bool:
    """True for a :class:`~ctmm.planar.model.PlanarModel` or a ``ControlledModel`` on one."""
    from .control.controlled_model import ControlledModel
    from .planar.model import PlanarModel

    return isinstance(system, PlanarModel) or (isinstance(system, ControlledModel)
                                               and isinstance(system.plant, PlanarModel))


def _split(system: Any) -> tuple[Any, tuple]:
    from .planar.model import PlanarModel

    return (system, ()) if isinstance(system, PlanarModel) else (system.plant, tuple(system.loops))


def _resolve(system: Any, names: Sequence[str]) -> tuple[list[ParameterDerivative], list[int]]:
    """Parameters of a planar system and the :func:`parameter_vector` index of each plant number (-1 else)."""
    from .compiled_parameters import compile_refusal, parameter_vector
    from .sensitivity_time import parameter_index

    model, loops = _split(system)
    reason = compile_refusal(model)
    if reason:
        raise ModelError(f"ctmm.sensitivity: the derivatives of a planar model are taken on its generated "
                         f"expression, and {reason}")
    p0 = parameter_vector(model)
    out, indices = [], []
    for name in names:
        if not isinstance(name, str) or "." not in name:
            raise ModelError(f"ctmm.sensitivity: parameter {name!r} must be '<body>.mass', '<body>.inertia', "
                             "'<hinge>.stiffness', '<hinge>.damping' or '<loop>.gain' / '<loop>.delay' / "
                             "'<loop>.<sensor>'")
        loop = loop_parameter(loops, name)
        if loop is not None:
            out.append(loop)
            indices.append(-1)
            continue
        k = parameter_index(model, name, p0)
        out.append(ParameterDerivative(name, "plant", None, -1, -1, float(p0[k])))
        indices.append(k)
    return out, indices


def planar_parameter_values(system: Any, names: Sequence[str]) -> dict[str, float]:
    """Current values of named parameters of a planar (controlled) model."""
    return {p.name: p.value for p in _resolve(system, names)[0]}


def _rebuilt_element(element: Any, tail: str, value: float) -> Any:
    """``element`` with its mass, inertia, stiffness or damping set (an actuated hinge's ``kp``, ``kd``)."""
    field = tail
    if not hasattr(element, field):
        field = {"stiffness": "kp", "damping": "kd"}.get(tail, tail)
    if not hasattr(element, field):
        raise ModelError(f"parameter '{element.name}.{tail}': a {type(element).__name__} has no {tail} to set")
    return dataclasses.replace(element, **{field: value})


def planar_with_parameters(system: Any, values: Mapping[str, float]) -> Any:
    """A copy of a planar (controlled) model with named parameters set (elements rebuilt, loops replaced).

    Raises
    ------
    ModelError
        Unknown names; values the elements refuse (a mass <= 0, ...), a negative delay.
    """
    from .planar.model import PlanarModel
    from .stability import with_loop_parameters

    parameters, _ = _resolve(system, list(values))
    model, _ = _split(system)
    elements = list(model.elements)
    per_loop: dict[str, dict] = {}
    for p in parameters:
        value = validation.finite(f"parameter {p.name!r}", values[p.name])
        head, _, tail = p.name.partition(".")
        if p.loop >= 0:
            per_loop.setdefault(head, {})[{"weight": tail}.get(p.kind, p.kind)] = value
            continue
        j = next(k for k, e in enumerate(elements) if getattr(e, "name", None) == head)
        elements[j] = _rebuilt_element(elements[j], tail, value)
    plant = PlanarModel(model.name, elements, gravity=model.gravity) if any(p.loop < 0 for p in parameters) \
        else model
    if plant is model and not per_loop:
        return system
    if isinstance(system, PlanarModel):
        return plant
    out = system.with_loops(system.loops) if plant is model else type(system)(plant, system.loops)
    for loop, changes in per_loop.items():
        out = with_loop_parameters(out, loop, changes)
    return out


def selection(size: int, indices: Sequence[int]) -> np.ndarray:
    """``(size, len(indices))``: column ``j`` the unit vector of entry ``indices[j]`` (zero for ``-1``)."""
    select = np.zeros((size, len(indices)))
    for j, index in enumerate(indices):
        if index >= 0:
            select[index, j] = 1.0
    return select


def equilibrium_motion(f_q: np.ndarray, f_p: np.ndarray, name: str, values: Sequence[float] = (),
                       tolerance: float = 0.0, neutral: bool = False) -> np.ndarray:
    """``dq*/dp = -(df/dq)^{-1} df/dp`` of a static equilibrium ``f(q*(p), p) = 0`` (implicit function theorem),
    zero for the parameters that do not move it: ``max |df/dp_j| |p_j| <= tolerance`` [acceleration] (round-off of
    an equilibrium that ``p_j`` does not load, e.g. a spring at its rest position).  ``neutral``: the caller has
    checked that nothing depends on the neutral directions of a singular ``df/dq``; the minimum-norm solution is
    then used when ``df/dp`` lies in the range of ``df/dq``.

    Raises
    ------
    ModelError
        A neutral equilibrium (``df/dq`` singular) that the parameters move (along a neutral direction, or at all
        without ``neutral``).
    """
    f_p = np.array(f_p, dtype=float)
    for j, value in enumerate(values):
        if np.max(np.abs(f_p[:, j]), initial=0.0) * abs(value) <= tolerance:
            f_p[:, j] = 0.0
    if not np.any(f_p):
        return np.zeros((f_q.shape[1], f_p.shape[1]))
    if np.linalg.cond(f_q) > 1e12:
        moving = [j for j in range(f_p.shape[1]) if np.any(f_p[:, j])]
        if neutral:
            motion = -np.linalg.lstsq(f_q, f_p, rcond=1e-12)[0]
            if np.max(np.abs(f_q @ motion + f_p)) <= 1e-9 * np.max(np.abs(f_p)):
                return motion
        raise ModelError(f"ctmm.sensitivity: the equilibrium of {name!r} is neutral (its acceleration Jacobian is "
                         f"singular, condition {np.linalg.cond(f_q):.2e}) and the parameters (positions {moving} in "
                         "the list) move it; its linearisation has no derivative")
    return -np.linalg.solve(f_q, f_p)


class PlanarCharacteristicMatrix(LoopCharacteristicMatrix):
    """``Delta(s) = s I - A + sum_l K_l b_l c_l^T`` of a planar (controlled) model (module docstring).

    Parameters
    ----------
    system : PlanarModel or ControlledModel (planar plant)
        Compilable; linearised about its static equilibrium (as :func:`ctmm.linearize` with the default
        operating point).
    parameters : sequence of str
        Plant numbers and loop parameters (module docstring).

    Raises
    ------
    ModelError
        A model that cannot be compiled, a parameter that is zero in the model (a constant of the
        generated expression), a neutral equilibrium, a sensor that moves with ``q*``, saturated loops.
    """

    def __init__(self, system: Any, parameters: Sequence[str] = ()) -> None:  # noqa: D107 -- class docstring
        import casadi as ca

        from .compiled_parameters import compiled_actuators, parameter_vector
        from .compiled_scene import symbolic_accelerations_with_inputs
        from .planar_linearization import EQUILIBRIUM_TOLERANCE, operating_point

        model, loops = _split(system)
        indices = self.bind(system, model, loops, _resolve(system, parameters), operating_point(model, None))
        n = model.n_coordinates
        self.n = 2 * n
        self.actuator_names = tuple(compiled_actuators(model))
        m, k = len(self.actuator_names), len(self.parameters)
        p0 = parameter_vector(model)
        select = selection(p0.size, indices)
        accelerations = symbolic_accelerations_with_inputs(model, self.actuator_names)
        q, v, u, d = ca.SX.sym("q", n), ca.SX.sym("v", n), ca.SX.sym("u", m), ca.SX.sym("d", k)
        a = accelerations(q, v, u, ca.DM(p0) + ca.DM(select) @ d, self.point.t)
        Jy, Ju = ca.jacobian(a, ca.vertcat(q, v)), ca.jacobian(a, u)
        terms = ca.Function("terms", [q, v, u, d], [
            Jy, Ju, ca.jacobian(a, d), ca.jacobian(ca.vec(Jy), q), ca.jacobian(ca.vec(Jy), d),
            ca.jacobian(ca.vec(Ju), q), ca.jacobian(ca.vec(Ju), d)])
        values = [np.asarray(x, dtype=float) for x in terms(self.point.q, np.zeros(n), np.zeros(m), np.zeros(k))]
        Jy, Ju, a_d, Jy_q, Jy_d, Ju_q, Ju_d = values
        # the equilibrium moves with p: a(q*(p), 0, 0, p) = 0 -> dq*/dp = -(da/dq)^-1 da/dp
        self.equilibrium_derivative = equilibrium_motion(
            Jy[:, :n], a_d, model.name, [p.value for p in self.parameters],
            1e-3 * EQUILIBRIUM_TOLERANCE * (1.0 + np.max(np.abs(model.gravity))))
        dq = self.equilibrium_derivative
        self.set_linearisation(Jy, Ju, Jy_d + Jy_q @ dq, Ju_d + Ju_q @ dq, self._sensor_row)

    def bind(self, system: Any, model: Any, loops: tuple, resolved: tuple[list, list[int]], point: Any) -> list[int]:
        """Hold the system, its plant, loops (saturated ones refused), parameters and operating point; the
        plant numbers' indices in the parameter column (-1 for loop numbers)."""
        from .saturation import refuse_saturation

        refuse_saturation(loops, "ctmm.sensitivity")
        self.system, self.model, self.loops, self.point = system, model, loops, point
        self.parameters = tuple(resolved[0])
        return resolved[1]

    def set_linearisation(self, J: np.ndarray, Ju: np.ndarray, dJ: np.ndarray, dJu: np.ndarray,
                          sensor_row: Any) -> None:
        """``A = [[0, I], J]``, ``B = [0 ; Ju]`` and their derivatives from ``dJ = d vec(J)/dp`` ``(n 2n, k)``,
        ``dJu = d vec(Ju)/dp`` (column-major vec), then the loops' ports (``sensor_row(name)`` a ``C`` row)."""
        n, m, k = J.shape[0], Ju.shape[1], len(self.parameters)
        self.A = np.block([[np.zeros((n, n)), np.eye(n)], [J]])
        self.B = np.vstack([np.zeros((n, m)), Ju])
        self.A_p = np.concatenate([np.zeros((n, 2 * n, k)), dJ.reshape(n, 2 * n, k, order="F")])    # (2n, 2n, k)
        self.B_p = np.concatenate([np.zeros((n, m, k)), dJu.reshape(n, m, k, order="F")])          # (2n, m, k)
        self.M, self.C, self.K = np.zeros((2 * n, 2 * n)), np.eye(2 * n), -self.A
        loops = self.loops
        self.controller_coefficients = [controller_polynomials(lp) for lp in loops]
        self.actuator_vectors = [sum(w * self.input_vector(name) for name, w in lp.actuator_terms) for lp in loops]
        self.sensor_terms = [[(sensor_row(sig), 0, w) for sig, w in lp.terms] for lp in loops]
        self.actuator_derivatives = [np.stack([sum(w * self.input_vector_p(name, i) for name, w in lp.actuator_terms)
                                               for i in range(k)]) if k else np.zeros((0, self.n)) for lp in loops]

    # -- ports ---------------------------------------------------------------------------------
    def _sensor_row(self, name: str) -> np.ndarray:
        """``C`` row of a sensor port or coordinate (``"<coordinate>_dot"`` a rate); refused when it
        changes with ``q`` while ``q*`` moves with a requested parameter."""
        from .planar_linearization import output_matrix

        row = output_matrix(self.model, [name], self.point)[0]
        moving = np.max(np.abs(self.equilibrium_derivative), initial=0.0) * \
            max([abs(p.value) for p in self.parameters] + [1.0]) > 1e-12
        if moving:
            shifted = self.point._replace(q=self.point.q + 0.1 * np.cos(np.arange(self.point.q.size) + 1.0))
            other = output_matrix(self.model, [name], shifted)[0]
            if not np.allclose(row, other, rtol=1e-12, atol=1e-12):
                raise ModelError(f"ctmm.sensitivity: sensor {name!r} of {self.model.name!r} depends on the "
                                 "configuration and the equilibrium moves with the parameters; its derivative is "
                                 "not implemented: use coordinates, their rates or hinge angles and rates")
        return row + 0j

    def input_vector(self, name: str) -> np.ndarray:
        """``b`` of an actuator port (a column of ``B``)."""
        if name not in self.actuator_names:
            raise unknown_name(f"input of {self.model.name!r} (actuator)", name, list(self.actuator_names))
        return self.B[:, self.actuator_names.index(name)] + 0j

    def input_vector_p(self, name: str, index: int) -> np.ndarray:
        """``db/dp`` of an actuator port."""
        if self.parameters[index].kind != "plant":
            return np.zeros(self.n, dtype=complex)
        return self.B_p[:, self.actuator_names.index(name), index] + 0j

    def output_row(self, name: str, s: complex) -> np.ndarray:
        """``c`` of a sensor port or coordinate (constant in ``s``: rates are states)."""
        return self._sensor_row(name)

    def actuator_p(self, index: int, loop: int) -> np.ndarray:
        """``db_l/dp`` (plant numbers move ``B``)."""
        return self.actuator_derivatives[loop][index] + 0j

    # -- Delta ---------------------------------------------------------------------------------
    def delta_p(self, s: complex, index: int, *, skip: int = -1) -> np.ndarray:
        """``dDelta/dp``: ``-dA/dp + sum_l K_l (db_l/dp c_l^T + b_l dc_l/dp^T)`` of a plant number; loops as
        for chains."""
        p = self.parameters[index]
        if p.kind != "plant":
            return super().delta_p(s, index, skip=skip)
        D = -self.A_p[:, :, index] + 0j
        for i in range(len(self.loops)):
            if i != skip:
                D += self.loop_gain(i, s)[0] * (np.outer(self.actuator_derivatives[i][index], self.sensor(i, s)[0])
                                                + np.outer(self.actuator_vectors[i], self.sensor_p(index, i, s)))
        return D

    def delay_free_roots(self) -> np.ndarray:
        """Eigenvalues of ``A - sum_l g_l b_l c_l^T`` (static gains, no delay)."""
        closed = self.A.astype(complex)
        for i, lp in enumerate(self.loops):
            closed -= float(lp.gain) * np.outer(self.actuator_vectors[i], self.sensor(i, 0.0)[0])
        return np.linalg.eigvals(closed)
