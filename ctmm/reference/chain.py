"""Global-equation reference for 1-D spring–mass–damper chains (no transfer-matrix code).

This module builds the classical global equations of motion

.. math:: M \\ddot x + C \\dot x + K x = f(t)

of a serial chain of lumped masses and solves them with textbook linear algebra (``eigh``,
dense and banded solves, matrix exponential, Newmark, ``solve_ivp``).  It is the independent
reference the transfer-matrix path is validated against, so it imports nothing from ctmm
except :mod:`ctmm.errors` and :mod:`ctmm.validation`.

Topology and coordinates
------------------------
``n`` masses ``0 .. n-1`` in order; ``n + 1`` connectors (spring ``k_i`` parallel to damper
``c_i``): connector ``0`` joins the start boundary to mass 0, connector ``i`` joins mass
``i-1`` to mass ``i``, connector ``n`` joins mass ``n-1`` to the end boundary.  A ``"fixed"``
boundary has zero displacement; at a ``"free"`` boundary the connector does not exist (its
stiffness and damping must be zero).  Mass ``i`` may also carry a grounded spring/damper.

The coordinates ``x_i`` [m] are *displacements from the unstretched configuration*: all
connectors at their free length, all ground springs relaxed.  Free lengths then only shift the
reference and never appear in ``M, C, K``.  In absolute coordinates ``X = X0 + x`` (``X0`` from
:func:`unstretched_positions`) the same equations read ``M Ẍ + C Ẋ + K X = f + static_load``.

Sign convention (as ``ctmm.layouts``): the tension of connector ``j`` is
``q_j = k_j (x_out - x_in) + c_j (v_out - v_in)``; the *connector force* reported here is the
force exerted by the inboard part on the outboard part, ``-q_j``.
"""
from __future__ import annotations

import operator
from dataclasses import dataclass, field
from typing import Callable, NamedTuple

import numpy as np
import scipy.linalg as sla
from scipy.integrate import solve_ivp

from ..errors import ModelError, SimulationError, SingularSystemError
from ..validation import finite, finite_array, nonnegative, positive

BOUNDARIES = ("fixed", "free")
QUANTITIES = ("displacement", "velocity", "acceleration", "force")
FORCE_KINDS = ("constant", "sine", "cosine")

ForceFunction = Callable[[float], "np.ndarray"]

__all__ = ["GlobalChain", "TimeHistory", "assemble", "assemble_banded", "static_load",
           "unstretched_positions", "natural_frequencies", "mode_shapes", "frequency_response",
           "frequency_response_banded", "state_space", "complex_eigenvalues", "exact_response",
           "newmark_global", "solve_ivp_response", "accelerations"]


class TimeHistory(NamedTuple):
    """Sampled time response of a chain.

    Attributes
    ----------
    time : ndarray, shape (nt,)
        Sample times [s].
    displacement : ndarray, shape (nt, n)
        Displacements from the unstretched configuration [m].
    velocity : ndarray, shape (nt, n)
        Velocities [m/s].
    acceleration : ndarray, shape (nt, n)
        Accelerations [m/s²].
    """

    time: np.ndarray
    displacement: np.ndarray
    velocity: np.ndarray
    acceleration: np.ndarray


# ---------------------------------------------------------------------------------------------
# description
# ---------------------------------------------------------------------------------------------
def _vector(name: str, value, size: int, *, allow_zero: bool = True) -> np.ndarray:
    array = finite_array(name, value, ndim=1)
    if array.shape != (size,):
        raise ModelError(f"{name} must have shape ({size},), got shape {array.shape}")
    bad = array <= 0.0 if not allow_zero else array < 0.0
    if np.any(bad):
        index = int(np.flatnonzero(bad)[0])
        relation = "> 0" if not allow_zero else ">= 0"
        raise ModelError(f"{name}[{index}] must be {relation}, got {array[index]!r}")
    return array


