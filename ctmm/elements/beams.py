"""Exact Euler-Bernoulli beam elements for the frequency domain (layout :data:`~ctmm.layouts.BENDING`).

State vector ``z = [w, theta, shear, moment]`` at a station: deflection ``w`` [m], slope
``theta = w'`` [rad], and the transverse force ``shear`` [N] and bending moment ``moment``
[N m] **exerted by the inboard part on the outboard part** (package convention, see
:mod:`ctmm.layouts`).  For a beam with bending stiffness ``EI`` and axial tension ``T``

    shear  = EI w''' - T w'        (= Q_e of FORMULAS §2.4)
    moment = -EI w''               (= -M of FORMULAS §2.2, which uses M = EI w'')

so the package state is ``z = diag(1, 1, 1, -1)`` applied to FORMULAS' ``[w, θ, Q, M]`` after
swapping the force pair; ``docs/beams.md`` gives the derivation and the conversion.

Notation of the numeric kernel (dimensionless, ``x = L ξ``):

=========  =====================================================================
``a``      ``T L^2 / EI*``  (tension parameter, ``EI* = EI (1 + i η sgn Im s + τ s)``)
``c``      ``-(ρA s^2 + c_v s) L^4 / EI*``  (``= β^4`` for ``s = iω`` without damping)
``φ``      solution of ``φ'''' = a φ'' + c φ``, ``φ(0)=φ'(0)=φ''(0)=0, φ'''(0)=1``
``p_j``    ``φ^(j)(1)``, j = 0..3; for ``a = 0``: ``p_3, p_2, p_1, p_0 = S, T/β, U/β^2, V/β^3``
           (Krylov functions of ``β``)
=========  =====================================================================

Field matrix (symbolic derivation ``U = P expm(C L) P^-1`` in ``docs/beams.md``, checked in
``tests/test_beams_exact.py`` against sympy and ``scipy.linalg.expm``), with
``qA = p3 - a p1``, ``qB = p2 - a p0``, ``qC = a p2 + c p0``::

    U = [[ qA,               L p2,             L^3 p0 / EI,   -L^2 p1 / EI ],
         [ c p0 / L,         p3,               L^2 p1 / EI,   -L p2 / EI   ],
         [ EI c qB / L^3,    EI c p1 / L^2,    qA,            -c p0 / L    ],
         [ -EI c p1 / L^2,   -EI qC / L,       -L p2,          p3          ]]

Closed form with ``m^2 = a/2 + r``, ``n^2 = r - a/2``, ``r = sqrt(a^2/4 + c)`` (roots ``±m, ±in``
of the characteristic equation, FORMULAS §2.4):
``φ(ξ) = (sinh(mξ)/m - sin(nξ)/n) / (m^2 + n^2)``; for small ``max(|m|, |n|)`` the Taylor series
of ``φ`` from the recurrence ``φ^(k+4)(0) = a φ^(k+2)(0) + c φ^(k)(0)`` is used instead (no
cancellation), and near the double root ``m^2 + n^2 -> 0`` the element falls back to
``scipy.linalg.expm``.
"""
from __future__ import annotations

import math
from typing import Any, Mapping

import numpy as np
import scipy.linalg

from .. import validation
from ..errors import ModelError
from ..layouts import BENDING
from .base import Element
from .bending import (BeamClamped, BeamFree, BeamHinge, BeamPinned, BeamPointLoad, BeamPointMass,  # noqa: F401
                      BeamSliding, BeamSpring, identity_matrices, laplace_array)

__all__ = [
    "BeamField", "BeamPointMass", "BeamSpring", "BeamHinge", "BeamPointLoad",
    "BeamClamped", "BeamFree", "BeamPinned", "BeamSliding",
    "beam_state_matrix", "clamped_clamped_beta",
]

MAX_TIME_ELEMENTS = 10_000
"""Most Hermite elements per BeamField span in time simulations (``time_elements`` or the default count)."""

# Series / closed-form switch: max(|m|, |n|) below this uses the Taylor series.
_SERIES_LIMIT = 2.0
_SERIES_TERMS = 32
_INV_FACT = np.array([1.0 / math.factorial(k) for k in range(_SERIES_TERMS)])
# Near the double root (m^2 + n^2 -> 0) the closed form cancels: fall back to expm.
_DOUBLE_ROOT_RATIO = 1e-3
# Largest β (and tension parameter sqrt(|T|/EI) L) of a piece made by BeamField.subdivide.
_SUBDIVISION_BETA = 4.0



