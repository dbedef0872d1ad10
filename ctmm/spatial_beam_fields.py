"""Exact frequency-domain field transfer matrix of a straight spatial Euler-Bernoulli beam.

State layout :data:`SPATIAL_BEAM` (``d = 6``, ``n = 12``) at a station, in the chain's (global) axes::

    z = [ux, uy, uz, theta_x, theta_y, theta_z, fx, fy, fz, mx, my, mz]

displacements ``u`` [m], small rotations ``theta`` [rad] (right-handed), and the force ``f`` [N] and
moment ``m`` [N m] **exerted by the inboard part on the outboard part** about the station
(``docs/spatial.md`` §3 at displacement level: ``[A ; F]`` with ``F = [f ; m]``; displacement
component ``i`` and force component ``i`` are work-conjugate, as every ctmm layout requires).  The
book's order ``[.., m, q, 1]`` (seed 003 eq. 6.1) swaps the force and moment triples.

Derivation (``docs/spatial_beams.md`` §1).  Beam along its local ``x`` axis, constant axial tension
``T`` (the preload: ``f0 = -T e_x``), a slice ``[x, x + dx]`` with ``q(s) = rhoA s^2 + c_v s``:

* Newton: ``f(x) - f(x + dx) = q u dx``, so ``f' = -q u``;
* Euler about ``x`` on the deformed axis ``e_x + u'``: ``m' = -(e_x + u') x f`` linearised about
  ``f0``: ``m' = -e_x x f + T u' x e_x`` plus the torsional inertia ``-(rhoIp s^2 + c_t s) theta_x``;
* constitutive laws (section resultants on the inboard part's positive face are ``-f``, ``-m``):
  ``ux' = -fx / EA``, ``theta_x' = -mx / GJ``, ``theta_y' = -my / EI_y``, ``theta_z' = -mz / EI_z``;
  Euler-Bernoulli kinematics ``uy' = theta_z``, ``uz' = -theta_y``.

The system ``z' = A(s) z`` (:func:`spatial_beam_state_matrix`) splits into four decoupled sub-fields,
each solved in closed form:

* **axial** ``(ux, fx)``: ``ux'' = k^2 ux``, ``k^2 = q / EA*``::

      [ux; fx](L) = [[cosh kL, -L sinhc(kL) / EA*], [-EA* k^2 L sinhc(kL), cosh kL]] [ux; fx](0)

  (``sinhc z = sinh z / z``; ``cosh`` and ``sinhc`` are even in ``k``, so no branch of the root is
  chosen; for ``s = i omega`` undamped they are ``cos`` and ``sin``);
* **torsion** ``(theta_x, mx)``: the same with ``GJ*`` and ``q_t = rhoIp s^2 + c_t s``;
* **bending in the x-y plane** ``(uy, theta_z, fy, mz)``: exactly the planar field of
  :class:`ctmm.elements.beams.BeamField` (``w = uy``, ``theta = theta_z``, ``shear = fy``,
  ``moment = mz``, ``EI = EI_z``): ``uy' = theta_z``, ``theta_z' = -mz/EI_z``, ``fy' = -q uy``,
  ``mz' = -fy - T theta_z``;
* **bending in the x-z plane** ``(uz, theta_y, fz, my)``: the planar field with ``EI = EI_y`` in
  ``(w, theta, shear, moment) = (uz, -theta_y, fz, -my)``, i.e. ``U_xz = D U_planar D`` with
  ``D = diag(1, -1, 1, -1)`` (``uz' = -theta_y``, ``theta_y' = -my/EI_y``, ``fz' = -q uz``,
  ``my' = fz - T theta_y``).

Damping: a structural loss factor ``eta`` and a Kelvin-Voigt time ``tau`` multiply every stiffness
(``EA, GJ, EI_y, EI_z``) by ``1 + i eta sgn(Im s) + tau s``; ``c_v`` [N s/m^2] is external viscous
damping of the translations, ``c_t`` [N m s/m] of the twist.  A beam turned by ``rotation`` (local
to chain axes, its local ``x`` is ``rotation[:, 0]``) has ``U = R4 U_local R4^T``,
``R4 = diag(R, R, R, R)``.  Optional: the tension's effect on torsion (Wagner, ``wagner_term``:
``GJ -> GJ + T I_p / A``, :mod:`ctmm.spatial_beam_torsion`) and the section's rotary inertia in
bending (Rayleigh, ``rotary_inertia_per_length_y/z``: ``T -> T + rho I s^2`` in the moment equation,
:mod:`ctmm.spatial_beam_rayleigh`).  Not modelled: shear deformation (Timoshenko), warping, the
axial-bending coupling of an unsymmetric section (the section's principal axes are the local ``y``,
``z``).

:class:`SpatialVaryingTensionField`: the same field with a tension varying linearly along it (a beam
hanging or standing in gravity); its bending planes are error-controlled Magnus fields
(:mod:`ctmm.elements.bending_preload`), checked against an ODE integration of ``A(x, s)``
(``tests/test_spatial_exact_gravity.py``).

``tests/test_spatial_beam_fields.py`` checks ``U`` against ``scipy.linalg.expm(A L)`` (with tension,
damping and rotation) and that ``U`` is symplectic (reciprocity).
"""
from __future__ import annotations

