"""Exact-field frequency form of a straight planar chain with beams (``fields="exact"``).

About a straight rest configuration (no loads, no spin, every hinge at zero relative angle,
beams undeformed; gravity only along the chain) a serial planar chain vibrates transversely as a bending
chain (layout :data:`~ctmm.layouts.BENDING`, ``w`` transverse to the chain, ``theta`` the
small rotation); its axial motion decouples at first order.  :func:`exact_form` converts

* the base: ``Fixed`` ground with a revolute hinge -> :class:`~ctmm.elements.bending.BeamPinned`
  (``w = 0``, ``moment = 0``) then the hinge law ``k + c s`` as a grounded
  :class:`~ctmm.elements.bending.BeamSpring` and its torque input as a point moment;
  a driven / welded base hinge -> :class:`~ctmm.elements.bending.BeamClamped`;
* a revolute hinge between bodies -> :class:`~ctmm.elements.bending_bodies.RevoluteJoint`
  (law ``k + c s``, torque input); a welded / driven one -> continuity;
* a rigid body -> :class:`~ctmm.elements.bending_bodies.RigidSegment` (mass, inertia and centre
  of mass on the axis);
* a :class:`~ctmm.flexible.ModalBeam` -> exact :class:`~ctmm.elements.beams.BeamField` pieces
  (``EI``, ``rhoA``, Kelvin-Voigt ``stiffness_damping``) between its named stations and ends,
  with a :class:`~ctmm.elements.bending.BeamPointLoad` at each (station force and moment inputs);
* the free outboard end -> :class:`~ctmm.elements.bending.BeamFree`;
* gravity ``g_a`` along the chain (``> 0`` hanging, ``< 0`` standing; :mod:`ctmm.elements.bending_preload`):
  the tension ``T = g_a m_outboard`` makes every beam piece a
  :class:`~ctmm.elements.bending_preload.VaryingTensionBeamField` (linear ``T(x)``, error-controlled
  sixth-order Magnus field) and adds after each rigid segment a
  :class:`~ctmm.elements.bending_preload.GeometricMoment` ``k_g = T_out l + m g_a a`` (the
  pendulum terms of the linearisation); a standing chain needs its straight ``operating_point``
  (the default equilibrium search starts hanging);

and maps the ports (:mod:`ctmm.planar.ports`) to weighted chain signals and inputs: body
angles and rates, hinge angles and rates, the transverse point coordinates (``y``/``vy`` of a
chain along x, ``x``/``vx`` of a chain along y), beam station signals (in the beam's frame:
``w(x) - w_root - x theta_root`` and ``theta(x) - theta_root``), hinge torques, body forces
(their transverse part) and moments, station forces and moments.  :class:`~ctmm.control.Feedback`
loops are mapped term by term and closed by the chain's extended-state sweep with exact delays.

Refused (:class:`~ctmm.errors.ModelError`): trees and mid-span branches, free or translational
bases, gravity with a component across the chain (named; the equilibrium is not straight), loads or modal hooks (preload / no field counterpart), modal damping ratios,
section rotary inertia (the planar field is Euler-Bernoulli), kinked or moving operating points, free hinges between bodies (no transfer matrix), and ports
without an exact-field counterpart (modal coordinates, axial point coordinates, beam centres
of mass).
"""
from __future__ import annotations

import time
from dataclasses import dataclass
from typing import Any, Sequence

import numpy as np

from . import validation
from .errors import ModelError
from .saturation import refuse_saturation
from .loop_phasors import close_loops, loop_signal
from .results import FrequencyResponse
from .signal_units import loop_units

__all__ = ["ExactForm", "exact_form", "form_response", "frequency_response", "ExactResponse",
           "natural_frequencies"]

#: Largest hinge angle [rad], modal coordinate and rate counted as zero at the operating point.
STRAIGHT_TOLERANCE = 1e-9
#: Largest transverse gravity component, relative to ``|g|``, counted as zero.
GRAVITY_ALIGNMENT = 1e-12

Terms = list[tuple[str, float]]