@dataclass(frozen=True, eq=False)
class GlobalChain:
    """Plain-array description of a 1-D spring–mass–damper chain.

    Parameters
    ----------
    masses : array_like, shape (n,)
        Lumped masses [kg], all > 0, in order from the start boundary.
    stiffness : array_like, shape (n + 1,)
        Connector spring stiffnesses [N/m], >= 0 (see module docstring for the numbering).
    damping : array_like, shape (n + 1,), optional
        Connector viscous damping [N s/m], >= 0; zeros when omitted.
    free_length : array_like, shape (n + 1,), optional
        Connector free lengths [m] (finite, any sign); zeros when omitted.  They do not enter
        ``M, C, K``; see :func:`static_load`.
    ground_stiffness, ground_damping : array_like, shape (n,), optional
        Grounded spring [N/m] and damper [N s/m] at each mass, >= 0; zeros when omitted.
    start, end : {"fixed", "free"}
        Boundary conditions (keyword-only, required).  For a free boundary the connector at
        that end must have zero stiffness and damping.

    Raises
    ------
    ModelError
        On wrong shapes, non-finite entries, non-positive masses, negative stiffness or
        damping, an unknown boundary, or a connector attached to a free boundary.

    Examples
    --------
    >>> chain = GlobalChain([1.0, 2.0], [100.0, 200.0, 0.0], start="fixed", end="free")
    >>> chain.size
    2
    """

    masses: np.ndarray
    stiffness: np.ndarray
    damping: np.ndarray | None = None
    free_length: np.ndarray | None = None
    ground_stiffness: np.ndarray | None = None
    ground_damping: np.ndarray | None = None
    start: str = field(kw_only=True)
    end: str = field(kw_only=True)

    def __post_init__(self) -> None:
        masses = finite_array("masses", self.masses, ndim=1)
        n = masses.size
        if n < 1:
            raise ModelError("masses must contain at least one mass, got an empty array")
        masses = _vector("masses", masses, n, allow_zero=False)
        zeros_c, zeros_m = np.zeros(n + 1), np.zeros(n)
        values = {
            "masses": masses,
            "stiffness": _vector("stiffness", self.stiffness, n + 1),
            "damping": _vector("damping", zeros_c if self.damping is None else self.damping, n + 1),
            "free_length": finite_array(
                "free_length", zeros_c if self.free_length is None else self.free_length, ndim=1),
            "ground_stiffness": _vector(
                "ground_stiffness", zeros_m if self.ground_stiffness is None else self.ground_stiffness, n),
            "ground_damping": _vector(
                "ground_damping", zeros_m if self.ground_damping is None else self.ground_damping, n),
        }
        if values["free_length"].shape != (n + 1,):
            raise ModelError(f"free_length must have shape ({n + 1},), got shape "
                             f"{values['free_length'].shape}")
        for side, index in (("start", 0), ("end", n)):
            condition = getattr(self, side)
            if condition not in BOUNDARIES:
                raise ModelError(f"{side} must be one of {BOUNDARIES}, got {condition!r}")
            if condition == "free":
                for key in ("stiffness", "damping"):
                    if values[key][index] != 0.0:
                        raise ModelError(
                            f"{key}[{index}] must be 0 for a free {side} (the connector does not "
                            f"exist), got {values[key][index]!r}")
        for key, array in values.items():
            array.setflags(write=False)
            object.__setattr__(self, key, array)

    @property
    def size(self) -> int:
        """Number of masses ``n`` (degrees of freedom)."""
        return int(self.masses.size)

    @classmethod
    def uniform(cls, n: int, mass: float, stiffness: float, damping: float = 0.0, *,
                start: str, end: str) -> "GlobalChain":
        """Chain of ``n`` equal masses [kg] joined by equal connectors [N/m], [N s/m].

        The connector at a free boundary is omitted (zero), every other connector gets
        ``stiffness`` and ``damping``.
        """
        count = _index("n", n, 10**9, "count") if n != 0 else 0
        if count < 1:
            raise ModelError(f"n must be an integer >= 1, got {n!r}")
        k = np.full(count + 1, nonnegative("stiffness", stiffness))
        c = np.full(count + 1, nonnegative("damping", damping))
        for index, side in ((0, start), (count, end)):
            if side == "free":
                k[index] = c[index] = 0.0
        return cls(np.full(count, positive("mass", mass)), k, c, start=start, end=end)


