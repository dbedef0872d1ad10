"""The closed-loop characteristic matrix of a spatial (controlled) model and its exact derivatives.

A spatial model of rigid bodies and modal beams (:class:`~ctmm.spatial.model.SpatialModel`; compilable,
:func:`ctmm.compiled_spatial.spatial_compile_refusal`), alone or closed by loops
(``ctmm.control.with_feedback``), is linearised as :func:`ctmm.linearize` does
(:mod:`ctmm.spatial_linearization`): about the plant's static equilibrium ``q*``, in tangent coordinates
``x = [r ; v]`` (``q = q* (+) r``: angle increments, rotation vectors of spherical, free and elastic joints),
``x' = A x + B u``, sensors ``y = C x``.  With the loops ``u_l = -K_l(s) c_l^T x``,

    Delta(s) = s I - A + sum_l K_l(s) b_l c_l^T,      b_l = B w_l,  c_l = C^T v_l,

the form of :mod:`ctmm.sensitivity_planar`, so every formula of :mod:`ctmm.sensitivity` applies.  Here
``A``, ``B`` and ``C`` are Jacobians of the accelerations ``f(q* (+) a (+) b, v, u, p)`` and of the sensors
stated on casadi symbols: the one articulated sweep with the model's numbers ``p`` as inputs
(:func:`ctmm.compiled_spatial_loops.loop_acceleration` with a ``layout``; port actuators ``u``),
the sensors of :class:`ctmm.compiled_spatial_loops.SpatialSymbols`, and the retraction ``(+)`` on symbols
(quaternion exponential to third order: exact first and second derivatives at ``r = 0``).  Their
derivatives are casadi's algorithmic differentiation, no differences:

* ``dA/dp = partial_p A + partial_a A da*/dp`` with the equilibrium's tangent motion
  ``da*/dp = -(df/da)^{-1} df/dp`` (implicit function theorem), ``A`` at ``q* (+) a`` being the second
  derivative ``d^2 f / da db`` -- likewise ``B`` and every sensor row ``C`` (a sensor that depends on the
  configuration moves with the equilibrium: differentiated, not refused);
* at a neutral equilibrium (``df/da`` singular: a pendulum on a ball joint turns freely about the vertical)
  the library's equilibrium is the end of a search that may move along the neutral directions with the
  numbers: plant numbers are differentiated only when ``A``, the input's column of ``B`` and the output's row
  of ``C`` do not depend on those directions (else refused by name), with the minimum-norm ``da*/dp``;
* loop numbers as for chains (:mod:`ctmm.sensitivity_model`).

Parameters: the entries of :func:`ctmm.compiled_spatial_parameters.spatial_parameter_layout` --
``"<body>.mass"`` [kg], ``"<body>.inertia.xx"`` (``yy``, ``zz``, ``xy``, ``xz``, ``yz``; about the centre
of mass, body axes, the symmetric pair together) [kg m^2], ``"<joint>.stiffness"``, ``".damping"``,
``".reference"`` of revolute, prismatic and universal joints (``"[k]"`` appended on a universal joint),
``"gravity.x|y|z"`` [m/s^2], a :class:`~ctmm.spatial.beam.SpatialBeam`'s ``"<beam>.mass_per_length"`` [kg/m],
``".polar_inertia_per_length"`` [kg m], ``".bending_stiffness_y"``, ``".bending_stiffness_z"``,
``".torsional_stiffness"`` [N m^2], ``".axial_stiffness"`` [N], ``".damping_ratio"`` [-], ``".stiffness_damping"``
[s] (:mod:`ctmm.compiled_spatial_beam_numbers`; a beam's modal coordinates are plain tangent coordinates) -- and the
loops' ``"<loop>.gain"``, ``"<loop>.delay"``, ``"<loop>.<sensor>"``.  A number that is zero in the model is a
constant of the generated expression and is refused (give it a nonzero value); a beam's length, elastic-joint laws,
finite-element subsystems and geometry are not parameters.
"""
from __future__ import annotations

import dataclasses
from typing import Any, Mapping, Sequence

import numpy as np

from . import validation
from .errors import ModelError, unknown_name
from .sensitivity_model import ParameterDerivative, loop_parameter
from .sensitivity_planar import PlanarCharacteristicMatrix, equilibrium_motion
from .sensitivity_spatial_terms import spatial_terms, symbolic_retraction

__all__ = ["SpatialCharacteristicMatrix", "is_spatial_system", "spatial_parameter_index", "spatial_parameter_values",
           "spatial_with_parameters", "symbolic_retraction"]