def beam_state_matrix(s: complex, bending_stiffness: complex, mass_per_length: float,
                      axial_force: float = 0.0, viscous_damping: float = 0.0) -> np.ndarray:
    """System matrix ``A`` of ``z' = A z`` for one Laplace variable (package convention).

    ``z = [w, theta, shear, moment]`` with ``shear = EI w''' - T w'``, ``moment = -EI w''``::

        w'      = theta
        theta'  = -moment / EI
        shear'  = -(rho A s^2 + c_v s) w          (EI w'''' - T w'' = -(rho A s^2 + c_v s) w)
        moment' = -shear - T theta

    Parameters
    ----------
    s : complex
        Laplace variable [1/s].
    bending_stiffness : complex
        Effective ``EI*`` [N m^2] (complex with damping).
    mass_per_length : float
        ``rho A`` [kg/m].
    axial_force : float
        Axial tension ``T`` [N] (negative: compression).
    viscous_damping : float
        External viscous damping per unit length ``c_v`` [N s/m^2].
    """
    q = mass_per_length * s * s + viscous_damping * s
    return np.array([[0, 1, 0, 0],
                     [0, 0, 0, -1 / bending_stiffness],
                     [-q, 0, 0, 0],
                     [0, -axial_force, -1, 0]], dtype=complex)


def _phi_series(a: np.ndarray, c: np.ndarray) -> tuple[np.ndarray, ...]:
    """``p_j = φ^(j)(1)``, j=0..3, by the Taylor series at ξ = 0 (for ``max(|m|, |n|) <= 2``).

    ``D_k = φ^(k)(0)``: ``D_0 = D_1 = D_2 = 0``, ``D_3 = 1``, ``D_{k+4} = a D_{k+2} + c D_k``;
    ``p_j = Σ_k D_{k+j} / k!``.  ``|D_k| <= 2^(k-3)`` here, so 32 terms leave < 1e-20.
    """
    D = np.zeros((_SERIES_TERMS + 4,) + a.shape, dtype=complex)
    D[3] = 1.0
    for k in range(_SERIES_TERMS):
        D[k + 4] = a * D[k + 2] + c * D[k]
    return tuple(_INV_FACT @ D[j:j + _SERIES_TERMS] for j in range(4))


def _sinhc(z: np.ndarray) -> np.ndarray:
    small = np.abs(z) < 1e-4
    zs = np.where(small, 1.0, z)
    return np.where(small, 1 + z * z / 6, np.sinh(zs) / zs)


def _sinc(z: np.ndarray) -> np.ndarray:
    small = np.abs(z) < 1e-4
    zs = np.where(small, 1.0, z)
    return np.where(small, 1 - z * z / 6, np.sin(zs) / zs)


def _kernel(a: np.ndarray, c: np.ndarray) -> tuple[np.ndarray, ...]:
    """Return ``(p0, p1, p2, p3, qA, qB, qC, fallback)`` for 1-D arrays ``a, c``.

    ``qA = p3 - a p1``, ``qB = p2 - a p0``, ``qC = a p2 + c p0`` are formed without
    cancellation in the closed form.  ``fallback`` flags entries near the double root.
    """
    r = np.sqrt(a * a / 4 + c)
    m2 = a / 2 + r
    n2 = r - a / 2
    m = np.sqrt(m2)
    n = np.sqrt(n2)
    size = np.maximum(np.abs(m), np.abs(n))
    series = size <= _SERIES_LIMIT
    D = m2 + n2
    fallback = (~series) & (np.abs(D) < _DOUBLE_ROOT_RATIO * np.maximum(np.abs(m2), np.abs(n2)))
    closed = ~series & ~fallback
    res = [np.zeros_like(a) for _ in range(7)]
    if np.any(series):
        aa, cc = a[series], c[series]
        p0, p1, p2, p3 = _phi_series(aa, cc)
        for i, v in enumerate((p0, p1, p2, p3, p3 - aa * p1, p2 - aa * p0, aa * p2 + cc * p0)):
            res[i][series] = v
    if np.any(closed):
        M2, N2, Dc = m2[closed], n2[closed], D[closed]
        mm, nn = m[closed], n[closed]
        Sh, Ch = _sinhc(mm), np.cosh(mm)
        Sn, Cs = _sinc(nn), np.cos(nn)
        vals = ((Sh - Sn) / Dc,                       # p0
                (Ch - Cs) / Dc,                       # p1
                (M2 * Sh + N2 * Sn) / Dc,             # p2
                (M2 * Ch + N2 * Cs) / Dc,             # p3
                (N2 * Ch + M2 * Cs) / Dc,             # qA = p3 - a p1
                (N2 * Sh + M2 * Sn) / Dc,             # qB = p2 - a p0
                (M2 * M2 * Sh - N2 * N2 * Sn) / Dc)   # qC = a p2 + c p0
        for i, v in enumerate(vals):
            res[i][closed] = v
    return (*res, fallback)