def mass_index(chain: GlobalChain, name: str, value) -> int:
    """Validate a mass index ``0 <= value < n`` (``name`` is the parameter name)."""
    return _index(name, value, chain.size - 1, "mass")


def _index(name: str, value, largest: int, what: str) -> int:
    try:
        if isinstance(value, bool):
            raise TypeError
        index = operator.index(value)
    except TypeError:
        raise ModelError(f"{name} must be an integer {what} index, got {value!r}") from None
    if not 0 <= index <= largest:
        raise ModelError(f"{name} must be a {what} index in [0, {largest}], got {value!r}")
    return index


# ---------------------------------------------------------------------------------------------
# assembly
# ---------------------------------------------------------------------------------------------
def _assemble_pair(chain: GlobalChain, connector: np.ndarray, ground: np.ndarray) -> np.ndarray:
    """Stiffness-like matrix: each connector scatters ``v [[1, -1], [-1, 1]]`` onto its two
    end DOFs (boundary DOFs dropped: displacement 0 when fixed, connector absent when free)."""
    n = chain.size
    matrix = np.diag(ground.astype(float))
    for j in range(n + 1):
        dofs = [d for d in (j - 1, j) if 0 <= d < n]
        block = connector[j] * np.array([[1.0, -1.0], [-1.0, 1.0]])
        if len(dofs) == 1:                       # connector to a boundary
            local = 1 if j == 0 else 0           # which end of the connector is the mass
            block = block[local:local + 1, local:local + 1]
        matrix[np.ix_(dofs, dofs)] += block
    return matrix


def assemble(chain: GlobalChain) -> tuple[np.ndarray, np.ndarray, np.ndarray]:
    """Dense global matrices of the chain.

    Returns
    -------
    M : ndarray, shape (n, n)
        Diagonal mass matrix [kg].
    C : ndarray, shape (n, n)
        Damping matrix [N s/m] (connector dampers + ground dampers).
    K : ndarray, shape (n, n)
        Stiffness matrix [N/m] (connector springs + ground springs).
    """
    return (np.diag(chain.masses.astype(float)),
            _assemble_pair(chain, chain.damping, chain.ground_damping),
            _assemble_pair(chain, chain.stiffness, chain.ground_stiffness))


def to_banded(matrix: np.ndarray) -> np.ndarray:
    """Tridiagonal ``matrix`` (..., n, n) in ``scipy.linalg.solve_banded((1, 1), ...)`` form
    (..., 3, n): row 0 super-diagonal (first entry unused), row 1 diagonal, row 2
    sub-diagonal (last entry unused)."""
    n = matrix.shape[-1]
    band = np.zeros(matrix.shape[:-2] + (3, n), dtype=matrix.dtype)
    band[..., 1, :] = np.diagonal(matrix, axis1=-2, axis2=-1)
    if n > 1:
        band[..., 0, 1:] = np.diagonal(matrix, offset=1, axis1=-2, axis2=-1)
        band[..., 2, :-1] = np.diagonal(matrix, offset=-1, axis1=-2, axis2=-1)
    return band


def assemble_banded(chain: GlobalChain) -> tuple[np.ndarray, np.ndarray, np.ndarray]:
    """Mass, damping and stiffness in ``solve_banded((1, 1), ...)`` form, each shape (3, n).

    The dynamic stiffness at ``omega`` [rad/s] is ``K_b - omega**2 * M_b + 1j*omega*C_b``.
    """
    return tuple(to_banded(matrix) for matrix in assemble(chain))  # type: ignore[return-value]


def unstretched_positions(chain: GlobalChain) -> np.ndarray:
    """Absolute coordinates ``X0_i = sum_{j<=i} free_length[j]`` [m] of the masses in the
    unstretched configuration, measured from the start boundary (at 0).  For a free start
    ``free_length[0]`` is simply the reference position of mass 0."""
    return np.cumsum(chain.free_length)[:-1]


