"""Frequency verbs on planar models through their linearisation (:func:`ctmm.linearize`).

:func:`ctmm.frequency_response`, :func:`ctmm.natural_frequencies`, :func:`ctmm.mode_shapes` and
:func:`ctmm.eigenvalue_count` dispatch here for a :class:`~ctmm.planar.model.PlanarModel` (rigid or flexible) or a
``ctmm.control.ControlledModel``.  The model is linearised about ``operating_point`` (default:
its static equilibrium, see :func:`ctmm.linearize`); the response is that of the linearisation,
``G(s) = C (s I - A)^{-1} B + D``, with delayed loops closed exactly by ``e^{-s tau}``.  It is computed by
the one sweep's frequency context batched over omega (:mod:`ctmm.planar_transfer_response`, ``O(N)`` per
frequency, every loop closed per frequency); the dense resolvent of :func:`ctmm.linearize` answers (or
refuses) the frequencies the sweep's pivots do not certify and the models it does not state
(:class:`PlanarResponse`).

Natural frequencies are those of the undamped linearisation ``M qddot + K q = 0``:
``omega_k^2`` are the eigenvalues of ``-df/dq`` (``= M^{-1} K``).  As for chains, a model with
damping (any velocity-dependent force: hinge dampers, beam damping, PD hinges) or with loops
is refused; an unstable equilibrium (``omega^2 < 0``) is refused too.  The frequencies themselves
come from Wittrick-Williams counting on the one sweep's frequency context
(:mod:`ctmm.planar_counting`, rigid and flexible models, exact to round-off); the dense eig of
``M^{-1} K`` only checks the symmetry (circulatory forces are refused), gives the starting shapes
for inverse iteration, and stands in for models off the element protocol.
"""
from __future__ import annotations

import time
from typing import Any, Sequence

import numpy as np
import scipy.linalg

from . import validation
from .errors import ModelError
from .saturation import refuse_saturation
from .controlled_linearization import delayed_loop_response_function
from .planar_linearization import linearize_planar, tangent
from .planar_linearization import operating_point as planar_operating_point
from .results import FrequencyResponse, ModalResult
from .signal_units import loop_units

__all__ = ["is_planar_system", "frequency_response", "PlanarResponse", "acceleration_twin", "natural_frequencies", "mode_shapes", "eigenvalue_count",
           "ZERO_MODE_FACTOR", "RESOLUTION"]

_CLOSED_LOOP = ("ctmm.linearize (eigenvalues of the closed-loop A, delays beside it) or ctmm.stability "
                "for the closed-loop roots")
_DAMPED = "ctmm.frequency_response, or the eigenvalues of ctmm.linearize(model).state_space.A for damped roots"
#: Largest |df/dqdot| counted as undamped, relative to sqrt(max |df/dq|) [1/s].
UNDAMPED_TOLERANCE = 1e-8
#: Round-off of an eigenvalue of M^-1 K in units of its first-order perturbation bound (``n eps max|M^-1 K|``
#: times the eigenvector condition): below it a mode is rigid (omega = 0), below -it unstable.
ZERO_MODE_FACTOR = 8.0
#: Where the dense eig stands in for the exact count, modes within RESOLUTION times their round-off are refused.
RESOLUTION = 1e2


def is_planar_system(system: Any) -> bool:
    """True for a PlanarModel or a ControlledModel (a PlanarModel plant with loops)."""
    from .planar.model import PlanarModel

    return isinstance(system, PlanarModel) or (isinstance(getattr(system, "plant", None), PlanarModel)
                                                and hasattr(system, "loops"))


def _split(system: Any):
    from .planar.model import PlanarModel

    if isinstance(system, PlanarModel):
        return system, ()
    refuse_saturation(system.loops, "the frequency-domain verbs")
    return system.plant, tuple(system.loops)