@dataclass(frozen=True)
class ExactForm:
    """A planar chain as a bending chain of exact fields, with its port map.

    Attributes
    ----------
    chain : ctmm.Chain
        The uncontrolled bending chain.
    sensors : dict of str to list of (str, float)
        Planar sensor name -> weighted chain signals (an empty list: identically zero).
    actuators : dict of str to list of (str, float)
        Planar actuator name -> weighted chain inputs.
    refused : dict of str to str
        Ports without an exact-field counterpart -> the reason.
    """

    chain: Any
    sensors: dict
    actuators: dict
    refused: dict

    def sensor(self, name: str) -> Terms:
        """Chain signal terms of planar sensor ``name`` (or a :class:`ModelError`)."""
        return self._lookup(name, self.sensors, "sensor")

    def actuator(self, name: str) -> Terms:
        """Chain input terms of planar actuator ``name`` (or a :class:`ModelError`)."""
        return self._lookup(name, self.actuators, "actuator")

    def _lookup(self, name: str, table: dict, what: str) -> Terms:
        if name in table:
            return table[name]
        if name in self.refused:
            raise ModelError(f"{what} {name!r} has no exact-field counterpart: {self.refused[name]}; use the "
                             "modal form (fields='modal')")
        raise ModelError(f"unknown {what} {name!r} of the exact-field form; available: {', '.join(sorted(table))}")


def _refuse(model: Any, reason: str) -> ModelError:
    return ModelError(f"fields='exact' cannot convert model {model.name!r}: {reason}")


def _check_model(model: Any, operating_point: Any) -> tuple[float, float]:
    """The chain direction ``theta_0`` [rad] and the axial gravity ``g_a`` [m/s^2] (along the chain,
    outward) of a straight, resting serial chain loaded at most by gravity along its axis."""
    from .planar.model import BUSHING, FREE
    from .planar_linearization import operating_point as planar_operating_point

    nb = model.n_bodies
    if not np.array_equal(model.parent, np.arange(-1, nb - 1)):
        raise _refuse(model, "it is not a serial chain (a tree: a body with several children, or several bases)")
    if np.any(model.joint_kind == FREE):
        raise _refuse(model, "its base is free (a floating chain): only a grounded base is supported")
    if np.any(model.joint_kind == BUSHING):
        names = [model.joint_names[j] for j in np.flatnonzero(model.joint_kind == BUSHING)]
        raise _refuse(model, f"hinges {names} have translational springs")
    if model.nonlinear_hinges:
        raise _refuse(model, f"hinges {[model.joint_names[j] for j in model.nonlinear_hinges]} have nonlinear laws "
                             "(use the linearised fields, the default)")
    if len(model.load_body):
        raise _refuse(model, "its bodies carry loads (a preload; the exact form has no load terms)")
    for i in range(nb):
        if i in model.beams:
            _check_beam(model, model.bodies[i])
        else:
            _check_body_geometry(model, i)
    op = planar_operating_point(model, operating_point)
    theta, omega = model.body_angles(op.q, op.qdot, op.t)
    relative, _ = model.relative_angles(theta, omega, op.q, op.qdot)
    axial = _axial_gravity(model, float(theta[0]))
    modal = np.concatenate([op.q[index] for index in model.modal_index]) if nb else np.zeros(0)
    if (np.max(np.abs(relative[1:]), initial=0.0) > STRAIGHT_TOLERANCE
            or np.max(np.abs(modal), initial=0.0) > STRAIGHT_TOLERANCE):
        stretch = " (a beam with axial modes stretches under gravity: give n_axial_modes=0)" if axial else ""
        raise _refuse(model, f"the operating point is not straight and undeformed (hinge angles "
                             f"{np.round(relative, 12).tolist()} rad, modal coordinates {modal.tolist()}){stretch}")
    if np.max(np.abs(op.qdot), initial=0.0) > STRAIGHT_TOLERANCE or np.max(np.abs(omega), initial=0.0) > 0.0:
        raise _refuse(model, "the operating point moves (a spin or a driven motion)")
    return float(theta[0]), axial