def is_spatial_system(system: Any) -> bool:
    """True for a :class:`~ctmm.spatial.model.SpatialModel` or a ``ControlledModel`` on one."""
    from .control.controlled_model import ControlledModel
    from .spatial.model import SpatialModel

    return isinstance(system, SpatialModel) or (isinstance(system, ControlledModel)
                                                and isinstance(system.plant, SpatialModel))


def _split(system: Any) -> tuple[Any, tuple]:
    from .spatial.model import SpatialModel

    return (system, ()) if isinstance(system, SpatialModel) else (system.plant, tuple(system.loops))


def check_differentiable(model: Any, what: str = "ctmm.sensitivity", *, time_signals: bool = False) -> None:
    """Refuse (``ModelError``) a spatial model whose numbers are not parameters of a generated expression:
    one that cannot be compiled or that has finite-element subsystems.  ``time_signals``: loads and driven
    joints may carry :mod:`ctmm.signals` with a symbolic form (time runs state them on the time symbol);
    otherwise they must be constants (linearisations about one equilibrium)."""
    from .compiled_spatial import spatial_compile_refusal

    reason = spatial_compile_refusal(model, time_signals=time_signals)
    if reason:
        raise ModelError(f"{what}: the derivatives of a spatial model are taken on its generated expression, "
                         f"and {reason}")
    from .spatial.beam import SpatialBeam

    others = [body.name for body, layout in zip(model.bodies, model.modal)
              if layout is not None and not isinstance(body, SpatialBeam)]
    if others:
        raise ModelError(f"{what}: spatial model {model.name!r} has the finite-element subsystems {others}; the "
                         "derivatives are implemented for rigid bodies, modal beams (SpatialBeam) and 1-/2-DOF joint "
                         "laws (the numbers of ctmm.fem subsystems are not parameters of the generated expression)")


def spatial_parameter_index(model: Any, name: str) -> int:
    """Index of a named number in :func:`~ctmm.compiled_spatial_parameters.spatial_parameter_layout`.

    Raises
    ------
    ModelError
        A name that is not in the layout (with the allowed names; a number that is zero in the model is
        not in it: a constant of the expression).
    """
    from .compiled_spatial_parameters import spatial_parameter_layout

    names = [entry.name for entry in spatial_parameter_layout(model)]
    if name not in names:
        raise unknown_name(f"parameter of spatial model {model.name!r} (a number that is zero in the model is a "
                           "constant of the generated expression: give it a nonzero value)", name, names)
    return names.index(name)


def _resolve(system: Any, names: Sequence[str], *, time_signals: bool = False
             ) -> tuple[list[ParameterDerivative], list[int]]:
    """Parameters of a spatial system and the layout index of each plant number (-1 for loop numbers);
    ``time_signals`` as :func:`check_differentiable` (reading and setting numbers: any symbolic signal)."""
    from .compiled_spatial_parameters import spatial_parameter_layout

    model, loops = _split(system)
    check_differentiable(model, time_signals=time_signals)
    layout = spatial_parameter_layout(model)
    out, indices = [], []
    for name in names:
        if not isinstance(name, str) or "." not in name:
            raise ModelError(f"ctmm.sensitivity: parameter {name!r} must be '<body>.mass', '<body>.inertia.xx', "
                             "'<joint>.stiffness', '<joint>.damping', '<joint>.reference', 'gravity.z', "
                             "'<beam>.mass_per_length', '<beam>.bending_stiffness_y' (and the other beam numbers) or "
                             "'<loop>.gain' / '<loop>.delay' / '<loop>.<sensor>'")
        loop = loop_parameter(loops, name)
        if loop is not None:
            out.append(loop)
            indices.append(-1)
            continue
        k = spatial_parameter_index(model, name)
        out.append(ParameterDerivative(name, "plant", None, -1, -1, float(layout[k].value)))
        indices.append(k)
    return out, indices


def spatial_parameter_values(system: Any, names: Sequence[str]) -> dict[str, float]:
    """Current values of named parameters of a spatial (controlled) model."""
    return {p.name: p.value for p in _resolve(system, names, time_signals=True)[0]}