def frequency_response(system: Any, omega: Any, *, input: str | Sequence[str],  # noqa: A002
                       output: str | Sequence[str], operating_point: Any = None,
                       fields: str = "modal") -> FrequencyResponse:
    """Frequency response of a planar model's linearisation, loops closed with exact delays.

    The plant's ``G(s)`` comes from the one sweep's frequency context, batched over ``omega``
    (:mod:`ctmm.planar_transfer_response`), and each loop ``u = -C(s) e^{-s tau} (y - r)`` (``tau = 0``
    for a loop without delay) is closed at every frequency: ``(I + K G_yu) u = K (r - G_yw w)``,
    ``K = diag(C_l(s) e^{-s tau_l})``.  Frequencies the sweep does not certify (at or next to a pole, a
    substructure resonance) and models it does not state (hinges with translational springs, nonlinear
    hinges, beams with user laws) take the dense resolvent of :func:`ctmm.linearize`, loops without delay
    closed inside it (:class:`PlanarResponse`); it refuses a frequency at a pole
    (:class:`~ctmm.controlled_linearization.FrequencyAtPoleError`).  ``info["method"]`` names the path,
    ``info["n_dense_frequencies"]`` the number of frequencies the resolvent answered.

    Parameters
    ----------
    system : PlanarModel or ControlledModel
    omega : array_like
        Angular frequencies [rad/s], >= 0.
    input : str or sequence of str
        Actuator names (:func:`ctmm.planar.ports.actuator_names`, e.g. ``"motor.torque"`` [N m])
        or ``"<loop>.reference"``.
    output : str or sequence of str
        Sensor names (:func:`ctmm.planar.ports.sensor_names`, e.g. ``"arm.out.y"`` [m]),
        ``"<loop>.y"``, ``"<loop>.u"``, or accelerations (``s^2`` times the position twin, outputs of this
        verb only): ``"<body>.<point>.ax|ay"`` [m/s^2], ``"<body>.alpha"`` [rad/s^2],
        ``"<beam>.<station>.w_ddot"`` [m/s^2], ``"<coordinate>_ddot"``.
    operating_point : optional
        As for :func:`ctmm.linearize` (default: the static equilibrium).
    fields : {"modal", "exact"}
        ``"modal"``: the model as built (beams by their kept modes).  ``"exact"``: a straight
        serial chain converted to exact beam fields between its stations
        (:func:`ctmm.exact_fields.frequency_response`; refused where it does not apply).

    Returns
    -------
    FrequencyResponse
        ``response[i_out, i_in, k]``: output deviation phasor per unit input phasor.
    """

    if validation.option("fields", fields, ("modal", "exact")) == "exact":
        from .exact_fields import frequency_response as exact_response
        return exact_response(system, omega, input=input, output=output, operating_point=operating_point)

    model, loops = _split(system)
    inputs = list(validation.names("input", input))
    outputs = list(validation.names("output", output))
    s = 1j * validation.frequencies("omega", omega)
    started = time.perf_counter()

    responder = PlanarResponse(system, inputs, outputs, operating_point)
    response = responder(s)
    named = responder.ports                         # resolved once (building them is O(N))
    units = {name: named.actuator_unit(name) for name in inputs if name in named.actuators}
    units.update({name: named.sensor_unit(name) for name in outputs if name in named.sensors})
    units.update({name: f"{named.sensor_unit(twin)}/s^2" for name, twin in zip(outputs, responder.outputs)
                  if twin != name})
    units.update(loop_units(named, loops, inputs + outputs))
    point = responder.point
    info = {"method": responder.method, "wall_time_s": time.perf_counter() - started, "n_frequencies": int(s.size),
            "n_dense_frequencies": responder.dense_count, "operating_point_q": point.q.tolist(),
            "jacobian_error": point.jacobian_error}
    return FrequencyResponse(np.imag(s), response, tuple(inputs), tuple(outputs), model.name, info=info, units=units)