def _axial_gravity(model: Any, theta0: float) -> float:
    """Gravity's component along the chain direction ``theta_0`` [m/s^2], or a refusal if it has a
    transverse one (the equilibrium would not be straight)."""
    g = np.asarray(model.gravity, dtype=float)
    c, s = np.cos(theta0), np.sin(theta0)
    transverse = float(-s * g[0] + c * g[1])
    if abs(transverse) > GRAVITY_ALIGNMENT * float(np.linalg.norm(g)):
        raise _refuse(model, f"gravity = {g.tolist()} m/s^2 has a component {transverse:.6g} m/s^2 transverse to the "
                             f"straight chain (direction {theta0:.6g} rad): its equilibrium is not straight; only "
                             "gravity along the chain (hanging or standing) is allowed")
    return float(c * g[0] + s * g[1])


def _check_body_geometry(model: Any, i: int) -> None:
    name = model.body_names[i]
    off_axis = [e for e, p in model.ends[i].items() if p[1] != 0.0]
    if model.com[i][1] != 0.0 or off_axis:
        raise _refuse(model, f"body {name!r} has its centre of mass or ends {off_axis} off its axis (y != 0 in "
                             "its frame): its transverse and axial motions couple")


def _check_beam(model: Any, beam: Any) -> None:
    from .flexible import ModalBeam
    if not isinstance(beam, ModalBeam):
        raise _refuse(model, f"body {beam.name!r} is a {type(beam).__name__}; only ModalBeam has an exact field")
    if beam.damping_ratio:
        raise _refuse(model, f"beam {beam.name!r} has a modal damping ratio {beam.damping_ratio!r} (no field "
                             "counterpart; use stiffness_damping, Kelvin-Voigt)")
    if beam.modal_forces:
        raise _refuse(model, f"beam {beam.name!r} has modal-force hooks (modal laws; use Feedback loops on "
                             "station ports instead)")
    if beam.loads or any(getattr(f, "value", None) != 0.0 for f in beam.distributed_load):
        raise _refuse(model, f"beam {beam.name!r} carries loads (a preload)")
    if beam.rotary_inertia_per_length:
        raise _refuse(model, f"beam {beam.name!r} has section rotary inertia {beam.rotary_inertia_per_length!r} kg m "
                             "(the planar bending field is Euler-Bernoulli; the spatial SpatialBeam's exact field has "
                             "the Rayleigh term)")