def static_load(chain: GlobalChain, *, end_position: float | None = None) -> np.ndarray:
    """Constant force vector [N] produced by the free lengths in absolute coordinates.

    With absolute positions ``X`` (start boundary at 0, fixed end wall at ``end_position``,
    ground springs relaxed at ``X0``), the tension of connector ``j`` is
    ``k_j (X_j - X_{j-1} - l_j)``; collecting the terms that do not multiply ``X`` gives
    ``M Ẍ + C Ẋ + K X = f + static_load`` with, on mass ``i``,
    ``k_i l_i - k_{i+1} l_{i+1} + kg_i X0_i`` (+ ``k_n * end_position`` on the last mass for a
    fixed end).  With the default ``end_position = sum(free_length)`` this equals ``K @ X0``, so
    ``x = X - X0`` obeys the load-free equations: free lengths only shift the reference.

    Parameters
    ----------
    end_position : float, optional
        Absolute position [m] of a fixed end wall; ignored for a free end.
    """
    k, length = chain.stiffness, chain.free_length
    load = k[:-1] * length[:-1] - k[1:] * length[1:]
    load = load + chain.ground_stiffness * unstretched_positions(chain)
    if chain.end == "fixed":
        wall = float(np.sum(length)) if end_position is None else finite("end_position", end_position)
        load[-1] += k[-1] * wall
    return load


# ---------------------------------------------------------------------------------------------
# modal analysis
# ---------------------------------------------------------------------------------------------
def _generalized_eigh(chain: GlobalChain) -> tuple[np.ndarray, np.ndarray]:
    M, _, K = assemble(chain)
    eigenvalues, vectors = sla.eigh(K, M)
    scale = max(float(np.max(np.abs(eigenvalues))), np.finfo(float).tiny)
    eigenvalues = np.where(np.abs(eigenvalues) <= 1e-12 * scale, 0.0, eigenvalues)
    return np.sqrt(np.clip(eigenvalues, 0.0, None)), vectors


def natural_frequencies(chain: GlobalChain) -> np.ndarray:
    """Undamped natural frequencies [rad/s], ascending, from ``scipy.linalg.eigh(K, M)``.

    Rigid-body (zero) modes are kept as exact zeros (eigenvalues below ``1e-12`` times the
    largest one are set to 0).
    """
    return _generalized_eigh(chain)[0]


def natural_frequencies_precise(chain: GlobalChain, digits: int = 40) -> np.ndarray:
    """Undamped natural frequencies [rad/s], ascending, to ``digits`` significant digits
    (mpmath symmetric eigensolver on ``M^{-1/2} K M^{-1/2}``; lumped masses only, ``M``
    diagonal and positive), rounded to float at the end.

    ``eigh`` in double precision is accurate to about ``eps * lambda_max`` in each eigenvalue, so
    a low mode of a stiff chain carries a relative error ``eps * lambda_max / lambda`` (1e-12 for
    a spread of 1e4); this reference has none of it.
    """
    import mpmath

    M, _, K = assemble(chain)
    mass = np.diag(M)
    if not (np.allclose(M, np.diag(mass)) and np.all(mass > 0)):
        raise ValueError("natural_frequencies_precise needs positive lumped masses (diagonal M)")
    with mpmath.workdps(digits):
        scale = [1 / mpmath.sqrt(mpmath.mpf(float(m))) for m in mass]
        n = len(mass)
        A = mpmath.matrix(n, n)
        for i in range(n):
            for j in range(n):
                A[i, j] = mpmath.mpf(float(K[i, j])) * scale[i] * scale[j]
        values = mpmath.eigsy(A, eigvals_only=True)
        out = sorted(float(mpmath.sqrt(v)) if v > 0 else 0.0 for v in values)
    return np.array(out)


def mode_shapes(chain: GlobalChain) -> tuple[np.ndarray, np.ndarray]:
    """Natural frequencies [rad/s] and mass-normalised mode shapes.

    Returns
    -------
    omega : ndarray, shape (n,)
        As :func:`natural_frequencies`.
    shapes : ndarray, shape (n, n)
        Column ``r`` is mode ``r`` with ``shapes.T @ M @ shapes = I`` [kg^-1/2]; the sign is
        chosen so that the entry of largest magnitude is positive.
    """
    omega, vectors = _generalized_eigh(chain)
    pivot = np.argmax(np.abs(vectors), axis=0)
    signs = np.sign(vectors[pivot, np.arange(vectors.shape[1])])
    return omega, vectors * np.where(signs == 0, 1.0, signs)


