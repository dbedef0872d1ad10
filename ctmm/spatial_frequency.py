"""Frequency verbs on spatial models through their linearisation (issue 14, ``docs/spatial.md`` §9).

:func:`ctmm.natural_frequencies`, :func:`ctmm.mode_shapes`, :func:`ctmm.eigenvalue_count` and
:func:`ctmm.frequency_response` dispatch here for a :class:`~ctmm.spatial.model.SpatialModel` and a
``ControlledModel`` on one (the frequency response with the loops closed; the other verbs refuse loops).  About a
static operating point ``q0`` (default: the static equilibrium of :func:`ctmm.linearize`) in the tangent
coordinates of :mod:`ctmm.spatial_linearization`, small motions obey ``M x'' + C x' + K x = B u`` with

* ``M^-1`` from the one articulated sweep: its columns are the accelerations of unit generalised
  forces added to each joint's law (one batched sweep), ``M`` its inverse;
* ``K = -M df/dr``, ``C = -M df/dv`` from the complex-step Jacobians of :func:`ctmm.linearize`.

``K`` must be symmetric (a conservative linearisation: refused otherwise, e.g. the linear law of an
anisotropic rotary spring away from its rest rotation) and, for natural frequencies, positive
semi-definite (a stable equilibrium) with ``C = 0`` (damped models are refused, as for chains).

**Counting.**  The number of natural frequencies strictly below ``omega`` is the number of negative
eigenvalues of the symmetric ``K - omega^2 M`` (Sylvester's law of inertia: the Wittrick-Williams count
of the global matrices), certified next to a natural frequency by :func:`ctmm.counting.certified_count`
with the sign of ``det(K - omega^2 M)`` as its side test.  Natural frequencies come from the symmetric
generalised eigenproblem ``eigh(K, M)`` and are certified by that independent count: every gap between
them and the range above the highest must hold the count ``eigh`` claims, so no root is missed (a
:class:`~ctmm.errors.ModelError` otherwise).  A mode is rigid (``omega = 0``) only within its own round-off
(:func:`rayleigh_modes`), never by a cut relative to the stiffest mode, so a slow mode beside a stiff part keeps its
frequency; one above its round-off by less than :data:`RESOLUTION` is refused as unresolved.  The
articulated *frequency context* of the sweep with ``d = 6`` answers frequency responses at static equilibria,
gravity and static loads included (:mod:`ctmm.spatial_transfer_response`); counting on it (the planar
:mod:`ctmm.planar_counting`) is not built for spatial bodies (under a preload the sweep's terms are not
symmetric).
"""
from __future__ import annotations

import dataclasses
import time
from typing import Any, Sequence

import numpy as np
import scipy.linalg

from . import validation
from .counting import PIVOT_TOLERANCE, certified_count
from .errors import ModelError
from .ops import NUMPY
from .results import FrequencyResponse, ModalResult
from .saturation import refuse_saturation

__all__ = ["is_spatial_system", "mass_matrix", "SpatialModes", "natural_frequencies", "mode_shapes", "eigenvalue_count",
           "frequency_response", "SYMMETRY_TOLERANCE", "UNDAMPED_TOLERANCE",
           "rayleigh_modes", "ZERO_MODE_FACTOR", "RESOLUTION"]

SYMMETRY_TOLERANCE = 1e-8
"""Largest ``|K - K^T|`` accepted as symmetric, relative to ``max |K|``."""
UNDAMPED_TOLERANCE = 1e-8
"""Largest ``|C|`` counted as undamped, relative to ``sqrt(max |K| max |M|)``."""
ZERO_MODE_FACTOR = 8.0
"""Round-off of ``omega_k^2`` in units of ``n eps max|K| |x_k|_1^2`` (:func:`rayleigh_modes`)."""
RESOLUTION = 1e2
"""Modes with ``noise < |omega^2| <= RESOLUTION * noise`` are refused as unresolved (fewer than two digits)."""