class _Builder:
    """Walks a checked serial chain and collects the bending elements and the port map."""

    def __init__(self, model: Any, theta0: float, axial_gravity: float = 0.0) -> None:
        self.model = model
        self.gravity = axial_gravity
        masses = np.asarray(model.mass, dtype=float)
        # mass outboard of each body's child attachment [kg]
        self.outboard_mass = [float(np.sum(masses[i + 1:])) for i in range(model.n_bodies)]
        self.elements: list = []
        self.sensors: dict[str, Terms] = {}
        self.actuators: dict[str, Terms] = {}
        self.refused: dict[str, str] = {}
        c, s = np.cos(theta0), np.sin(theta0)
        # global transverse components: delta y = c w (needs s = 0), delta x = -s w (needs c = 0)
        self.axis = {"y": c if abs(s) < 1e-12 else None, "x": -s if abs(c) < 1e-12 else None}
        self.force_weight = {"force_x": -s, "force_y": c}

    def marker(self, name: str):
        from .elements.bending import BeamPointLoad
        self.elements.append(BeamPointLoad(name))
        return name

    def point(self, body: str, point: str, terms: Terms) -> None:
        """Point sensors ``<body>.<point>.x|y|vx|vy`` from the transverse terms ``w``."""
        for axis in ("x", "y"):
            factor = self.axis[axis]
            for part, suffix in ((axis, ""), (f"v{axis}", "_dot")):
                label = f"{body}.{point}.{part}"
                if factor is None:
                    self.refused[label] = "an axial component of the straight chain (axial motion is not modelled)"
                else:
                    self.sensors[label] = [(f"{signal}{suffix}", factor * weight) for signal, weight in terms]

    def build(self) -> ExactForm:
        from .elements.bending import BeamClamped, BeamFree, BeamPinned, BeamSpring
        from .elements.bending_bodies import RevoluteJoint
        from .planar.model import DRIVEN
        from .system import Chain

        model = self.model
        previous_end = None                      # chain signal of the parent's attachment point
        for i, body in enumerate(model.body_names):
            hinge = model.joint_names[i]
            k, c = float(model.stiffness[i]), float(model.damping[i])
            welded = model.joint_kind[i] == DRIVEN
            if i == 0:
                self.elements.append((BeamClamped if welded else BeamPinned)(f"{hinge}__base"))
                if not welded and (k or c):
                    self.elements.append(BeamSpring(f"{hinge}__law", 0.0, k, rotational_damping=c))
            elif not welded:
                if not (k or c):
                    raise _refuse(model, f"hinge {hinge!r} between bodies is free (no stiffness or damping): a free "
                                         "joint inside the chain has no transfer matrix")
                self.elements.append(RevoluteJoint(hinge, stiffness=k, damping=c))
            root = self.marker(f"{body}__root")
            if not welded:
                torque = f"{root}.moment" if i == 0 else f"{hinge}.torque"
                self.actuators[f"{hinge}.torque"] = [(torque, 1.0)]
            angle = [(f"{root}.theta", 1.0)] + ([] if i == 0 else [(previous_end, -1.0)])
            self.sensors[f"{hinge}.angle"] = [] if welded else angle
            self.sensors[f"{hinge}.rate"] = [] if welded else [(f"{n}_dot", w) for n, w in angle]
            self.sensors[f"{body}.theta"] = [(f"{root}.theta", 1.0)]
            self.sensors[f"{body}.omega"] = [(f"{root}.theta_dot", 1.0)]
            if model.theta_index[i] >= 0:
                self.sensors[f"{body}.theta_dot"] = [(f"{root}.theta_dot", 1.0)]
            child_end = model.parent_end[i + 1] if i + 1 < model.n_bodies else None
            if i in model.beams:
                previous_end = self.beam(i, body, root, child_end)
            else:
                previous_end = self.rigid(i, body, root, child_end)
        self.elements.append(BeamFree(f"{model.body_names[-1]}__tip"))
        modal = {int(k) for index in model.modal_index for k in index}
        for index, name in enumerate(model.coordinates):
            if index in modal:
                for label in (name, f"{name}_dot", f"{name}.force"):
                    self.refused[label] = "a modal coordinate of the modal form (use station ports)"
        return ExactForm(Chain(f"{model.name}_exact", self.elements), self.sensors, self.actuators, self.refused)

    def rigid(self, i: int, body: str, root: str, child_end: str | None) -> str:
        from .elements.bending_bodies import RigidSegment
        model = self.model
        points = {"inboard": 0.0, "com": float(model.com[i][0])}
        points.update({e: float(p[0]) for e, p in model.ends[i].items()})
        for point, x in points.items():
            self.point(body, point, [(f"{root}.w", 1.0), (f"{root}.theta", x)])
        length = points[child_end] if child_end is not None else 0.0
        if length < 0.0:
            raise _refuse(model, f"body {body!r} carries its child at x = {length} m behind its inboard point")
        self.elements.append(RigidSegment(body, length=length, mass=float(model.mass[i]),
                                          inertia=float(model.inertia[i]), center=points["com"]))
        preload = self.gravity * (self.outboard_mass[i] * length + float(model.mass[i]) * points["com"])
        if preload:
            from .elements.bending_preload import GeometricMoment
            self.elements.append(GeometricMoment(f"{body}__gravity", preload))
        for part, weight in self.force_weight.items():
            self.actuators[f"{body}.{part}"] = [(f"{body}.force", weight)]
        self.actuators[f"{body}.moment"] = [(f"{body}.moment", 1.0)]
        return f"{body}.theta"

    def field(self, i: int, name: str, start: float, end: float):
        """The field of beam ``i`` from ``start`` to ``end`` [m]: exact, or with the gravity tension."""
        from .elements.beams import BeamField
        from .elements.bending_preload import VaryingTensionBeamField
        beam = self.model.bodies[i]
        if not self.gravity:
            return BeamField(name, end - start, beam.bending_stiffness, beam.mass_per_length,
                             kelvin_voigt_time=beam.stiffness_damping)
        tension = [self.gravity * (self.outboard_mass[i] + beam.mass_per_length * (beam.length - x))
                   for x in (start, end)]
        return VaryingTensionBeamField(name, end - start, beam.bending_stiffness, beam.mass_per_length,
                                       inboard_tension=tension[0], outboard_tension=tension[1],
                                       kelvin_voigt_time=beam.stiffness_damping)

    def beam(self, i: int, body: str, root: str, child_end: str | None) -> str:
        model = self.model
        beam = model.bodies[i]
        if child_end is not None and beam.outboard[child_end] < beam.length * (1 - 1e-12):
            raise _refuse(model, f"body {model.body_names[i + 1]!r} hangs from beam {body!r} mid-span "
                                 f"(x = {beam.outboard[child_end]} m < L): a branch")
        places = [(x, f"end_{e}", e, "end") for e, x in beam.outboard.items()]
        places += [(x, f"at_{n}", n, "station") for n, x in beam.stations.items()]
        places.sort(key=lambda item: item[0])
        position, pieces, end_signal = 0.0, 0, None
        self.point(body, "inboard", [(f"{root}.w", 1.0)])
        for x, suffix, label, kind in places:
            if x - position > 1e-12 * beam.length:
                pieces += 1
                self.elements.append(self.field(i, f"{body}__{pieces}", position, x))
                position = x
            marker = self.marker(f"{body}__{suffix}")
            w = [(f"{marker}.w", 1.0), (f"{root}.w", -1.0), (f"{root}.theta", -x)]
            slope = [(f"{marker}.theta", 1.0), (f"{root}.theta", -1.0)]
            if kind == "end":
                self.point(body, label, [(f"{marker}.w", 1.0)])
                if label == child_end:
                    end_signal = f"{marker}.theta"
                continue
            self.sensors[f"{body}.{label}.w"] = w
            self.sensors[f"{body}.{label}.slope"] = slope
            self.sensors[f"{body}.{label}.w_dot"] = [(f"{n}_dot", v) for n, v in w]
            self.sensors[f"{body}.{label}.slope_rate"] = [(f"{n}_dot", v) for n, v in slope]
            self.actuators[f"{body}.{label}.force"] = [(f"{marker}.force", 1.0)]
            self.actuators[f"{body}.{label}.moment"] = [(f"{marker}.moment", 1.0)]
        if beam.length - position > 1e-12 * beam.length:
            self.elements.append(self.field(i, f"{body}__{pieces + 1}", position, beam.length))
        for part in ("x", "y", "vx", "vy"):
            self.refused[f"{body}.com.{part}"] = "the centre of mass of a deformed beam is not a chain signal"
        return end_signal