def _field_matrix(length: float, EI: np.ndarray, a: np.ndarray, c: np.ndarray) -> np.ndarray:
    """Assemble ``U`` (shape ``a.shape + (4, 4)``) from the dimensionless kernel."""
    shape = a.shape
    af, cf, EIf = a.ravel(), c.ravel(), np.broadcast_to(EI, shape).ravel()
    p0, p1, p2, p3, qA, qB, qC, fallback = _kernel(af, cf)
    L = length
    U = np.empty(af.shape + (4, 4), dtype=complex)
    # rows: w, theta, shear, moment (package convention); p_j = L^(j-3) φ^(j)(L) scaled
    U[:, 0, 0] = qA
    U[:, 0, 1] = L * p2
    U[:, 0, 2] = L ** 3 * p0 / EIf
    U[:, 0, 3] = -L ** 2 * p1 / EIf
    U[:, 1, 0] = cf * p0 / L
    U[:, 1, 1] = p3
    U[:, 1, 2] = L ** 2 * p1 / EIf
    U[:, 1, 3] = -L * p2 / EIf
    U[:, 2, 0] = EIf * cf * qB / L ** 3
    U[:, 2, 1] = EIf * cf * p1 / L ** 2
    U[:, 2, 2] = qA
    U[:, 2, 3] = -cf * p0 / L
    U[:, 3, 0] = -EIf * cf * p1 / L ** 2
    U[:, 3, 1] = -EIf * qC / L
    U[:, 3, 2] = -L * p2
    U[:, 3, 3] = p3
    if np.any(fallback):
        for i in np.flatnonzero(fallback):
            # A in dimensional form from the dimensionless parameters
            A = np.array([[0, 1, 0, 0], [0, 0, 0, -1 / EIf[i]],
                          [EIf[i] * cf[i] / L ** 4, 0, 0, 0],
                          [0, -af[i] * EIf[i] / L ** 2, -1, 0]], dtype=complex)
            U[i] = scipy.linalg.expm(A * L)
    return U.reshape(shape + (4, 4))


# ----------------------------------------------------------------------------------------
# clamped-clamped roots 1 - cos β cosh β = 0 (β_0 = 0 excluded)
def clamped_clamped_beta(index: np.ndarray | int) -> np.ndarray:
    """Roots ``β_k`` (k = 1, 2, ...) of ``1 - cos β cosh β = 0`` (clamped-clamped, free-free).

    Solved in the scaled form ``cos β - 1/cosh β = 0`` by Newton's method from
    ``(k + 1/2) π``; exact to round-off for every ``k``.
    """
    k = np.asarray(index, dtype=float)
    beta = (k + 0.5) * np.pi
    for _ in range(8):
        sech = np.exp(-beta) * 2 / (1 + np.exp(-2 * beta))
        g = np.cos(beta) - sech
        dg = -np.sin(beta) + sech * np.tanh(beta)
        beta = beta - g / dg
    return beta


def _count_clamped_beta(beta: np.ndarray) -> np.ndarray:
    """Number of roots ``β_k`` (k >= 1) of ``1 - cos β cosh β`` strictly below ``beta``."""
    base = np.floor(beta / np.pi - 0.5).astype(np.int64)  # points (k+1/2)π <= beta, k >= 0
    count = np.maximum(base - 1, 0)                      # roots k=1..base-1 lie surely below
    for k_off in (0, 1):               # only roots base and base+1 can straddle beta
        k = base + k_off
        rk = clamped_clamped_beta(np.maximum(k, 1))
        count = count + np.where((k >= 1) & (rk < beta), 1, 0)
    return count