def mass_matrix(model: Any, q: np.ndarray, t: float = 0.0) -> np.ndarray:
    """``M(q)`` (nv, nv) of a spatial model in its velocity coordinates, from one batched sweep.

    Row ``0`` of the batch is the model at rest, row ``1 + k`` the same with a unit generalised force
    added to velocity ``k``'s joint law; the difference of their accelerations is column ``k`` of ``M^-1``.
    """
    from .articulated import articulated_sweep
    from .spatial.body_forms import SpatialScene

    n = model.n_velocities
    scene = SpatialScene(model)
    q_rows = np.repeat(np.asarray(q, dtype=float)[None], n + 1, axis=0)
    bodies, joints, _ = scene.terms(NUMPY, q_rows, np.zeros((n + 1, n)), t, scene.numpy_inputs(None, t, n + 1))
    unit = np.vstack([np.zeros((1, n)), np.eye(n)])
    forced = []
    for joint, terms, layout in zip(model.joints, joints, model.layout):
        k = layout.velocity.stop - layout.velocity.start
        if joint.driven or k == 0:
            forced.append(terms)
            continue
        extra = unit[:, layout.velocity][:, :, None]
        forced.append(dataclasses.replace(terms, tau=extra if terms.tau is None else terms.tau + extra))
    for j, layout in enumerate(model.modal):                # beams: unit generalised forces on the modal equations
        if layout is not None:
            h = np.array(np.broadcast_to(bodies[j].h, (n + 1,) + bodies[j].h.shape[1:]))
            h[:, 6:, :] -= unit[:, layout.velocity][:, :, None]
            bodies[j] = dataclasses.replace(bodies[j], h=h)
    solution = articulated_sweep(NUMPY, scene.tree, bodies, forced)
    parts = [np.broadcast_to(np.asarray(a), (n + 1,) + np.asarray(a).shape[1:])[:, :, 0]
             for a in scene.velocity_rates(solution)]
    rates = np.concatenate(parts, axis=1)
    inverse = (rates[1:] - rates[:1]).T
    inverse = 0.5 * (inverse + inverse.T)
    return np.linalg.inv(inverse)