def _rebuilt(model: Any, changes: Mapping[int, float]) -> Any:
    """``model`` with layout entries ``{index: value}`` set (bodies, joints and gravity rebuilt)."""
    from .compiled_spatial_beam_numbers import BEAM_NUMBERS
    from .compiled_spatial_parameters import INERTIA_ENTRIES, spatial_parameter_layout
    from .spatial.model import SpatialModel

    beam_kinds = {kind for kind, _ in BEAM_NUMBERS}
    layout = spatial_parameter_layout(model)
    bodies, joints = list(model.bodies), list(model.joints)
    gravity = np.array(model.gravity, dtype=float)
    for k, value in changes.items():
        entry = layout[k]
        j = entry.index
        if entry.kind in beam_kinds:
            bodies[j] = dataclasses.replace(bodies[j], **{entry.kind: value})
        elif entry.kind == "mass":
            bodies[j] = dataclasses.replace(bodies[j], mass=value)
        elif entry.kind == "inertia":
            inertia = np.array(bodies[j].inertia, dtype=float)
            _, a, b = INERTIA_ENTRIES[entry.entry]
            inertia[a, b] = inertia[b, a] = value
            bodies[j] = dataclasses.replace(bodies[j], inertia=inertia)
        elif entry.kind == "gravity":
            gravity[entry.entry] = value
        else:
            numbers = np.array(getattr(joints[j], entry.kind), dtype=float).reshape(-1)
            numbers[entry.entry] = value
            joints[j] = dataclasses.replace(joints[j], **{entry.kind: numbers})
    return SpatialModel(model.name, bodies + joints + list(model.loads), gravity=gravity)


def spatial_with_parameters(system: Any, values: Mapping[str, float]) -> Any:
    """A copy of a spatial (controlled) model with named parameters set (elements rebuilt, loops replaced).

    Raises
    ------
    ModelError
        Unknown names; values the elements refuse (a mass <= 0, an inertia that is not positive definite,
        a negative stiffness, ...), a negative delay.
    """
    from .stability import with_loop_parameters

    parameters, indices = _resolve(system, list(values), time_signals=True)
    model, _ = _split(system)
    changes: dict[int, float] = {}
    per_loop: dict[str, dict] = {}
    for p, index in zip(parameters, indices):
        value = validation.finite(f"parameter {p.name!r}", values[p.name])
        if p.loop >= 0:
            head, _, tail = p.name.partition(".")
            per_loop.setdefault(head, {})[{"weight": tail}.get(p.kind, p.kind)] = value
        else:
            changes[index] = value
    plant = _rebuilt(model, changes) if changes else model
    if plant is model and not per_loop:
        return system
    if plant is not system and system is model:
        return plant
    out = system.with_loops(system.loops) if plant is model else type(system)(plant, system.loops)
    for loop, change in per_loop.items():
        out = with_loop_parameters(out, loop, change)
    return out