class PlanarResponse:
    """``s -> response[i_out, i_in, k]`` of a planar model (or a ``ControlledModel`` on one) with its loops
    closed, as :func:`frequency_response` answers it; the model is linearised once, at the first call, and
    that answers every call (e.g. the repeated evaluations of a crossover search, :func:`ctmm.control.margins`).

    The one sweep's frequency context (:mod:`ctmm.planar_transfer_response`) answers the frequencies it
    certifies; the dense resolvent of :func:`ctmm.linearize` (:func:`ctmm.controlled_linearization.delayed_loop_response`)
    answers or refuses the others, and the whole response of what the sweep does not state: hinges with
    translational springs, nonlinear hinges, beams with user state laws, names that are not plain ports
    (the dense path's messages for them), an operating point that is not a static equilibrium.

    Parameters
    ----------
    system : PlanarModel or ControlledModel
    inputs, outputs : sequence of str
        As for :func:`frequency_response`.
    operating_point : optional
        As for :func:`ctmm.linearize`.

    Attributes
    ----------
    method : str
        Which path answered (set at the first call).
    dense_count : int
        Number of frequencies the dense resolvent answered, over all calls.
    point : OperatingPoint
        The operating point (after the first call).
    """

    def __init__(self, system: Any, inputs: Sequence[str], outputs: Sequence[str], operating_point: Any = None) -> None:
        from .planar.ports import PlanarPorts

        self.model, self.loops = _split(system)
        self.ports = PlanarPorts(self.model)
        self.inputs, self.operating_point = list(inputs), operating_point
        # an acceleration output is s^2 times its position twin (both paths answer the twin)
        twins = [acceleration_twin(self.ports, name) for name in outputs]
        self.outputs = [name if twin is None else twin for name, twin in zip(outputs, twins)]
        self.accelerations = np.array([twin is not None for twin in twins], dtype=bool)
        self.method, self.dense_count, self.point = "", 0, None
        self._plant: list = []
        self._dense = None

    def _dense_response(self, s: np.ndarray) -> np.ndarray:
        if self._dense is None:
            model, loops, point = self.model, self.loops, self.operating_point
            self._dense = delayed_loop_response_function(
                lambda lin_in, lin_out: self._record(linearize_planar(model, loops, point, inputs=lin_in,
                                                                      outputs=lin_out)),
                loops, self.inputs, self.outputs, model.name)
        self.dense_count += int(s.size)
        return self._dense(s)

    def _record(self, lin: Any) -> Any:
        self.point = lin.operating_point
        return lin

    def _sweep_plant(self) -> Any:
        """The :class:`~ctmm.planar_transfer_response.SweepResponse` of the plant, or ``None`` where it does not apply."""
        from .planar_transfer_response import SweepResponse, sweep_applies

        ports = self.ports
        loop_names = {lp.name for lp in self.loops}
        for name in self.inputs:
            head, _, tail = name.partition(".")
            if name not in ports.actuators and not (head in loop_names and tail == "reference"):
                return None
        for name in self.outputs:
            head, _, tail = name.partition(".")
            if name not in ports.sensors and not (head in loop_names and tail in ("y", "u")):
                return None
        try:
            point = planar_operating_point(self.model, self.operating_point)
        except ModelError:
            return None
        if not sweep_applies(self.model, point):
            return None
        try:
            plant = SweepResponse(self.model, point, ports)
        except ModelError:
            return None
        self.point = point
        return plant

    def __call__(self, s: np.ndarray) -> np.ndarray:
        from .planar_transfer_response import closed_loop_response

        s = np.asarray(s, dtype=complex).reshape(-1)
        if not self._plant:
            self._plant.append(self._sweep_plant())
            self.method = ("linearisation (ctmm.linearize), delays exact" if self._plant[0] is None
                           else "one sweep's frequency context (ctmm.planar_transfer_response), delays exact")
        if self._plant[0] is None:
            response = self._dense_response(s)
        else:
            response, good = closed_loop_response(self._plant[0], self.loops, s, self.inputs, self.outputs)
            if not np.all(good):            # frequencies the sweep does not certify: the dense resolvent's rule
                response[:, :, ~good] = self._dense_response(s[~good])
        response[self.accelerations] *= s * s
        return response