def exact_form(model: Any, operating_point: Any = None) -> ExactForm:
    """The exact-field bending chain of a straight planar chain and its port map (module docstring).

    Parameters
    ----------
    model : PlanarModel
    operating_point : optional
        As for :func:`ctmm.linearize` (default: the static equilibrium); it must be straight,
        undeformed and at rest.
    """
    theta0, axial_gravity = _check_model(model, operating_point)
    return _Builder(model, theta0, axial_gravity).build()


def _expand(terms: Sequence[tuple[str, float]], lookup) -> Terms:
    out: Terms = []
    for name, weight in terms:
        out += [(signal, weight * w) for signal, w in lookup(name)]
    return out


def _open_loop(chain: Any, s: np.ndarray, inputs: list[str], outputs: list[str]) -> np.ndarray:
    """``G[k, i_out, i_in]``: chain displacement signals per unit chain input (one Riccati sweep for
    all inputs: the beam matrices evaluated once, the inputs' load vectors stacked)."""
    from .chain_assembly import solve_load_cases

    if hasattr(chain, "open_loop"):            # a ctmm.spatial_beam_trees.SpatialBeamTree: branches condensed
        return chain.open_loop(s, inputs, outputs)
    G = np.empty((s.size, len(outputs), len(inputs)), dtype=complex)
    entries = [chain.input(name) for name in inputs]
    states = solve_load_cases(chain, s, [{entry.position: {entry.input: 1.0}} for entry in entries])
    for a, signal in enumerate(chain.signal(name) for name in outputs):
        G[:, a, :] = states[:, signal.point, :, signal.component].T * (s ** signal.derivative)[:, None]
    return G