# ---------------------------------------------------------------------------------------------
# frequency response
# ---------------------------------------------------------------------------------------------
def connector_index(chain: GlobalChain, name: str, value) -> int:
    """Validate a connector index ``0 <= value <= n``."""
    return _index(name, value, chain.size, "connector")


def _omega(omega) -> np.ndarray:
    return finite_array("omega", omega)


def _quantity(quantity: str) -> str:
    if quantity not in QUANTITIES:
        raise ModelError(f"quantity must be one of {QUANTITIES}, got {quantity!r}")
    return quantity


def output_from_displacements(chain: GlobalChain, displacement: np.ndarray, omega: np.ndarray,
                              output: int, quantity: str) -> np.ndarray:
    """Turn complex displacement amplitudes (nw, n) into the requested output (nw,).

    ``displacement``/``velocity``/``acceleration`` of mass ``output`` (factors 1, iω, -ω²) or,
    for ``"force"``, the connector force ``-(k_j + iω c_j)(X_out - X_in)`` of connector
    ``j = output`` (boundary displacements 0).
    """
    jw = 1j * omega
    if quantity == "force":
        j = connector_index(chain, "output_mass (connector index for quantity='force')", output)
        n = chain.size
        outboard = displacement[:, j] if j < n else 0.0
        inboard = displacement[:, j - 1] if j > 0 else 0.0
        return -(chain.stiffness[j] + jw * chain.damping[j]) * (outboard - inboard)
    j = mass_index(chain, "output_mass", output)
    factor = {"displacement": 1.0, "velocity": jw, "acceleration": jw ** 2}[quantity]
    return factor * displacement[:, j]


def solve_dynamic_stiffness(D: np.ndarray, rhs: np.ndarray, omega: np.ndarray) -> np.ndarray:
    """Solve ``D[w] X[w] = rhs`` for a stack of matrices (nw, n, n); raise on singularity."""
    try:
        solution = np.linalg.solve(D, np.broadcast_to(rhs, D.shape[:-1])[..., None])[..., 0]
    except np.linalg.LinAlgError:
        raise SingularSystemError(
            "the dynamic stiffness is singular at one of the frequencies "
            f"(omega in [{omega.min()}, {omega.max()}] rad/s); e.g. a free-free chain at "
            "omega = 0 or an undamped resonance") from None
    if not np.all(np.isfinite(solution)):
        raise SingularSystemError("the dynamic stiffness is singular at one of the frequencies")
    return solution


def frequency_response(chain: GlobalChain, omega, input_mass: int, output_mass: int,
                       quantity: str = "displacement") -> np.ndarray:
    """Harmonic response per unit force on ``input_mass`` by dense solves.

    Solves ``(K - ω² M + iω C) X = e_input`` for all frequencies at once (time factor
    ``e^{iωt}``).

    Parameters
    ----------
    omega : array_like
        Real angular frequencies [rad/s].
    input_mass : int
        Mass carrying the unit harmonic force [N].
    output_mass : int
        Mass whose motion is returned; for ``quantity="force"`` this is the connector index
        ``j`` in ``[0, n]`` (connector ``j`` joins mass ``j-1`` to mass ``j``).
    quantity : {"displacement", "velocity", "acceleration", "force"}
        Output per unit force: [m/N], [m/(s N)], [m/(s² N)], or the connector force exerted by
        the inboard part on the outboard part [N/N] (= minus the connector tension).

    Returns
    -------
    ndarray, complex, shape of ``omega``
    """
    w = _omega(omega)
    flat = np.atleast_1d(w).ravel()
    _quantity(quantity)
    M, C, K = assemble(chain)
    D = K[None] - flat[:, None, None] ** 2 * M[None] + 1j * flat[:, None, None] * C[None]
    rhs = np.zeros(chain.size, dtype=complex)
    rhs[mass_index(chain, "input_mass", input_mass)] = 1.0
    X = solve_dynamic_stiffness(D, rhs, flat)
    return output_from_displacements(chain, X, flat, output_mass, quantity).reshape(w.shape)