@dataclasses.dataclass(frozen=True)
class SpatialModes:
    """Symmetric linearisation of a spatial model: ``M``, ``K`` (nv, nv) in tangent coordinates, the
    operating point and the tangent names."""

    model: Any
    mass: np.ndarray
    stiffness: np.ndarray
    operating_point: Any
    names: tuple[str, ...]

    def raw(self, omega: np.ndarray) -> tuple[np.ndarray, np.ndarray]:
        """Sylvester count (negative eigenvalues of ``K - omega^2 M``) and the smallest eigenvalue in
        size relative to ``max |K| + omega^2 max |M|``, at each ``omega`` (B,) [rad/s]."""
        omega = np.asarray(omega, dtype=float)
        squared = (omega * omega)[:, None, None]
        values = np.linalg.eigvalsh(self.stiffness[None] - squared * self.mass[None])
        scale = float(np.max(np.abs(self.stiffness), initial=0.0)) + squared[:, 0, 0] * float(np.max(np.abs(self.mass)))
        scale = np.where(scale > 0, scale, 1.0)
        return np.sum(values < 0.0, axis=1), np.min(np.abs(values), axis=1, initial=np.inf) / scale

    def determinant_sign(self, omega: np.ndarray) -> np.ndarray:
        """Sign of ``det(K - omega^2 M)``."""
        omega = np.asarray(omega, dtype=float)
        return np.linalg.slogdet(self.stiffness[None] - (omega * omega)[:, None, None] * self.mass[None])[0]

    def count(self, omega: Any) -> np.ndarray:
        """Number of natural frequencies strictly below each ``omega`` [rad/s] (certified)."""
        omega = np.atleast_1d(np.asarray(omega, dtype=float)).reshape(-1)
        if omega.size == 0:
            return np.zeros(0, dtype=np.int64)

        def side(lower: np.ndarray, upper: np.ndarray) -> np.ndarray:
            return self.determinant_sign(lower) != self.determinant_sign(upper * (1.0 - 1e-12))

        counted = certified_count(self.raw, omega, tolerance=PIVOT_TOLERANCE, side=side)
        # Below half the lowest non-zero frequency only the rigid-body modes (omega = 0, told apart from modes
        # within their round-off as solve() does) can lie below omega: the Sylvester count there reads the sign
        # of K's round-off along them (the symmetric arm of docs/spatial.md §9 counted 2 at omega = 0 and 1 at
        # 1e-9 rad/s).  solve() certifies that count at its lowest probe, 0.5 * lowest.
        values, _, noise = rayleigh_modes(self.stiffness, self.mass)
        rigid = np.abs(values) <= noise
        flexible = values[~rigid]
        if not np.any(flexible <= 0.0):
            low = omega < 0.5 * np.sqrt(np.min(flexible, initial=np.inf))
            counted[low] = np.where(omega[low] > 0.0, int(np.sum(rigid)), 0)
        return counted

    def solve(self, verb: str) -> tuple[np.ndarray, np.ndarray]:
        """Natural frequencies [rad/s] ascending (rigid-body modes 0) and M-orthonormal shapes, certified
        by :meth:`count` (module docstring)."""
        values, vectors, noise = rayleigh_modes(self.stiffness, self.mass)
        unstable = values < -noise
        if np.any(unstable):
            raise ModelError(f"model {self.model.name!r} is statically unstable about q = "
                             f"{self.operating_point.q.tolist()}: {int(np.sum(unstable))} mode(s) with "
                             f"negative stiffness (omega^2 = {values[unstable].tolist()} rad^2/s^2 < 0); natural "
                             "frequencies exist only about a stable equilibrium")
        unresolved = (np.abs(values) > noise) & (np.abs(values) <= RESOLUTION * noise)
        if np.any(unresolved):
            raise ModelError(f"{verb}: the mode(s) of {self.model.name!r} with omega^2 = {values[unresolved].tolist()} "
                             f"rad^2/s^2 cannot be told from rigid-body modes (round-off of K - omega^2 M about "
                             f"{noise[unresolved].tolist()} rad^2/s^2: stiffness spread over too many decades); "
                             "soften the stiffest part or use a model without it")
        omega = np.sqrt(np.where(np.abs(values) <= noise, 0.0, values))
        order = np.argsort(omega, kind="stable")
        omega, vectors = omega[order], vectors[:, order]
        positive = omega[omega > 0.0]
        if positive.size:
            distinct = np.unique(positive)
            distinct = distinct[np.concatenate([[True], np.diff(distinct) > 1e-9 * distinct[1:]])]
            probes = np.concatenate([0.5 * (distinct[:-1] + distinct[1:]), [2.0 * distinct[-1]],
                                     [0.5 * distinct[0]]])
            expected = np.sum(omega[None, :] < probes[:, None], axis=1)
            counted = self.count(probes)
            if not np.array_equal(counted, expected):
                raise ModelError(f"{verb}: the Sylvester count of K - omega^2 M of {self.model.name!r} disagrees with "
                                 f"its eigenvalues (counts {counted.tolist()} != {expected.tolist()} at omega = "
                                 f"{probes.tolist()} rad/s); the linearisation is ill-conditioned")
        return omega, vectors