import math
from typing import Any

import numpy as np
import scipy.linalg

from . import validation
from .elements.base import Element
from .elements.beams import BeamField
from .elements.bending import laplace_array
from .elements.bending_preload import DEFAULT_TOLERANCE, VaryingTensionBeamField
from .errors import ModelError
from .layouts import StateLayout
from .spatial_beam_rayleigh import RayleighPlane
from .spatial_beam_torsion import bar_matrix, clamped_bar_count, varying_bar_matrix

__all__ = ["SPATIAL_BEAM", "SpatialBeamField", "SpatialVaryingTensionField", "spatial_beam_state_matrix",
           "rotation_matrix_check",
           "AXIAL", "TORSION", "BENDING_XY", "BENDING_XZ"]

SPATIAL_BEAM = StateLayout("spatial_beam", ("ux", "uy", "uz", "theta_x", "theta_y", "theta_z"),
                           ("fx", "fy", "fz", "mx", "my", "mz"))
"""Spatial beam chain, small motion: displacements [m], rotations [rad], force [N] and moment
[N m] by the inboard on the outboard part, chain axes (module docstring)."""

#: State indices of the decoupled sub-fields in the local frame.
AXIAL = (0, 6)
TORSION = (3, 9)
BENDING_XY = (1, 5, 7, 11)
BENDING_XZ = (2, 4, 8, 10)
_XZ_SIGNS = np.array([1.0, -1.0, 1.0, -1.0])

#: Largest dimensionless wave number (bending ``beta``, axial / torsional ``k L``, tension
#: ``sqrt(|T|/EI) L``) of a piece made by :meth:`SpatialBeamField.subdivide`.
SUBDIVISION_LIMIT = 4.0
#: Largest wave number for which :meth:`SpatialBeamField.transfer_matrix` answers: the Riccati
#: transfer through one field loses about ``e^beta eps`` (2e-9 at 16); longer fields must be split.
MAX_WAVE_NUMBER = 16.0


def rotation_matrix_check(name: str, rotation: Any) -> np.ndarray:
    """``rotation`` as a proper orthonormal 3 x 3 matrix, or a :class:`ModelError`."""
    try:
        R = np.array(rotation, dtype=float)
    except (TypeError, ValueError):
        raise ModelError(f"{name} must be a 3 x 3 rotation matrix, got {rotation!r}") from None
    if R.shape != (3, 3) or not np.all(np.isfinite(R)):
        raise ModelError(f"{name} must be a finite 3 x 3 rotation matrix, got shape {R.shape}")
    if np.max(np.abs(R.T @ R - np.eye(3))) > 1e-10 or np.linalg.det(R) < 0:
        raise ModelError(f"{name} must be orthonormal with determinant +1 (a rotation), got {R.tolist()}")
    return R