def frequency_response_banded(chain: GlobalChain, omega, input_mass: int, output_mass: int,
                              quantity: str = "displacement") -> np.ndarray:
    """Same as :func:`frequency_response` with one ``scipy.linalg.solve_banded`` per frequency
    (O(n) per frequency; the reference for long chains)."""
    w = _omega(omega)
    flat = np.atleast_1d(w).ravel()
    _quantity(quantity)
    Mb, Cb, Kb = assemble_banded(chain)
    rhs = np.zeros(chain.size, dtype=complex)
    rhs[mass_index(chain, "input_mass", input_mass)] = 1.0
    X = np.empty((flat.size, chain.size), dtype=complex)
    for index, value in enumerate(flat):
        try:
            X[index] = sla.solve_banded((1, 1), Kb - value ** 2 * Mb + 1j * value * Cb, rhs)
        except np.linalg.LinAlgError:
            raise SingularSystemError(
                f"the dynamic stiffness is singular at omega = {value} rad/s") from None
    return output_from_displacements(chain, X, flat, output_mass, quantity).reshape(w.shape)


# ---------------------------------------------------------------------------------------------
# first-order form
# ---------------------------------------------------------------------------------------------
def state_space(chain: GlobalChain) -> tuple[np.ndarray, np.ndarray]:
    """First-order form ``d/dt [x; v] = A [x; v] + B f``.

    Returns
    -------
    A : ndarray, shape (2n, 2n)
        ``[[0, I], [-M⁻¹K, -M⁻¹C]]`` [1/s, 1/s²].
    B : ndarray, shape (2n, n)
        ``[[0], [M⁻¹]]`` [1/kg]; column ``i`` is a force on mass ``i``.
    """
    M, C, K = assemble(chain)
    n = chain.size
    inverse_mass = np.diag(1.0 / chain.masses)
    A = np.block([[np.zeros((n, n)), np.eye(n)], [-inverse_mass @ K, -inverse_mass @ C]])
    return A, np.vstack([np.zeros((n, n)), inverse_mass])


def sort_roots(roots: np.ndarray) -> np.ndarray:
    """Sort complex roots by |imaginary part|, then imaginary part, then real part."""
    roots = np.asarray(roots)
    return roots[np.lexsort((roots.real, roots.imag, np.abs(roots.imag)))]


def complex_eigenvalues(chain: GlobalChain) -> np.ndarray:
    """The 2n damped characteristic roots ``s`` [1/s] (``det(s²M + sC + K) = 0``), eigenvalues
    of the state matrix, sorted by |Im s| (conjugate pairs adjacent, negative imaginary first)."""
    return sort_roots(sla.eigvals(state_space(chain)[0]))


# ---------------------------------------------------------------------------------------------
# time responses
# ---------------------------------------------------------------------------------------------
def _state_vector(chain: GlobalChain, name: str, value) -> np.ndarray:
    array = finite_array(name, value, ndim=1)
    if array.shape != (chain.size,):
        raise ModelError(f"{name} must have shape ({chain.size},), got shape {array.shape}")
    return array


def _times(name: str, value) -> np.ndarray:
    t = finite_array(name, value, ndim=1)
    if t.size == 0 or np.any(t < 0.0):
        raise ModelError(f"{name} must be a non-empty 1-D array of times >= 0 s, got {value!r}")
    return t


def accelerations(chain: GlobalChain, displacement: np.ndarray, velocity: np.ndarray,
                  force: np.ndarray) -> np.ndarray:
    """``a = M⁻¹ (f - C v - K x)`` row-wise for arrays (..., n) [m/s²]."""
    _, C, K = assemble(chain)
    return (force - velocity @ C.T - displacement @ K.T) / chain.masses