def rayleigh_modes(stiffness: np.ndarray, mass: np.ndarray) -> tuple[np.ndarray, np.ndarray, np.ndarray]:
    """``omega_k^2`` [rad^2/s^2], M-orthonormal shapes (columns) and the round-off of each ``omega_k^2`` of
    the symmetric pencil ``(K, M)``.

    ``omega_k^2`` is the Rayleigh quotient ``x_k^T K x_k`` of the shape of ``eigh(K, M)`` (``x_k^T M x_k = 1``):
    exact to the round-off of ``K`` along ``x_k``, where ``eigh``'s own value carries ``eps omega_max^2``.
    Each entry of ``K`` is known to ``eps max|K|`` (an entry that should be 0, such as the stiffness of a free
    yaw, is the round-off of sums of terms as large as the stiffest), so ``x_k^T K x_k`` is known to
    ``noise_k = ZERO_MODE_FACTOR n eps max|K| |x_k|_1^2``: a mode with ``|omega_k^2| <= noise_k`` cannot be
    told from a rigid-body mode by any computation on ``K`` and is one (``omega_k = 0``); any larger value
    is a mode, however far below ``omega_max`` (no cut relative to the stiffest mode).
    """
    _, vectors = scipy.linalg.eigh(stiffness, mass)
    values = np.einsum("ik,ij,jk->k", vectors, stiffness, vectors)
    size = float(np.max(np.abs(stiffness), initial=0.0))
    noise = ZERO_MODE_FACTOR * stiffness.shape[0] * np.finfo(float).eps * size * np.sum(np.abs(vectors), axis=0) ** 2
    order = np.argsort(values, kind="stable")
    return values[order], vectors[:, order], noise[order]


def is_spatial_system(system: Any) -> bool:
    """True for a SpatialModel or a ControlledModel whose plant is one."""
    from .spatial.model import SpatialModel

    return isinstance(system, SpatialModel) or (isinstance(getattr(system, "plant", None), SpatialModel)
                                                and hasattr(system, "loops"))


def _split(system: Any, verb: str) -> tuple[Any, tuple]:
    """``(plant, loops)`` of a spatial model or of a controlled one (saturating loops refused)."""
    from .spatial.model import SpatialModel

    if isinstance(system, SpatialModel):
        return system, ()
    refuse_saturation(system.loops, verb)
    return system.plant, tuple(system.loops)


def _modes(system: Any, verb: str, operating_point: Any) -> SpatialModes:
    from .spatial_linearization import operating_point as spatial_operating_point
    from .spatial_linearization import tangent, tangent_names

    model, loops = _split(system, verb)
    if loops:
        raise ModelError(f"{verb} cannot honour the feedback loops {[lp.name for lp in loops]} of {model.name!r}: it "
                         "describes an uncontrolled model; for the closed loop use ctmm.linearize (eigenvalues of the "
                         "closed-loop A, delays beside it) or ctmm.stability.characteristic_roots; for the plant pass "
                         "system.plant")
    A, op = tangent(model, spatial_operating_point(model, operating_point))
    n = model.n_velocities
    M = mass_matrix(model, op.q, op.t)
    K, C = -M @ A[n:, :n], -M @ A[n:, n:]
    k_size = max(float(np.max(np.abs(K), initial=0.0)), 1e-300)
    if np.max(np.abs(C), initial=0.0) > UNDAMPED_TOLERANCE * np.sqrt(k_size * float(np.max(np.abs(M)))):
        raise ModelError(f"{verb} needs an undamped system, but {model.name!r} has velocity-dependent forces at the "
                         f"operating point (largest |C| = {np.max(np.abs(C)):.3e}: joint dampers); use "
                         "ctmm.frequency_response, or the eigenvalues of ctmm.linearize(model).state_space.A")
    if np.max(np.abs(K - K.T), initial=0.0) > SYMMETRY_TOLERANCE * k_size:
        raise ModelError(f"{verb}: the stiffness of {model.name!r} at the operating point is not symmetric (largest "
                         f"|K - K^T| = {np.max(np.abs(K - K.T)):.3e} of {k_size:.3e}: a circulatory law, e.g. an "
                         "anisotropic rotary spring deflected from its rest rotation); use ctmm.linearize")
    return SpatialModes(model, 0.5 * (M + M.T), 0.5 * (K + K.T), op, tangent_names(model))