def spatial_beam_state_matrix(s: complex, *, axial_stiffness: complex, torsional_stiffness: complex,
                              bending_stiffness_y: complex, bending_stiffness_z: complex,
                              mass_per_length: float, polar_inertia_per_length: float,
                              axial_force: float = 0.0, viscous_damping: float = 0.0,
                              torsional_damping: float = 0.0, rotary_inertia_y: float = 0.0,
                              rotary_inertia_z: float = 0.0) -> np.ndarray:
    """System matrix ``A`` (12 x 12) of ``z' = A z`` in the beam's local frame, one ``s``.

    Parameters
    ----------
    s : complex
        Laplace variable [1/s].
    axial_stiffness, torsional_stiffness, bending_stiffness_y, bending_stiffness_z : complex
        Effective ``EA*`` [N], ``GJ*`` [N m^2] (with the Wagner term ``T I_p / A`` when wanted),
        ``EI_y*``, ``EI_z*`` [N m^2].
    mass_per_length : float
        ``rhoA`` [kg/m].
    polar_inertia_per_length : float
        ``rhoIp`` [kg m], mass moment of inertia per length about the beam axis.
    axial_force : float
        Tension ``T`` [N] (negative: compression).
    viscous_damping, torsional_damping : float
        ``c_v`` [N s/m^2], ``c_t`` [N m s/m].
    rotary_inertia_y, rotary_inertia_z : float
        ``rho I_y``, ``rho I_z`` [kg m]: section rotary inertia of bending about the local y (x-z plane)
        and z (x-y plane) axes (Rayleigh beam, :mod:`ctmm.spatial_beam_rayleigh`; 0: Euler-Bernoulli).
    """
    q = mass_per_length * s * s + viscous_damping * s
    q_t = polar_inertia_per_length * s * s + torsional_damping * s
    T = axial_force
    A = np.zeros((12, 12), dtype=complex)
    A[0, 6] = -1 / axial_stiffness
    A[1, 5] = 1.0
    A[2, 4] = -1.0
    A[3, 9] = -1 / torsional_stiffness
    A[4, 10] = -1 / bending_stiffness_y
    A[5, 11] = -1 / bending_stiffness_z
    A[6, 0] = A[7, 1] = A[8, 2] = -q
    A[9, 3] = -q_t
    A[10, 8], A[10, 4] = 1.0, -T - rotary_inertia_y * s * s     # my' = fz - (T + rhoI_y s^2) theta_y
    A[11, 7], A[11, 5] = -1.0, -T - rotary_inertia_z * s * s    # mz' = -fy - (T + rhoI_z s^2) theta_z
    return A