def exact_response(chain: GlobalChain, t, x0, v0, force_amplitudes, force_kind: str = "constant",
                   *, force_frequency: float | None = None) -> TimeHistory:
    """Exact response to constant or harmonic forces by the matrix exponential.

    The load ``f(t) = F * w(t)`` with ``w = 1`` (``"constant"``), ``sin(Ωt)`` (``"sine"``) or
    ``cos(Ωt)`` (``"cosine"``) is generated by an exosystem appended to the state:
    ``z = [x, v, w_s, w_c]`` with ``ẇ_s = Ω w_c``, ``ẇ_c = -Ω w_s`` (or ``ẇ = 0``), so
    ``z(t) = expm(A_aug t) z(0)`` is exact up to round-off, resonance included.

    Parameters
    ----------
    t : array_like, shape (nt,)
        Times [s] >= 0, any order.
    x0, v0 : array_like, shape (n,)
        Initial displacements [m] and velocities [m/s].
    force_amplitudes : array_like, shape (n,)
        Force amplitude ``F_i`` [N] on each mass.
    force_kind : {"constant", "sine", "cosine"}
    force_frequency : float
        Ω [rad/s], required for harmonic kinds.
    """
    times = _times("t", t)
    x0, v0 = _state_vector(chain, "x0", x0), _state_vector(chain, "v0", v0)
    amplitudes = _state_vector(chain, "force_amplitudes", force_amplitudes)
    if force_kind not in FORCE_KINDS:
        raise ModelError(f"force_kind must be one of {FORCE_KINDS}, got {force_kind!r}")
    A, B = state_space(chain)
    n = chain.size
    if force_kind == "constant":
        exo, w0, pick = np.zeros((1, 1)), np.array([1.0]), np.array([1.0])
    else:
        if force_frequency is None:
            raise ModelError(f"force_frequency [rad/s] is required for force_kind={force_kind!r}")
        big_omega = finite("force_frequency", force_frequency)
        exo = np.array([[0.0, big_omega], [-big_omega, 0.0]])
        w0 = np.array([0.0, 1.0])
        pick = np.array([1.0, 0.0]) if force_kind == "sine" else np.array([0.0, 1.0])
    m = exo.shape[0]
    augmented = np.zeros((2 * n + m, 2 * n + m))
    augmented[:2 * n, :2 * n] = A
    augmented[:2 * n, 2 * n:] = (B @ amplitudes)[:, None] * pick[None, :]
    augmented[2 * n:, 2 * n:] = exo
    z0 = np.concatenate([x0, v0, w0])
    states = sla.expm(times[:, None, None] * augmented[None]) @ z0
    x, v = states[:, :n], states[:, n:2 * n]
    force = (states[:, 2 * n:] @ pick)[:, None] * amplitudes[None, :]
    return TimeHistory(times, x, v, accelerations(chain, x, v, force))


def force_function(chain: GlobalChain, force_fn: ForceFunction | None) -> ForceFunction:
    if force_fn is None:
        zero = np.zeros(chain.size)
        return lambda time: zero
    """Wrap ``f(t) -> (n,)`` [N] (``None`` = no load) so that a wrong shape raises ModelError."""
    if not callable(force_fn):
        raise ModelError(f"force_fn must be a callable f(t) -> array of shape ({chain.size},), "
                         f"got {force_fn!r}")

    def checked(time: float) -> np.ndarray:
        value = np.asarray(force_fn(time), dtype=float)
        if value.shape != (chain.size,):
            raise ModelError(f"force_fn(t) must return shape ({chain.size},), got {value.shape}")
        return value
    return checked


def time_grid(t_final: float, dt: float) -> np.ndarray:
    """Uniform grid ``0, dt, ..., t_final``; ``t_final/dt`` must be (nearly) an integer."""
    t_final, dt = positive("t_final", t_final), positive("dt", dt)
    steps = int(round(t_final / dt))
    if steps < 1 or abs(steps * dt - t_final) > 1e-9 * t_final:
        raise ModelError(f"t_final/dt must be a positive integer, got t_final={t_final}, dt={dt}")
    return dt * np.arange(steps + 1)