def _weights(terms_by_name: dict, names: list[str], index: dict) -> np.ndarray:
    """``E[i_signal, i_name]``: weights of chain signals (or inputs) in each planar port."""
    E = np.zeros((len(index), len(names)))
    for k, name in enumerate(names):
        for signal, weight in terms_by_name[name]:
            E[index[signal], k] += weight
    return E


def frequency_response(system: Any, omega: Any, *, input: str | Sequence[str],  # noqa: A002
                       output: str | Sequence[str], operating_point: Any = None) -> FrequencyResponse:
    """Frequency response of a planar chain's exact-field form, loops closed with exact delays.

    The open-loop bending chain is solved by the Riccati sweep from every chain input used (port
    or loop actuator) to every chain signal used; each :class:`~ctmm.control.Feedback` loop
    ``u = -C(s) e^{-s tau} (y - r)`` is then closed at every frequency,
    ``(I + K G_yu) u = K (r - G_yw w)``, ``K = diag(C_l(s) e^{-s tau_l})``.

    Parameters as :func:`ctmm.planar_frequency.frequency_response` (actuator names or
    ``"<loop>.reference"``; sensor names or ``"<loop>.y"``, ``"<loop>.u"``).

    Returns
    -------
    FrequencyResponse
        ``response[i_out, i_in, k]``: output deviation phasor per unit input phasor.
    """
    from .planar import ports
    from .planar.model import PlanarModel

    responder = ExactResponse(system, input, output, operating_point)
    model, inputs, outputs = responder.model, responder.inputs, responder.outputs
    omega = validation.frequencies("omega", omega)
    started = time.perf_counter()
    response = responder(omega)
    form = responder.form
    sensors, actuators = set(ports.sensor_names(model)), set(ports.actuator_names(model))
    units = {name: ports.actuator_unit(model, name) for name in inputs if name in actuators}
    units.update({name: ports.sensor_unit(model, name) for name in outputs if name in sensors})
    units.update(loop_units(ports.PlanarPorts(model), responder.loops, inputs + outputs))
    info = {"method": "exact fields (bending chain of BeamField pieces, ctmm.exact_fields), delays exact",
            "wall_time_s": time.perf_counter() - started, "n_frequencies": int(omega.size),
            "chain_elements": len(form.chain.elements)}
    return FrequencyResponse(omega, response, tuple(inputs), tuple(outputs), model.name, info=info, units=units)


class ExactResponse:
    """``omega -> response[i_out, i_in, k]`` of :func:`frequency_response`, the exact form built once.

    The form (:func:`exact_form`: the operating point, the checks, the bending chain) does not depend
    on the frequency; it is built at the first call and answers every later call, so a search that
    evaluates a few frequencies at a time (the margins' crossover refinement) builds it once.

    Parameters
    ----------
    system : PlanarModel or ControlledModel
    input, output : str or sequence of str
        As for :func:`frequency_response`.
    operating_point : optional
        As for :func:`ctmm.linearize` (default: the static equilibrium).
    """

    def __init__(self, system: Any, input: str | Sequence[str], output: str | Sequence[str],  # noqa: A002
                 operating_point: Any = None) -> None:
        from .planar.model import PlanarModel

        self.model, self.loops = ((system, ()) if isinstance(system, PlanarModel)
                                  else (system.plant, tuple(system.loops)))
        refuse_saturation(self.loops, "the frequency-domain verbs (fields='exact')")
        self.inputs = list(validation.names("input", input))
        self.outputs = list(validation.names("output", output))
        self.operating_point = operating_point
        self.form: ExactForm | None = None

    def __call__(self, omega: np.ndarray) -> np.ndarray:
        """``response[i_out, i_in, k]`` at checked angular frequencies ``omega`` [rad/s]."""
        if self.form is None:
            self.form = exact_form(self.model, self.operating_point)
        return form_response(self.form, self.loops, omega, self.inputs, self.outputs)