class SpatialBeamField(Element):
    """Uniform straight spatial Euler-Bernoulli beam with its exact field transfer matrix.

    Parameters
    ----------
    name : str
        Element name.
    length : float
        ``L`` [m], > 0.
    axial_stiffness : float
        ``EA`` [N], > 0.
    torsional_stiffness : float
        ``GJ`` [N m^2], > 0.
    bending_stiffness_y, bending_stiffness_z : float
        ``EI_y`` (bending in the local x-z plane, about y) and ``EI_z`` (x-y plane, about z)
        [N m^2], > 0.
    mass_per_length : float
        ``rhoA`` [kg/m], > 0.
    polar_inertia_per_length : float
        ``rhoIp`` [kg m], > 0: mass moment of inertia per length about the axis (``rho (I_y + I_z)``
        for a homogeneous section).
    axial_force : float, optional
        Constant tension ``T`` [N] (negative: compression); geometric stiffening of both
        bending planes (and of the twist with ``wagner_term``).
    loss_factor : float, optional
        Structural loss factor ``eta >= 0`` on every stiffness (exact for ``s = i omega``).
    kelvin_voigt_time : float, optional
        Strain-rate damping time ``tau >= 0`` [s] on every stiffness.
    viscous_damping : float, optional
        External viscous damping of the translations ``c_v >= 0`` [N s/m^2].
    torsional_damping : float, optional
        External viscous damping of the twist ``c_t >= 0`` [N m s/m].
    rotation : array_like (3, 3), optional
        Local to chain axes (default identity: the beam lies along the chain's ``x``).
    wagner_term : bool, optional
        Torsion stiffened by the tension (Wagner): ``GJ + T I_p / A`` with ``I_p / A`` [m^2] taken as
        ``polar_inertia_per_length / mass_per_length`` (a homogeneous, doubly symmetric section;
        derivation in :mod:`ctmm.spatial_beam_torsion`).  Default False (Saint-Venant torsion only).
    rotary_inertia_per_length_y, rotary_inertia_per_length_z : float, optional
        Section rotary inertia ``rho I_y``, ``rho I_z`` >= 0 [kg m] of bending about the local y (x-z
        plane) and z (x-y plane) axes: a Rayleigh beam (:mod:`ctmm.spatial_beam_rayleigh`); default 0
        (Euler-Bernoulli).  For a homogeneous section ``rho I_y + rho I_z = polar_inertia_per_length``.

    Notes
    -----
    ``transfer_matrix(s)`` maps :data:`SPATIAL_BEAM` states from the inboard end to the outboard
    end (module docstring).  ``subdivide`` cuts the beam into pieces that keep every sub-field's
    wave number ``<= 4`` (Riccati transfer and Wittrick-Williams count at round-off level for
    high modes); ``clamped_frequency_count`` is the sum of the four sub-fields' clamped-clamped
    counts (``J0`` of Wittrick-Williams).
    """

    layout = SPATIAL_BEAM
    is_point = False

    def __init__(self, name: str, length: float, *, axial_stiffness: float, torsional_stiffness: float,
                 bending_stiffness_y: float, bending_stiffness_z: float, mass_per_length: float,
                 polar_inertia_per_length: float, axial_force: float = 0.0, loss_factor: float = 0.0,
                 kelvin_voigt_time: float = 0.0, viscous_damping: float = 0.0, torsional_damping: float = 0.0,
                 rotation: Any = None, wagner_term: bool = False, rotary_inertia_per_length_y: float = 0.0,
                 rotary_inertia_per_length_z: float = 0.0) -> None:
        super().__init__(name)
        self.length = validation.positive(f"{name}: length", length)
        self.axial_stiffness = validation.positive(f"{name}: axial_stiffness", axial_stiffness)
        self.torsional_stiffness = validation.positive(f"{name}: torsional_stiffness", torsional_stiffness)
        self.bending_stiffness_y = validation.positive(f"{name}: bending_stiffness_y", bending_stiffness_y)
        self.bending_stiffness_z = validation.positive(f"{name}: bending_stiffness_z", bending_stiffness_z)
        self.mass_per_length = validation.positive(f"{name}: mass_per_length", mass_per_length)
        self.polar_inertia_per_length = validation.positive(f"{name}: polar_inertia_per_length",
                                                            polar_inertia_per_length)
        self.axial_force = validation.finite(f"{name}: axial_force", axial_force)
        self.loss_factor = validation.nonnegative(f"{name}: loss_factor", loss_factor)
        self.kelvin_voigt_time = validation.nonnegative(f"{name}: kelvin_voigt_time", kelvin_voigt_time)
        self.viscous_damping = validation.nonnegative(f"{name}: viscous_damping", viscous_damping)
        self.torsional_damping = validation.nonnegative(f"{name}: torsional_damping", torsional_damping)
        self.rotation = np.eye(3) if rotation is None else rotation_matrix_check(f"{name}: rotation", rotation)
        if not isinstance(wagner_term, (bool, np.bool_)):
            raise ModelError(f"{name}: wagner_term must be True or False, got {wagner_term!r}")
        self.wagner_term = bool(wagner_term)
        self.rotary_inertia_per_length_y = validation.nonnegative(f"{name}: rotary_inertia_per_length_y",
                                                                  rotary_inertia_per_length_y)
        self.rotary_inertia_per_length_z = validation.nonnegative(f"{name}: rotary_inertia_per_length_z",
                                                                  rotary_inertia_per_length_z)
        self._check_torsional_stiffness()
        damping = {"loss_factor": self.loss_factor, "kelvin_voigt_time": self.kelvin_voigt_time,
                   "viscous_damping": self.viscous_damping}
        self._planes = tuple(
            RayleighPlane(self.length, stiffness, self.mass_per_length, rotary, axial_force=self.axial_force, **damping)
            if rotary else BeamField(f"{name}__{plane}", self.length, stiffness, self.mass_per_length,
                                     axial_force=self.axial_force, **damping)
            for plane, stiffness, rotary in (("xy", self.bending_stiffness_z, self.rotary_inertia_per_length_z),
                                             ("xz", self.bending_stiffness_y, self.rotary_inertia_per_length_y)))

    def end_tensions(self) -> tuple[float, float]:
        """Axial tension [N] at the inboard and the outboard end."""
        return self.axial_force, self.axial_force

    def wagner_stiffness(self, tension: float) -> float:
        """The Wagner term ``T I_p / A`` [N m^2] at the tension ``T`` [N] (0 without ``wagner_term``)."""
        if not self.wagner_term:
            return 0.0
        return tension * self.polar_inertia_per_length / self.mass_per_length

    def torsional_stiffness_at_ends(self) -> tuple[float, float]:
        """Undamped torsion-bar stiffness ``GJ + T I_p / A`` [N m^2] at the inboard and outboard end."""
        return tuple(self.torsional_stiffness + self.wagner_stiffness(t) for t in self.end_tensions())

    def _check_torsional_stiffness(self) -> None:
        for tension, stiffness in zip(self.end_tensions(), self.torsional_stiffness_at_ends()):
            if stiffness <= 0.0:
                raise ModelError(f"{self.name}: the compression {-tension:.6g} N with wagner_term makes the torsional "
                                 f"stiffness GJ + T I_p / A = {stiffness:.6g} N m^2 <= 0 (torsional buckling); the "
                                 "straight beam is no equilibrium to vibrate about")

    # -- parameters --------------------------------------------------------------------
    def parameters(self) -> dict[str, Any]:
        return {"length": self.length, "axial_stiffness": self.axial_stiffness,
                "torsional_stiffness": self.torsional_stiffness, "bending_stiffness_y": self.bending_stiffness_y,
                "bending_stiffness_z": self.bending_stiffness_z, "mass_per_length": self.mass_per_length,
                "polar_inertia_per_length": self.polar_inertia_per_length, "axial_force": self.axial_force,
                "loss_factor": self.loss_factor, "kelvin_voigt_time": self.kelvin_voigt_time,
                "viscous_damping": self.viscous_damping, "torsional_damping": self.torsional_damping,
                "rotation": self.rotation.tolist(), "wagner_term": self.wagner_term,
                "rotary_inertia_per_length_y": self.rotary_inertia_per_length_y,
                "rotary_inertia_per_length_z": self.rotary_inertia_per_length_z}

    @property
    def is_conservative(self) -> bool:
        """False when any damping parameter is non-zero (checked by ``natural_frequencies``)."""
        return not (self.loss_factor or self.kelvin_voigt_time or self.viscous_damping or self.torsional_damping)

    def stiffness_factor(self, s: Any) -> np.ndarray:
        """``1 + i eta sgn(Im s) + tau s`` over ``s`` (multiplies every stiffness)."""
        s = laplace_array(s)
        return 1 + 1j * self.loss_factor * np.where(s.imag < 0, -1.0, 1.0) + self.kelvin_voigt_time * s

    def state_matrix(self, s: complex) -> np.ndarray:
        """``A(s)`` of ``z' = A z`` in chain axes (12 x 12, one ``s``); ``U = expm(A L)``."""
        s = complex(s)
        factor = complex(self.stiffness_factor(s))
        A = spatial_beam_state_matrix(
            s, axial_stiffness=self.axial_stiffness * factor,
            torsional_stiffness=self.torsional_stiffness * factor + self.wagner_stiffness(self.axial_force),
            bending_stiffness_y=self.bending_stiffness_y * factor,
            bending_stiffness_z=self.bending_stiffness_z * factor,
            mass_per_length=self.mass_per_length, polar_inertia_per_length=self.polar_inertia_per_length,
            axial_force=self.axial_force, viscous_damping=self.viscous_damping,
            torsional_damping=self.torsional_damping, rotary_inertia_y=self.rotary_inertia_per_length_y,
            rotary_inertia_z=self.rotary_inertia_per_length_z)
        R4 = scipy.linalg.block_diag(*([self.rotation] * 4))
        return R4 @ A @ R4.T

    def discretize(self, scheme: Any):
        """Refused: the spatial beam field is a frequency-domain element."""
        raise ModelError(f"element {self.name!r} (SpatialBeamField) has no time-domain form; in time use the modal "
                         "spatial beam body, or the frequency-domain verbs on this chain")

    # -- frequency domain --------------------------------------------------------------
    def transfer_matrix(self, s: Any) -> np.ndarray:
        """The exact field matrix (:meth:`field_matrix`) for the chain solvers, shape ``np.shape(s) + (12, 12)``.

        Raises
        ------
        ModelError
            When a wave number at ``max |s|`` exceeds :data:`MAX_WAVE_NUMBER`: a solver would lose
            ``e^beta eps`` through this one field (a wrong answer); split the beam
            (``*beam.split(beam.pieces_for(omega_max))``).  The counting verbs subdivide by
            themselves (:meth:`subdivide`).
        """
        s = laplace_array(s)
        largest = float(np.max(np.abs(s), initial=0.0))
        if max(self._wave_numbers(largest)) > MAX_WAVE_NUMBER:
            raise ModelError(f"{self.name}: at |s| = {largest:.6g} 1/s the field's wave number is "
                             f"{max(self._wave_numbers(largest)):.3g} > {MAX_WAVE_NUMBER} (a transfer through it "
                             f"loses e^beta eps); split the beam: *{self.name}.split({self.pieces_for(largest)})")
        return self.field_matrix(s)

    def field_matrix(self, s: Any) -> np.ndarray:
        """Exact ``U(s) = expm(A(s) L)`` in chain axes, shape ``np.shape(s) + (12, 12)`` (any size)."""
        s = laplace_array(s)
        factor = self.stiffness_factor(s)
        L = self.length
        U = np.zeros(s.shape + (12, 12), dtype=complex)
        axial = bar_matrix(L, self.axial_stiffness * factor, self.mass_per_length * s * s + self.viscous_damping * s)
        torsion = self._torsion_matrix(s, factor)
        for index, block in ((AXIAL, axial), (TORSION, torsion)):
            U[..., np.array(index)[:, None], np.array(index)[None, :]] = block
        xy = self._planes[0].transfer_matrix(s)
        xz = self._planes[1].transfer_matrix(s) * _XZ_SIGNS[:, None] * _XZ_SIGNS[None, :]
        for index, block in ((BENDING_XY, xy), (BENDING_XZ, xz)):
            U[..., np.array(index)[:, None], np.array(index)[None, :]] = block
        if np.array_equal(self.rotation, np.eye(3)):
            return U
        R4 = scipy.linalg.block_diag(*([self.rotation] * 4))
        return R4 @ U @ R4.T

    def _torsion_matrix(self, s: np.ndarray, factor: np.ndarray) -> np.ndarray:
        """Torsion bar ``(theta_x, mx)``, stiffness ``GJ* + T I_p / A`` (:mod:`ctmm.spatial_beam_torsion`)."""
        return bar_matrix(self.length, self.torsional_stiffness * factor + self.wagner_stiffness(self.axial_force),
                          self.polar_inertia_per_length * s * s + self.torsional_damping * s)

    def _wave_numbers(self, omega_max: float) -> list[float]:
        L, w = self.length, omega_max
        rho = self.mass_per_length
        numbers = [L * (rho * w * w / stiffness) ** 0.25
                   for stiffness in (self.bending_stiffness_y, self.bending_stiffness_z)]
        numbers += [w * L * math.sqrt(rho / self.axial_stiffness),
                    w * L * math.sqrt(self.polar_inertia_per_length / min(self.torsional_stiffness_at_ends()))]
        tension = max(abs(t) for t in self.end_tensions())
        numbers += [math.sqrt(tension / stiffness) * L for stiffness in (self.bending_stiffness_y, self.bending_stiffness_z)]
        numbers += [plane.wave_number(omega_max) for plane in self._planes if isinstance(plane, RayleighPlane)]
        return numbers

    def pieces_for(self, omega_max: float, *, limit: float = SUBDIVISION_LIMIT) -> int:
        """Number of equal pieces that keep every wave number ``<= limit`` up to ``omega_max`` [rad/s]."""
        omega_max = validation.nonnegative("omega_max", omega_max)
        limit = validation.positive("limit", limit)
        return max(1, math.ceil(max(self._wave_numbers(omega_max)) / limit))

    def split(self, pieces: int) -> tuple["SpatialBeamField", ...]:
        """``pieces`` equal segments ``"<name>_1" ...`` whose product equals this field."""
        pieces = validation.integer(f"{self.name}: pieces", pieces, minimum=1)
        params = self.parameters()
        params["length"] = self.length / pieces
        return tuple(SpatialBeamField(f"{self.name}_{i + 1}", **params) for i in range(pieces))

    def subdivide(self, omega_max: float) -> list["SpatialBeamField"]:
        """Equal pieces with every wave number ``<= SUBDIVISION_LIMIT`` up to ``omega_max`` [rad/s]."""
        pieces = self.pieces_for(omega_max)
        if pieces == 1:
            return [self]
        return [self.split(pieces)[0]] * pieces   # one object: solvers evaluate its matrix once

    # -- Wittrick-Williams -------------------------------------------------------------
    def clamped_frequency_count(self, omega: Any) -> np.ndarray:
        """Natural frequencies of the beam clamped at both ends strictly below ``omega`` [rad/s].

        ``J0`` of the Wittrick-Williams count: the sum over the four decoupled sub-fields, axial
        and torsional ``n pi / L sqrt(K / rho)`` (n >= 1) and each bending plane's count
        (:meth:`ctmm.elements.beams.BeamField.clamped_frequency_count`, with the tension).
        Damping parameters are ignored (undamped count).
        """
        omega = np.asarray(omega, dtype=float)
        if not np.all(np.isfinite(omega)) or np.any(omega < 0):
            raise ModelError(f"{self.name}: omega must be finite and >= 0 rad/s, got {omega!r}")
        count = clamped_bar_count(self.length, self.axial_stiffness, self.axial_stiffness, self.mass_per_length, omega)
        count = count + clamped_bar_count(self.length, *self.torsional_stiffness_at_ends(),
                                          self.polar_inertia_per_length, omega)
        for plane in self._planes:
            count = count + np.asarray(plane.clamped_frequency_count(omega), dtype=np.int64)
        return count