# ----------------------------------------------------------------------------------------
class BeamField(Element):
    """Uniform Euler-Bernoulli beam segment with exact (closed-form) field transfer matrix.

    Parameters
    ----------
    name : str
        Element name.
    length : float
        Segment length ``L`` [m], > 0.
    bending_stiffness : float
        ``EI`` [N m^2], > 0.
    mass_per_length : float
        ``rho A`` [kg/m], > 0.
    axial_force : float, optional
        Constant axial tension ``T`` [N] (negative for compression); geometric stiffening
        term ``-T w''`` of FORMULAS §2.4.
    loss_factor : float, optional
        Structural (hysteretic) loss factor ``η >= 0``: ``EI* = EI (1 + i η sgn(Im s))``.
        Exact for ``s = iω``; the modal damping ratio at resonance is about ``η / 2``.
    kelvin_voigt_time : float, optional
        Strain-rate (Kelvin-Voigt) damping time ``τ >= 0`` [s]: ``EI* = EI (1 + τ s)``,
        analytic in ``s``; mode ``k`` gets damping ratio ``τ ω_k / 2``.
    viscous_damping : float, optional
        External viscous damping per unit length ``c_v >= 0`` [N s/m^2].
    time_elements : int, optional
        Number of cubic Hermite elements of the span in time simulations (``ctmm.simulate``);
        default: enough to resolve every mode the step resolves, at a relative frequency error
        of 1e-3 (:func:`ctmm.elements.beam_time.time_element_count`; a smaller number warns);
        at most :data:`MAX_TIME_ELEMENTS`.

    Notes
    -----
    ``transfer_matrix(s)`` maps ``z = [w, theta, shear, moment]`` from the inboard end
    (``x = 0``) to the outboard end (``x = L``).  Entries grow like ``cosh(β)``; beyond
    ``|β| ≈ 700`` they overflow and the element must be :meth:`split` (the Riccati transfer
    needs pieces with ``|β| ≲ 20`` for round-off-level high modes).

    Examples
    --------
    >>> beam = BeamField("beam", length=1.0, bending_stiffness=15.0, mass_per_length=0.8)
    >>> beam.transfer_matrix(1j * np.array([1.0, 10.0])).shape
    (2, 4, 4)
    """

    layout = BENDING
    is_point = False

    def __init__(self, name: str, length: float, bending_stiffness: float, mass_per_length: float, *,
                 axial_force: float = 0.0, loss_factor: float = 0.0, kelvin_voigt_time: float = 0.0,
                 viscous_damping: float = 0.0, time_elements: int | None = None) -> None:
        super().__init__(name)
        self.time_elements = None if time_elements is None else validation.integer(f"{name}: time_elements",
                                                                                   time_elements)
        if self.time_elements is not None and self.time_elements > MAX_TIME_ELEMENTS:
            raise ModelError(f"{name}: time_elements must be at most {MAX_TIME_ELEMENTS} Hermite elements per span "
                             f"(the time steps cost O(N)), got {time_elements!r}")
        self.length = validation.positive(f"{name}: length", length)
        self.bending_stiffness = validation.positive(f"{name}: bending_stiffness", bending_stiffness)
        self.mass_per_length = validation.positive(f"{name}: mass_per_length", mass_per_length)
        self.axial_force = validation.finite(f"{name}: axial_force", axial_force)
        self.loss_factor = validation.nonnegative(f"{name}: loss_factor", loss_factor)
        self.kelvin_voigt_time = validation.nonnegative(f"{name}: kelvin_voigt_time", kelvin_voigt_time)
        self.viscous_damping = validation.nonnegative(f"{name}: viscous_damping", viscous_damping)

    # -- parameters --------------------------------------------------------------------
    def parameters(self) -> dict[str, Any]:
        return {"length": self.length, "bending_stiffness": self.bending_stiffness,
                "mass_per_length": self.mass_per_length, "axial_force": self.axial_force,
                "loss_factor": self.loss_factor, "kelvin_voigt_time": self.kelvin_voigt_time,
                "viscous_damping": self.viscous_damping}

    @property
    def is_conservative(self) -> bool:
        """False when any damping parameter is non-zero (checked by ``natural_frequencies``)."""
        return not (self.loss_factor or self.kelvin_voigt_time or self.viscous_damping)

    def effective_bending_stiffness(self, s: Any) -> np.ndarray:
        """``EI* = EI (1 + i η sgn(Im s) + τ s)`` [N m^2] over ``s``."""
        s = laplace_array(s)
        sign = np.where(s.imag < 0, -1.0, 1.0)
        return self.bending_stiffness * (1 + 1j * self.loss_factor * sign + self.kelvin_voigt_time * s)

    def frequency_parameter(self, s: Any) -> np.ndarray:
        """Dimensionless ``c = -(ρA s^2 + c_v s) L^4 / EI*`` (``= (βL)^4`` for undamped ``s = iω``)."""
        s = laplace_array(s)
        EI = self.effective_bending_stiffness(s)
        return -(self.mass_per_length * s * s + self.viscous_damping * s) * self.length ** 4 / EI

    def state_matrix(self, s: complex) -> np.ndarray:
        """``A(s)`` of ``z' = A z`` (4x4, one ``s``); ``U = expm(A L)``."""
        s = complex(s)
        EI = complex(self.effective_bending_stiffness(s))
        return beam_state_matrix(s, EI, self.mass_per_length, self.axial_force, self.viscous_damping)

    def discretize(self, scheme: Any):
        """Refused: in time the span is meshed into Hermite elements by the stepper (``ctmm.simulate``)."""
        raise ModelError(f"element {self.name!r} (BeamField) is stepped as the Hermite elements of "
                         "ctmm.elements.beam_time.field_segments; simulate its chain with ctmm.simulate")

    # -- frequency domain --------------------------------------------------------------
    def transfer_matrix(self, s: Any) -> np.ndarray:
        """Exact field matrix ``U(s) = expm(A(s) L)``, shape ``np.shape(s) + (4, 4)``."""
        s = laplace_array(s)
        EI = self.effective_bending_stiffness(s)
        c = self.frequency_parameter(s)
        a = self.axial_force * self.length ** 2 / EI
        return _field_matrix(self.length, EI, np.asarray(a, dtype=complex), np.asarray(c, dtype=complex))

    def split(self, pieces: int) -> tuple["BeamField", ...]:
        """Return ``pieces`` equal segments ``"<name>_1" ...`` whose product equals this field."""
        if isinstance(pieces, bool) or not isinstance(pieces, (int, np.integer)) or pieces < 1:
            raise ModelError(f"{self.name}: pieces must be an integer >= 1, got {pieces!r}")
        params = self.parameters()
        params["length"] = self.length / pieces
        return tuple(BeamField(f"{self.name}_{i + 1}", **params) for i in range(pieces))

    def pieces_for(self, omega_max: float, *, max_beta: float = 8.0) -> int:
        """Number of equal pieces so that each has ``β = L_piece (ρA ω^2/EI)^(1/4) <= max_beta``."""
        omega_max = validation.nonnegative("omega_max", omega_max)
        max_beta = validation.positive("max_beta", max_beta)
        beta = self.length * (self.mass_per_length * omega_max ** 2 / self.bending_stiffness) ** 0.25
        tension = math.sqrt(abs(self.axial_force) / self.bending_stiffness) * self.length
        return max(1, math.ceil(max(beta, tension) / max_beta))

    def subdivide(self, omega_max: float) -> list["BeamField"]:
        """Equal pieces with ``β_piece <= 4`` up to ``omega_max`` [rad/s] (solver hook).

        Used by :func:`ctmm.frequency.eigenvalue_count`, :func:`~ctmm.frequency.natural_frequencies`
        and :func:`~ctmm.frequency.mode_shapes` (and :func:`~ctmm.frequency.assemble` with
        ``subdivide=True``): a single long field has entries ``~ cosh β`` and a boundary
        determinant that loses ``~ e^β eps``; pieces of ``β <= 4`` keep natural frequencies at
        round-off level (``docs/beams.md``, "natural frequencies of beam assemblies").
        """
        pieces = self.pieces_for(omega_max, max_beta=_SUBDIVISION_BETA)
        if pieces == 1:
            return [self]
        piece = self.split(pieces)[0]
        return [piece] * pieces  # one object: solvers evaluate its matrix once

    # -- Wittrick-Williams -------------------------------------------------------------
    def clamped_frequency_count(self, omega: Any) -> np.ndarray:
        """Number of natural frequencies of the element clamped at both ends strictly below ``omega``.

        The ``J0`` term of the Wittrick-Williams count for the *undamped* element (damping
        parameters are ignored).  ``T = 0``: exact, from the roots of
        ``1 - cos β cosh β = 0`` (:func:`clamped_clamped_beta`).  ``T != 0``: the element is
        subdivided into pieces that each have no clamped-clamped frequency below ``omega``
        (``β_piece <= 3`` and ``|T| l^2/EI <= π^2``, i.e. at most a quarter of the piece's
        clamped buckling load) and ``J0`` is the Sturm count (negative eigenvalues) of the
        assembled dynamic stiffness of the interior nodes (Wittrick-Williams applied to the
        element itself); exact for tension, and for compression below the element's
        clamped-clamped buckling load.

        Parameters
        ----------
        omega : float or array
            Angular frequencies [rad/s], >= 0.

        Returns
        -------
        numpy.ndarray of int
            Same shape as ``omega``.
        """
        omega = np.asarray(omega, dtype=float)
        if not np.all(np.isfinite(omega)) or np.any(omega < 0):
            raise ModelError(f"{self.name}: omega must be finite and >= 0, got {omega!r}")
        EI, rhoA, L = self.bending_stiffness, self.mass_per_length, self.length
        beta = L * (rhoA * omega ** 2 / EI) ** 0.25
        if self.axial_force == 0.0:
            return _count_clamped_beta(beta).astype(np.int64)
        return self._clamped_count_subdivided(omega.ravel()).reshape(omega.shape)

    def _clamped_count_subdivided(self, omega: np.ndarray) -> np.ndarray:
        """Sturm count of the interior-node dynamic stiffness of ``N`` equal pieces (batched)."""
        omega = np.atleast_1d(np.asarray(omega, dtype=float))
        EI, rhoA, L, T = self.bending_stiffness, self.mass_per_length, self.length, self.axial_force
        beta = L * (rhoA * omega.max(initial=0.0) ** 2 / EI) ** 0.25
        pieces = max(1, math.ceil(beta / 3.0), math.ceil(math.sqrt(abs(T) / EI) * L / math.pi))
        if pieces == 1:
            return np.zeros(omega.shape, dtype=np.int64)
        ell = L / pieces
        c = rhoA * omega ** 2 * ell ** 4 / EI
        a = np.full(omega.shape, T * ell ** 2 / EI, dtype=complex)
        U = _field_matrix(ell, np.asarray(EI, dtype=complex), a, c.astype(complex)).real
        K = _dynamic_stiffness(U)                       # (B, 4, 4): [inboard w, θ, outboard w, θ]
        n = 2 * (pieces - 1)
        G = np.zeros(omega.shape + (n, n))
        for node in range(pieces - 1):                  # interior node `node+1`
            i = slice(2 * node, 2 * node + 2)
            G[:, i, i] += K[:, 2:, 2:] + K[:, :2, :2]   # outboard end of piece `node`, inboard of next
            if node + 1 < pieces - 1:
                j = slice(2 * node + 2, 2 * node + 4)
                G[:, i, j] += K[:, :2, 2:]
                G[:, j, i] += K[:, 2:, :2]
        G = 0.5 * (G + np.swapaxes(G, -1, -2))
        return np.sum(np.linalg.eigvalsh(G) < 0, axis=-1).astype(np.int64)


def _dynamic_stiffness(U: np.ndarray) -> np.ndarray:
    """Dynamic stiffness ``[F_L; F_R] = K [d_L; d_R]`` of a field from its transfer matrix.

    ``d = [w, theta]``; ``F`` = force/moment acting *on the element* at its ends:
    ``F_L = f_L`` (exerted by the inboard part), ``F_R = -f_R``.
    """
    U11, U12, U21, U22 = U[..., :2, :2], U[..., :2, 2:], U[..., 2:, :2], U[..., 2:, 2:]
    X = np.linalg.inv(U12)
    top = np.concatenate([-X @ U11, X], axis=-1)
    bottom = np.concatenate([-U21 + U22 @ X @ U11, -U22 @ X], axis=-1)
    return np.concatenate([top, bottom], axis=-2)