class SpatialCharacteristicMatrix(PlanarCharacteristicMatrix):
    """``Delta(s) = s I - A + sum_l K_l b_l c_l^T`` of a spatial (controlled) model (module docstring).

    Parameters
    ----------
    system : SpatialModel or ControlledModel (spatial plant)
        Rigid bodies and modal beams; compilable; linearised about the plant's static equilibrium.
    parameters : sequence of str
        Plant numbers and loop parameters (module docstring).

    Raises
    ------
    ModelError
        Finite-element subsystems, a model that cannot be compiled, a parameter that is zero in the model, a neutral
        equilibrium that moves with a parameter, saturated loops, rotation-vector sensors.
    """

    def __init__(self, system: Any, parameters: Sequence[str] = ()) -> None:  # noqa: D107 -- class docstring
        from .compiled_spatial_parameters import spatial_parameter_vector
        from .spatial.ports import SpatialPorts
        from .planar_linearization import EQUILIBRIUM_TOLERANCE
        from .spatial_linearization import operating_point, tangent_names

        model, loops = _split(system)
        indices = self.bind(system, model, loops, _resolve(system, parameters), operating_point(model, None))
        ports = system.ports if loops else SpatialPorts(model)
        nv = model.n_velocities
        self.n = 2 * nv
        self.actuator_names = tuple(ports.actuators)
        m = len(self.actuator_names)
        self.ports, self.tangent_names = ports, tuple(tangent_names(model)) + tuple(model.velocities)
        # built once per structure (ctmm.sensitivity_spatial_terms), evaluated at this model's q*, numbers and time
        self.terms = spatial_terms(model, ports, self.actuator_names, indices)
        J, Ju, f_a, f_d, J_a, J_d, Ju_a, Ju_d = self.terms.linearisation(self.point.q, spatial_parameter_vector(model),
                                                                          self.point.t)
        self._refuse_neutral(f_a, [J_a], J, indices)
        self.input_slopes, self.checked_inputs = Ju_a.reshape(m, nv, nv), set()       # d B[:, j] / da per input j
        self.equilibrium_derivative = equilibrium_motion(            # (nv, k): the equilibrium's tangent motion
            f_a, f_d, model.name, [p.value for p in self.parameters],
            1e-3 * EQUILIBRIUM_TOLERANCE * (1.0 + np.max(np.abs(model.gravity))), neutral=True)
        da = self.equilibrium_derivative
        self.rows: dict[str, tuple[np.ndarray, np.ndarray]] = {}
        self.set_linearisation(J, Ju, J_d + J_a @ da, Ju_d + Ju_a @ da, lambda name: self.output_row(name, 0.0))

    def _refuse_neutral(self, f_a: np.ndarray, slopes: Sequence[np.ndarray], J: np.ndarray, indices: Sequence[int]
                        ) -> None:
        """Refuse plant numbers at a neutral equilibrium (``df/dr`` singular) whose linearisation depends on the
        neutral directions: there the equilibrium the library finds (a search from the neutral configuration)
        moves along them with the numbers in a path-dependent way, so the verbs' linearisation has no derivative."""
        self.neutral = np.zeros((f_a.shape[1], 0))
        if not any(index >= 0 for index in indices) or not f_a.size:
            return
        _, sigma, Vh = np.linalg.svd(f_a)
        self.neutral = Vh[sigma <= 1e-12 * max(float(sigma[0]), 1e-300)].T
        for slope in slopes:
            self._check_neutral(slope, max(float(np.max(np.abs(J), initial=0.0)), 1.0), "its linearisation")

    def _check_neutral(self, slope: np.ndarray, scale: float, what: str) -> None:
        """Refuse when ``slope`` (``d vec(X) / da``) moves along the neutral directions (relative 1e-8 of ``scale``)."""
        if not self.neutral.size:
            return
        moved = float(np.max(np.abs(slope.reshape(-1, self.neutral.shape[0]) @ self.neutral), initial=0.0))
        if moved > 1e-8 * scale:
            raise ModelError(f"ctmm.sensitivity: the equilibrium of {self.model.name!r} is neutral in "
                             f"{self.neutral.shape[1]} direction(s) and {what} depends on them; the static equilibrium "
                             "is found by a search from the neutral configuration that moves along them with the "
                             "numbers, so it has no derivative in the plant numbers: add a restoring spring or gravity "
                             "to make the equilibrium isolated (loop numbers are differentiated)")

    def input_vector(self, name: str) -> np.ndarray:
        """``b`` of an actuator port (a column of ``B``; refused at a neutral equilibrium that moves it)."""
        column = super().input_vector(name)
        if name not in self.checked_inputs:
            self._check_neutral(self.input_slopes[self.actuator_names.index(name)],
                                max(float(np.max(np.abs(column))), 1e-300), f"input {name!r}")
            self.checked_inputs.add(name)
        return column

    def _sensor(self, name: str) -> tuple[np.ndarray, np.ndarray] | None:
        """``(row, d row / dp)`` (``(2 nv,)``, ``(2 nv, k)``) of a sensor port stated on symbols, its row moving
        with the equilibrium; ``None`` for a name that is not a sensor port."""
        if name not in self.ports.sensors:
            return None
        if name not in self.rows:
            if self.ports.sensors[name].kind == "rotation":
                raise ModelError(f"ctmm.sensitivity: sensor {name!r} is a rotation-vector component, not stated on "
                                 f"symbols; use the x-y-z angles '{name.split('.')[0]}.angle_x|y|z' or a tangent "
                                 "coordinate")
            value, slope = self.terms.sensor(name, self.ports, self.point.q)
            self._check_neutral(slope, max(float(np.max(np.abs(value))), 1.0), f"sensor {name!r}")
            self.rows[name] = (value, slope @ self.equilibrium_derivative if len(self.parameters)
                               else np.zeros((self.n, 0)))
        return self.rows[name]

    # -- ports ---------------------------------------------------------------------------------
    def output_row(self, name: str, s: complex) -> np.ndarray:
        """``c`` of a sensor port or a tangent coordinate / velocity (constant in ``s``)."""
        sensor = self._sensor(name)
        if sensor is not None:
            return sensor[0] + 0j
        if name in self.tangent_names:
            row = np.zeros(self.n, dtype=complex)
            row[self.tangent_names.index(name)] = 1.0
            return row
        raise unknown_name(f"output of {self.model.name!r} (sensor port or tangent coordinate / velocity)", name,
                           list(self.ports.sensors) + list(self.tangent_names))

    def output_row_p(self, name: str, s: complex, index: int) -> np.ndarray:
        """``dc/dp`` of an output: a sensor row moves with the equilibrium."""
        sensor = self._sensor(name)
        if sensor is not None and self.parameters[index].kind == "plant":
            return sensor[1][:, index] + 0j
        return np.zeros(self.n, dtype=complex)

    def sensor_p(self, index: int, loop: int, s: complex) -> np.ndarray:
        """``dc_l/dp``: the weights' as for chains, a plant number's through the sensor rows."""
        if self.parameters[index].kind != "plant":
            return super().sensor_p(index, loop, s)
        return sum((w * self.output_row_p(sig, s, index) for sig, w in self.loops[loop].terms),
                   np.zeros(self.n, dtype=complex))