#: Acceleration outputs of :func:`frequency_response` (not sensors of the ports: as loop signals they would close
#: an algebraic loop) -> the suffix of their position twin.
ACCELERATION_SUFFIXES = {".ax": ".x", ".ay": ".y", ".alpha": ".theta", ".w_ddot": ".w", "_ddot": ""}


def acceleration_twin(ports: Any, name: str) -> str | None:
    """The position sensor whose response times ``s^2`` is the acceleration output ``name``
    (``"<body>.<point>.ax|ay"`` [m/s^2], ``"<body>.alpha"`` [rad/s^2], ``"<beam>.<station>.w_ddot"`` [m/s^2],
    ``"<coordinate>_ddot"``), else ``None``."""
    if not isinstance(name, str) or name in ports.sensors:
        return None
    for suffix, twin in ACCELERATION_SUFFIXES.items():
        if name.endswith(suffix) and name[:-len(suffix)] + twin in ports.sensors:
            sensor = ports.sensors[name[:-len(suffix)] + twin]
            if not sensor.is_rate:
                return sensor.name
    return None


def _undamped_stiffness(system: Any, verb: str, operating_point: Any):
    """``(model, M^{-1} K, OperatingPoint)`` of an undamped, loop-free planar model, else a refusal."""
    model, loops = _split(system)
    if loops:
        names = [lp.name for lp in loops]
        raise ModelError(f"{verb} cannot honour the feedback loops {names} of {model.name!r}: it describes an "
                         f"uncontrolled model; for the closed loop use {_CLOSED_LOOP}; for the plant pass "
                         "system.plant")
    for name, damping in zip(model.joint_names, model.damping):
        if damping:
            raise ModelError(f"{verb} needs an undamped system, but {name!r} has damping={float(damping)!r}; "
                             f"use {_DAMPED}")
    A, op = tangent(model, planar_operating_point(model, operating_point))
    n = model.n_coordinates
    Jq, Jv = A[n:, :n], A[n:, n:]
    scale = np.sqrt(max(float(np.max(np.abs(Jq), initial=0.0)), 1e-300))
    if np.max(np.abs(Jv), initial=0.0) > UNDAMPED_TOLERANCE * scale:
        raise ModelError(f"{verb} needs an undamped system, but {model.name!r} has velocity-dependent forces at "
                         f"the operating point (largest |d qddot / d qdot| = {np.max(np.abs(Jv)):.3e} 1/s: a "
                         f"damped beam, a PD hinge or a velocity law); use {_DAMPED}")
    return model, -Jq, op


def _checked_eig(model: Any, stiffness: np.ndarray, op: Any, verb: str
                 ) -> tuple[np.ndarray, np.ndarray, float, np.ndarray]:
    """``omega^2`` (real, values within their round-off as 0), eigenvectors, largest ``|omega^2|`` and the
    round-off of each ``omega^2`` of ``M^{-1} K``,
    refusing a non-symmetric pair (circulatory forces) and an unstable operating point."""
    values, left, vectors = scipy.linalg.eig(stiffness, left=True, right=True)
    top = max(float(np.max(np.abs(values), initial=0.0)), 1e-300)
    # round-off of each eigenvalue (first-order perturbation bound, entries of M^-1 K known to eps max|M^-1 K|):
    # a mode is rigid only below its own round-off, never by a cut relative to the stiffest mode
    overlap = np.maximum(np.abs(np.sum(left.conj() * vectors, axis=0)), 1e-300)
    noise = (ZERO_MODE_FACTOR * stiffness.shape[0] * np.finfo(float).eps * float(np.max(np.abs(stiffness), initial=0.0))
             * np.sum(np.abs(left), axis=0) * np.sum(np.abs(vectors), axis=0) / overlap)
    if np.max(np.abs(values.imag), initial=0.0) > 1e-6 * top:
        raise ModelError(f"{verb}: the linearisation of {model.name!r} is not a symmetric mass-stiffness pair "
                         "(complex omega^2: circulatory forces such as follower loads); use ctmm.linearize")
    values = values.real
    unstable = np.flatnonzero(values < -noise)
    if unstable.size:
        names = list(model.coordinates)
        directions = []
        for k in unstable[np.argsort(values[unstable])]:
            shape = np.real(vectors[:, k])
            shape = shape / shape[np.argmax(np.abs(shape))]
            main = [f"{names[i]} {shape[i]:+.3g}" for i in np.argsort(-np.abs(shape))[:3] if abs(shape[i]) > 1e-3]
            directions.append(f"omega^2 = {values[k]:.6g} rad^2/s^2 along ({', '.join(main)})")
        raise ModelError(f"model {model.name!r} is statically unstable about q = {op.q.tolist()}: "
                         f"{unstable.size} mode(s) with negative stiffness (imaginary roots, e.g. a link held "
                         f"against gravity): {'; '.join(directions)}; natural frequencies exist only about a stable "
                         "equilibrium: pass operating_point=(q, qdot) at a stable equilibrium (e.g. the links hanging), "
                         "or use ctmm.linearize for the unstable linearisation")
    return np.where(np.abs(values) <= noise, 0.0, values), vectors, top, noise