def natural_frequencies(system: Any, *, n_modes: int | None = None, omega_max: float | None = None,
                        operating_point: Any = None) -> np.ndarray:
    """Undamped natural frequencies [rad/s] of a spatial model's linearisation (ascending, rigid as 0).

    Parameters
    ----------
    system : SpatialModel
        Undamped (else :class:`ModelError`).
    n_modes : int, optional
        Number of lowest frequencies.
    omega_max : float, optional
        All frequencies below ``omega_max`` [rad/s] instead.
    operating_point : optional
        As for :func:`ctmm.linearize` (default: the static equilibrium).
    """
    return _selected(system, "natural_frequencies", n_modes, omega_max, operating_point)[0]


def _selected(system, verb, n_modes, omega_max, operating_point):
    validation.one_mode_limit(n_modes, omega_max)
    modes = _modes(system, verb, operating_point)
    omega, vectors = modes.solve(verb)
    keep = validation.selected_modes(omega, n_modes, omega_max,
                                     f"model {system.name!r} (one per tangent coordinate)")
    return omega[keep], vectors[:, keep], modes


def mode_shapes(system: Any, *, n_modes: int | None = None, omega_max: float | None = None,
                operating_point: Any = None) -> ModalResult:
    """Natural frequencies and mode shapes in the tangent coordinates of a spatial model.

    ``shapes[k, i, 0]`` is tangent coordinate ``i`` (``point_names``: :func:`ctmm.spatial_linearization.tangent_names`)
    in mode ``k``, normalised to unit largest entry; otherwise as :func:`natural_frequencies`.  Modes of a
    repeated frequency are an M-orthogonal basis of its eigenspace.
    """
    omega, vectors, modes = _selected(system, "mode_shapes", n_modes, omega_max, operating_point)
    if vectors.size:
        ref = vectors[np.argmax(np.abs(vectors), axis=0), np.arange(vectors.shape[1])]
        vectors = vectors / ref
    return ModalResult(omega, vectors.T[:, :, None], ("amplitude",), modes.names)


def eigenvalue_count(system: Any, omega: Any, *, operating_point: Any = None) -> np.ndarray:
    """Number of undamped natural frequencies of a spatial model's linearisation strictly below each
    ``omega`` [rad/s] (Sylvester count of ``K - omega^2 M``, certified; module docstring)."""
    omega = validation.frequencies("omega", omega)
    modes = _modes(system, "eigenvalue_count", operating_point)
    return modes.count(omega.reshape(-1)).reshape(omega.shape)