def form_response(form: Any, loops: Sequence[Any], omega: np.ndarray, inputs: list[str],
                  outputs: list[str]) -> np.ndarray:
    """``response[i_out, i_in, k]`` of an exact-field form with its :class:`~ctmm.control.Feedback` loops closed.

    ``form`` maps port names to weighted chain terms (``form.sensor(name)``, ``form.actuator(name)``,
    ``form.chain``: :class:`ExactForm` or :class:`ctmm.spatial_exact_fields.SpatialExactForm`);
    inputs are actuator names or ``"<loop>.reference"``, outputs sensor names or ``"<loop>.y"`` /
    ``"<loop>.u"``; each loop ``u = -C(s) e^{-s tau} (y - r)`` is closed at every frequency.
    """
    s = 1j * omega
    index = {lp.name: j for j, lp in enumerate(loops)}
    plain_in = [x for x in inputs if loop_signal(x, index, ("reference",)) is None]
    plain_out = [x for x in outputs if loop_signal(x, index, ("y", "u")) is None]
    in_terms: dict = {x: form.actuator(x) for x in plain_in}       # loops keyed ("loop", name)
    out_terms: dict = {x: form.sensor(x) for x in plain_out}
    in_terms.update({("loop", lp.name): _expand(lp.actuator_terms, form.actuator) for lp in loops})
    out_terms.update({("loop", lp.name): _expand(lp.terms, form.sensor) for lp in loops})
    loop_keys = [("loop", lp.name) for lp in loops]
    chain_in = {n: k for k, n in enumerate(dict.fromkeys(n for t in in_terms.values() for n, _ in t))}
    chain_out = {n: k for k, n in enumerate(dict.fromkeys(n for t in out_terms.values() for n, _ in t))}
    if chain_in and chain_out:
        G = _open_loop(form.chain, s, list(chain_in), list(chain_out))
    else:
        G = np.zeros((s.size, len(chain_out), len(chain_in)), dtype=complex)
    P_z, P_y = _weights(out_terms, plain_out, chain_out).T, _weights(out_terms, loop_keys, chain_out).T
    Q_w, Q_u = _weights(in_terms, plain_in, chain_in), _weights(in_terms, loop_keys, chain_in)
    blocks = (P_z @ G @ Q_w, P_z @ G @ Q_u, P_y @ G @ Q_w, P_y @ G @ Q_u)
    K = np.zeros((s.size, len(loops), len(loops)), dtype=complex)
    for j, loop in enumerate(loops):
        K[:, j, j] = loop.loop_gain(s)
    return close_loops(blocks, K, inputs, outputs, plain_in, plain_out, index)


def natural_frequencies(system: Any, *, n_modes: int | None = None, omega_max: float | None = None,
                        operating_point: Any = None) -> np.ndarray:
    """Undamped natural frequencies [rad/s] of a planar chain's exact-field form (ascending).

    The bending chain of :func:`exact_form` is counted by Wittrick-Williams
    (:func:`ctmm.natural.natural_frequencies`): no mode is missed; a statically unstable chain (standing
    in gravity beyond its toppling or buckling load) is refused by that search.  Loops and damping (hinge
    dampers, Kelvin-Voigt beams) are refused as for chains.

    Parameters
    ----------
    system : PlanarModel
    n_modes : int, optional
        Number of lowest frequencies.
    omega_max : float, optional
        All frequencies below ``omega_max`` [rad/s] instead.
    operating_point : optional
        As for :func:`exact_form`.
    """
    from .natural import natural_frequencies as chain_natural
    from .planar.model import PlanarModel

    if not isinstance(system, PlanarModel):
        names = [lp.name for lp in getattr(system, "loops", ())]
        raise ModelError(f"natural_frequencies cannot honour the feedback loops {names}: it describes an uncontrolled "
                         "model; pass system.plant, or use frequency_response(..., fields='exact') for the closed loop")
    return chain_natural(exact_form(system, operating_point).chain, n_modes=n_modes, omega_max=omega_max)