def newmark_global(chain: GlobalChain, t_final: float, dt: float, x0, v0,
                   force_fn: ForceFunction | None = None, beta: float = 0.25, gamma: float = 0.5,
                   *, banded: bool = False) -> TimeHistory:
    """Textbook implicit Newmark integration of the global equations.

    Acceleration form (Newmark 1959; Hughes, *The Finite Element Method*, ch. 9): predictors
    ``x̃ = x + h v + (1/2 - β) h² a``, ``ṽ = v + (1 - γ) h a``; solve
    ``(M + γ h C + β h² K) a₊ = f(t₊) - C ṽ - K x̃``; correct ``x₊ = x̃ + β h² a₊``,
    ``v₊ = ṽ + γ h a₊``.  ``a₀`` from the equation of motion.  Algebraically identical to
    the displacement-form DT-TMM coefficients of FORMULAS §3.1.

    Parameters
    ----------
    t_final, dt : float
        End time and step [s]; ``t_final/dt`` must be an integer.
    force_fn : callable, optional
        ``f(t) -> (n,)`` external forces [N]; zero when omitted.
    beta, gamma : float
        Newmark parameters (0.25, 0.5 = average acceleration, 2nd order).
    banded : bool
        Use ``solve_banded`` per step instead of one dense LU factorisation.
    """
    beta = positive("beta", beta)
    gamma = nonnegative("gamma", gamma)
    times = time_grid(t_final, dt)
    h = float(times[1])
    force = force_function(chain, force_fn)
    M, C, K = assemble(chain)
    x = np.empty((times.size, chain.size))
    v, a = np.empty_like(x), np.empty_like(x)
    x[0], v[0] = _state_vector(chain, "x0", x0), _state_vector(chain, "v0", v0)
    a[0] = accelerations(chain, x[0], v[0], force(0.0))
    effective = M + gamma * h * C + beta * h * h * K
    if banded:
        band = to_banded(effective)
        solve = lambda rhs: sla.solve_banded((1, 1), band, rhs)  # noqa: E731
    else:
        factors = sla.lu_factor(effective)
        solve = lambda rhs: sla.lu_solve(factors, rhs)  # noqa: E731
    for i in range(times.size - 1):
        x_pred = x[i] + h * v[i] + (0.5 - beta) * h * h * a[i]
        v_pred = v[i] + (1.0 - gamma) * h * a[i]
        a[i + 1] = solve(force(times[i + 1]) - C @ v_pred - K @ x_pred)
        x[i + 1] = x_pred + beta * h * h * a[i + 1]
        v[i + 1] = v_pred + gamma * h * a[i + 1]
    return TimeHistory(times, x, v, a)


def solve_ivp_response(chain: GlobalChain, t_eval, x0, v0, force_fn: ForceFunction | None = None,
                       *, rtol: float = 1e-11, atol: float = 1e-13) -> TimeHistory:
    """Response to an arbitrary force ``f(t)`` by ``scipy.integrate.solve_ivp`` (DOP853).

    Integrates the first-order form from ``t = 0`` to ``max(t_eval)`` and samples it at the
    increasing times ``t_eval`` [s]; accelerations from the equation of motion.
    """
    times = _times("t_eval", t_eval)
    if np.any(np.diff(times) <= 0.0):
        raise ModelError("t_eval must be strictly increasing")
    rtol, atol = positive("rtol", rtol), positive("atol", atol)
    force = force_function(chain, force_fn)
    A, B = state_space(chain)
    z0 = np.concatenate([_state_vector(chain, "x0", x0), _state_vector(chain, "v0", v0)])
    result = solve_ivp(lambda time, z: A @ z + B @ force(time), (0.0, float(times[-1])), z0,
                       method="DOP853", t_eval=times, rtol=rtol, atol=atol)
    if not result.success:
        raise SimulationError(f"solve_ivp failed: {result.message}", time=float(result.t[-1]))
    n = chain.size
    x, v = result.y[:n].T, result.y[n:].T
    f = np.array([force(time) for time in times])
    return TimeHistory(times, x, v, accelerations(chain, x, v, f))