def _refuse_unresolved(model: Any, values: np.ndarray, noise: np.ndarray, verb: str) -> None:
    """Refuse eigenvalues of ``M^-1 K`` that are above their round-off but within ``RESOLUTION`` times it
    (where the dense eig stands in for the exact count: they cannot be told from rigid-body modes)."""
    unresolved = (np.abs(values) > 0.0) & (np.abs(values) <= RESOLUTION * noise)
    if np.any(unresolved):
        raise ModelError(f"{verb}: the mode(s) of {model.name!r} with omega^2 = {values[unresolved].tolist()} "
                         f"rad^2/s^2 cannot be told from rigid-body modes (round-off about {noise[unresolved].tolist()} "
                         "rad^2/s^2: stiffness spread over too many decades); soften the stiffest part")


def eigenvalue_count(system: Any, omega: Any, *, operating_point: Any = None) -> np.ndarray:
    """Number of undamped natural frequencies of a planar model's linearisation strictly below each
    ``omega`` [rad/s] (Wittrick-Williams counting on the one sweep's frequency context,
    :mod:`ctmm.planar_counting`; exact also at substructure resonances).

    Parameters
    ----------
    system : PlanarModel
        Undamped and without loops (else :class:`ModelError`, as for chains).
    omega : array_like
        Trial frequencies [rad/s], >= 0.
    operating_point : optional
        As for :func:`ctmm.linearize` (default: the static equilibrium).
    """
    from .planar_counting import FrequencyCounter

    model, stiffness, op = _undamped_stiffness(system, "eigenvalue_count", operating_point)
    values, _, _, noise = _checked_eig(model, stiffness, op, "eigenvalue_count")
    omega = validation.frequencies("omega", omega)
    if not np.any(op.qdot != 0.0):
        try:
            counter = FrequencyCounter(model, op.q, op.t, verb="eigenvalue_count")
        except ModelError:
            counter = None
        if counter is not None:
            return counter.count(omega.reshape(-1)).reshape(omega.shape)
    # off the element protocol (hinges with translational springs): the dense eigenvalues
    _refuse_unresolved(model, values, noise, "eigenvalue_count")
    return np.sum(np.sqrt(values)[None, :] < omega.reshape(-1, 1), axis=1).reshape(omega.shape)