def frequency_response(system: Any, omega: Any, *, input: str | Sequence[str],  # noqa: A002
                       output: str | Sequence[str], operating_point: Any = None) -> FrequencyResponse:
    """Frequency response of a spatial model's linearisation, loops closed with exact delays.

    At a static equilibrium (gravity and static loads included; joints as listed in
    :mod:`ctmm.spatial_transfer_response`) and with ports, tangent coordinates and loop signals as names, the
    plant's ``G(s)`` comes from the one sweep's frequency context batched over ``omega`` and every loop
    ``u = -C(s) e^{-s tau} (y - r)`` is closed at each frequency (:mod:`ctmm.sweep_response`); the frequencies
    whose pivots or loop matrix it does not certify, and every other model, take the dense resolvent
    ``C (i omega I - A)^-1 B`` of :func:`ctmm.linearize` (loops without delay closed inside ``A``, delayed
    loops per frequency: :func:`ctmm.controlled_linearization.delayed_loop_response`), which refuses a
    frequency at a pole.  ``info["method"]`` names the path, ``info["n_dense_frequencies"]`` the number of
    frequencies the resolvent answered.

    Parameters
    ----------
    system : SpatialModel or ControlledModel
    omega : array_like
        Angular frequencies [rad/s], >= 0.
    input : str or sequence of str
        Actuator ports (``"yaw.torque"`` [N m], ``"link.tip.force_x"`` [N]), input components
        (:func:`ctmm.spatial_linearization.input_names`, ``"base.wrench_fz"`` [N]) or ``"<loop>.reference"``.
    output : str or sequence of str
        Sensor ports (:mod:`ctmm.spatial.ports`), tangent coordinates [rad, m] and velocities [rad/s, m/s]
        (:func:`ctmm.linearize`), ``"<loop>.y"``, ``"<loop>.u"``.
    operating_point : optional
        As for :func:`ctmm.linearize` (default: the plant's static equilibrium).

    Returns
    -------
    FrequencyResponse
        ``response[i_out, i_in, k]``: output deviation phasor per unit input phasor.
    """
    from .controlled_linearization import delayed_loop_response
    from .spatial.ports import SpatialPorts
    from .spatial_linearization import linearize_spatial

    model, loops = _split(system, "the frequency-domain verbs")
    inputs = list(validation.names("input", input))
    outputs = list(validation.names("output", output))
    s = 1j * validation.frequencies("omega", omega)
    started = time.perf_counter()

    ports = SpatialPorts(model)
    plant, point = _sweep_plant(model, loops, inputs, outputs, operating_point, ports)
    dense = int(s.size)

    def resolvent(part: np.ndarray) -> tuple[np.ndarray, Any]:
        return delayed_loop_response(
            lambda lin_in, lin_out: linearize_spatial(model, point, inputs=lin_in, outputs=lin_out, loops=loops),
            loops, part, inputs, outputs, model.name)

    if plant is None:
        response, lin = resolvent(s)
        op = lin.operating_point
    else:
        from .sweep_response import closed_loop_response

        response, good = closed_loop_response(plant, loops, s, inputs, outputs)
        dense, op = int(np.sum(~good)), plant.point
        if dense:                       # frequencies the sweep does not certify: the dense resolvent's rule
            response[:, :, ~good] = resolvent(s[~good])[0]
    units = {name: ports.actuator_unit(name) for name in inputs if name in ports.actuators}
    units.update({name: ports.sensor_unit(name) for name in outputs if name in ports.sensors})
    method = ("linearisation (ctmm.linearize), delays exact" if plant is None
              else "one sweep's frequency context (ctmm.spatial_transfer_response), delays exact")
    info = {"method": method, "wall_time_s": time.perf_counter() - started, "n_frequencies": int(s.size),
            "n_dense_frequencies": dense, "operating_point_q": op.q.tolist(), "jacobian_error": op.jacobian_error}
    return FrequencyResponse(np.imag(s), response, tuple(inputs), tuple(outputs), model.name, info=info, units=units)


def _sweep_plant(model: Any, loops: Sequence[Any], inputs: Sequence[str], outputs: Sequence[str],
                 operating_point: Any, ports: Any) -> tuple[Any, Any]:
    """The :class:`~ctmm.spatial_transfer_response.SpatialSweepResponse` of the plant, or ``None`` where the
    sweep's frequency context does not state it or a name is not a plain port, tangent coordinate or loop signal
    (the dense path answers, with its own messages); and the operating point (as given where it was not
    resolved here)."""
    from .spatial_linearization import operating_point as spatial_operating_point
    from .spatial_linearization import tangent_names
    from .spatial_transfer_response import SpatialSweepResponse, model_applies, sweep_applies

    if not model_applies(model):            # before the equilibrium search: the dense path makes its own
        return None, operating_point
    loop_names = {lp.name for lp in loops}
    tangents = set(tangent_names(model)) | set(model.velocities)
    for name in inputs:
        head, _, tail = name.partition(".")
        if name not in ports.actuators and not (head in loop_names and tail == "reference"):
            return None, operating_point
    for name in outputs:
        head, _, tail = name.partition(".")
        if name not in ports.sensors and name not in tangents and not (head in loop_names and tail in ("y", "u")):
            return None, operating_point
    try:
        point = spatial_operating_point(model, operating_point)
    except ModelError:
        return None, operating_point        # the dense path refuses it with its message
    try:
        return (SpatialSweepResponse(model, point, ports) if sweep_applies(model, point) else None), point
    except ModelError:                      # not stated by the sweep: the dense path at the same point
        return None, point