class SpatialVaryingTensionField(SpatialBeamField):
    """A :class:`SpatialBeamField` whose tension varies linearly from ``inboard_tension`` to ``outboard_tension`` [N].

    The preload of a beam hanging or standing in gravity along its axis.  The axial and torsional
    bars are those of :class:`SpatialBeamField`; each bending plane is a
    :class:`~ctmm.elements.bending_preload.VaryingTensionBeamField` (error-controlled sixth-order Magnus
    field, its own clamped count).  Parameters as :class:`SpatialBeamField` but ``axial_force``
    (``loss_factor``, ``viscous_damping``, ``torsional_damping`` and the rotary inertias are not offered);
    ``tolerance``: the planes' (and the torsion bar's) estimated relative error.  With ``wagner_term`` the
    torsion bar's stiffness ``GJ + T(x) I_p / A`` varies linearly along the field: an error-controlled
    sixth-order Magnus bar (:func:`ctmm.spatial_beam_torsion.varying_bar_matrix`, its own clamped count).
    """

    def __init__(self, name: str, length: float, *, inboard_tension: float, outboard_tension: float,
                 axial_stiffness: float, torsional_stiffness: float, bending_stiffness_y: float,
                 bending_stiffness_z: float, mass_per_length: float, polar_inertia_per_length: float,
                 kelvin_voigt_time: float = 0.0, rotation: Any = None, tolerance: float = DEFAULT_TOLERANCE,
                 wagner_term: bool = False) -> None:
        tensions = (validation.finite(f"{name}: inboard_tension", inboard_tension),
                    validation.finite(f"{name}: outboard_tension", outboard_tension))
        self.inboard_tension, self.outboard_tension = tensions
        super().__init__(name, length, axial_stiffness=axial_stiffness, torsional_stiffness=torsional_stiffness,
                         bending_stiffness_y=bending_stiffness_y, bending_stiffness_z=bending_stiffness_z,
                         mass_per_length=mass_per_length, polar_inertia_per_length=polar_inertia_per_length,
                         axial_force=max(tensions, key=abs), kelvin_voigt_time=kelvin_voigt_time, rotation=rotation,
                         wagner_term=wagner_term)
        self.tolerance = tolerance
        self._planes = tuple(VaryingTensionBeamField(f"{name}__{plane}", self.length, stiffness, self.mass_per_length,
                                                     inboard_tension=tensions[0], outboard_tension=tensions[1],
                                                     kelvin_voigt_time=self.kelvin_voigt_time, tolerance=tolerance)
                             for plane, stiffness in (("xy", self.bending_stiffness_z),
                                                      ("xz", self.bending_stiffness_y)))

    def parameters(self) -> dict[str, Any]:
        out = super().parameters()
        for key in ("axial_force", "loss_factor", "viscous_damping", "torsional_damping",
                    "rotary_inertia_per_length_y", "rotary_inertia_per_length_z"):
            del out[key]
        out.update(inboard_tension=self.inboard_tension, outboard_tension=self.outboard_tension,
                   tolerance=self.tolerance)
        return out

    def end_tensions(self) -> tuple[float, float]:
        """Axial tension [N] at the inboard and the outboard end."""
        return self.inboard_tension, self.outboard_tension

    def _torsion_matrix(self, s: np.ndarray, factor: np.ndarray) -> np.ndarray:
        """Torsion bar: the Wagner term makes ``GJ* + T(x) I_p / A`` vary linearly (Magnus bar)."""
        ends = [self.wagner_stiffness(t) for t in self.end_tensions()]
        if ends[0] == ends[1]:
            return super()._torsion_matrix(s, factor)
        GJ = self.torsional_stiffness * np.broadcast_to(factor, s.shape)
        return varying_bar_matrix(self.name, self.length, GJ + ends[0], GJ + ends[1],
                                  self.polar_inertia_per_length * s * s, self.tolerance)

    def state_matrix(self, s: complex) -> np.ndarray:
        """Refused: ``A`` varies along the field (use :meth:`state_matrix_at`)."""
        raise ModelError(f"{self.name}: the varying-tension field has no single A(s); use state_matrix_at(s, x)")

    def state_matrix_at(self, s: complex, x: float) -> np.ndarray:
        """``A(s)`` of ``z' = A z`` at ``x`` [m] from the inboard end, chain axes (12 x 12)."""
        s = complex(s)
        factor = complex(self.stiffness_factor(s))
        tension = self.inboard_tension + (self.outboard_tension - self.inboard_tension) * float(x) / self.length
        A = spatial_beam_state_matrix(
            s, axial_stiffness=self.axial_stiffness * factor,
            torsional_stiffness=self.torsional_stiffness * factor + self.wagner_stiffness(tension),
            bending_stiffness_y=self.bending_stiffness_y * factor, bending_stiffness_z=self.bending_stiffness_z * factor,
            mass_per_length=self.mass_per_length, polar_inertia_per_length=self.polar_inertia_per_length,
            axial_force=tension)
        R4 = scipy.linalg.block_diag(*([self.rotation] * 4))
        return R4 @ A @ R4.T

    def split(self, pieces: int) -> tuple["SpatialVaryingTensionField", ...]:
        """``pieces`` equal segments (tension continued linearly) whose product is this field."""
        pieces = validation.integer(f"{self.name}: pieces", pieces, minimum=1)
        edges = np.linspace(self.inboard_tension, self.outboard_tension, pieces + 1)
        params = self.parameters()
        params.update(length=self.length / pieces)
        return tuple(SpatialVaryingTensionField(f"{self.name}_{i + 1}", **{**params, "inboard_tension": float(edges[i]),
                                                                          "outboard_tension": float(edges[i + 1])})
                     for i in range(pieces))

    def subdivide(self, omega_max: float) -> list["SpatialVaryingTensionField"]:
        """Pieces with every wave number ``<= SUBDIVISION_LIMIT`` up to ``omega_max`` [rad/s] (each its own tension)."""
        pieces = self.pieces_for(omega_max)
        return [self] if pieces == 1 else list(self.split(pieces))