def _modes(system: Any, verb: str, n_modes, omega_max, operating_point):
    model, stiffness, op = _undamped_stiffness(system, verb, operating_point)
    validation.one_mode_limit(n_modes, omega_max)
    values, vectors, top, noise = _checked_eig(model, stiffness, op, verb)
    order = np.argsort(values)
    omega = np.sqrt(values[order])
    shapes = np.real(vectors[:, order])
    keep = validation.selected_modes(omega, n_modes, omega_max, f"model {model.name!r} (one per coordinate)")
    exact = _counted_frequencies(model, op, keep.size, omega_max)
    if exact is None:
        _refuse_unresolved(model, values, noise, verb)
        return model, omega[keep], shapes[:, keep]
    # eig of the dense M^-1 K loses eps * omega_max^2 / omega^2 on the low modes of stiff chains:
    # the frequencies come from the exact count, the shapes by inverse iteration at them (the exact
    # count below omega_max decides how many: the lowest of eig's ascending modes start the iteration)
    omega_keep, shapes_keep = exact, shapes[:, np.arange(min(exact.size, omega.size))].copy()
    n = stiffness.shape[0]
    for j, w in enumerate(exact):
        shifted = stiffness - (w * w) * np.eye(n) + 1e-12 * max(top, 1.0) * np.eye(n)
        x = shapes_keep[:, j] if np.any(shapes_keep[:, j]) else np.ones(n)
        for _ in range(2):
            try:
                x = np.linalg.solve(shifted, x)
            except np.linalg.LinAlgError:
                break
            x = x / np.max(np.abs(x))
        shapes_keep[:, j] = x
    return model, omega_keep, shapes_keep


def _counted_frequencies(model: Any, op: Any, count: int, omega_max: Any) -> np.ndarray | None:
    """The ``count`` lowest frequencies [rad/s] by Wittrick-Williams counting on the one sweep's
    frequency context (:mod:`ctmm.planar_counting`; rigid and flexible models, exact to round-off),
    else ``None`` (eig stands: models off the protocol, e.g. hinges with translational springs, or a
    moving operating point).  With ``omega_max`` the exact count below it decides how many there are."""
    from .planar_counting import FrequencyCounter

    if np.any(op.qdot != 0.0):
        return None
    try:
        counter = FrequencyCounter(model, op.q, op.t)
    except ModelError:
        return None
    if omega_max is not None:
        return counter.frequencies(omega_max=float(omega_max))
    return counter.frequencies(n_modes=count) if count else np.zeros(0)


def natural_frequencies(system: Any, *, n_modes: int | None = None, omega_max: float | None = None,
                        operating_point: Any = None, fields: str = "modal") -> np.ndarray:
    """Undamped natural frequencies [rad/s] of a planar model's linearisation (ascending, rigid as 0).

    Parameters
    ----------
    system : PlanarModel
        Undamped and without loops (else :class:`ModelError`, as for chains).
    n_modes : int, optional
        Number of lowest frequencies.
    omega_max : float, optional
        All frequencies below ``omega_max`` [rad/s] instead.
    operating_point : optional
        As for :func:`ctmm.linearize` (default: the static equilibrium).
    fields : {"modal", "exact"}
        ``"exact"``: the Wittrick-Williams count of the exact-field form of a straight serial
        chain (:func:`ctmm.exact_fields.natural_frequencies`).
    """
    if validation.option("fields", fields, ("modal", "exact")) == "exact":
        from .exact_fields import natural_frequencies as exact_natural
        return exact_natural(system, n_modes=n_modes, omega_max=omega_max, operating_point=operating_point)
    return _modes(system, "natural_frequencies", n_modes, omega_max, operating_point)[1]


def mode_shapes(system: Any, *, n_modes: int | None = None, omega_max: float | None = None,
                operating_point: Any = None) -> ModalResult:
    """Natural frequencies and mode shapes in the generalised coordinates of a planar model.

    ``shapes[k, i, 0]`` is coordinate ``i`` (``point_names``) in mode ``k``, normalised to unit
    largest entry; otherwise as :func:`natural_frequencies`.
    """
    model, omega, vectors = _modes(system, "mode_shapes", n_modes, omega_max, operating_point)
    if vectors.size:
        ref = vectors[np.argmax(np.abs(vectors), axis=0), np.arange(vectors.shape[1])]
        vectors = vectors / ref
    return ModalResult(omega, vectors.T[:, :, None], ("amplitude",), tuple(model.coordinates))
