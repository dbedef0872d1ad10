"""Independent references for linear delay-differential equations (DDEs).

Closed forms and a spectral discretisation that ctmm's production root finder
(:mod:`ctmm.roots`) and stability module are checked against.  This module shares no code
with :mod:`ctmm.roots`: it never imports it and uses different algorithms (Lambert W,
D-subdivision formulas, Chebyshev collocation of the infinitesimal generator, Newton on a
determinant).

Notation (Laplace variable ``s`` in [1/s]; delays ``tau`` in [s])

===================  =====================================================================
symbol               meaning
===================  =====================================================================
``a, b``             coefficients of the scalar equation x'(t) = a x(t) + b x(t - tau) [1/s]
``A0, A_k``          matrices of x'(t) = A0 x(t) + sum_k A_k x(t - tau_k) [1/s]
``omega_n, zeta``    natural frequency [rad/s] and damping ratio [-] of the PD oscillator
``k_p, k_d``         delayed PD gains, per unit mass [1/s^2] and [1/s]
``Omega``            crossing frequency s = i Omega on the imaginary axis [rad/s]
===================  =====================================================================

References
----------
N. D. Hayes, "Roots of the transcendental equation associated with a certain
difference-differential equation", J. London Math. Soc. 25 (1950) 226-232.
G. Stépán, *Retarded Dynamical Systems: Stability and Characteristic Functions*, Longman, 1989.
T. Insperger, G. Stépán, *Semi-Discretization for Time-Delay Systems*, Springer AMS 178, 2011.
D. Breda, S. Maset, R. Vermiglio, "Pseudospectral differencing methods for characteristic
roots of delay differential equations", SIAM J. Sci. Comput. 27(2) (2005) 482-495.
H. Shinozaki, T. Mori, "Robust stability analysis of linear time-delay systems by Lambert W
function", Automatica 42 (2006) 1791-1799 (the principal branch gives the rightmost root).
"""
from __future__ import annotations

import math
from collections.abc import Callable, Sequence
from dataclasses import dataclass

import numpy as np
import scipy.linalg
from scipy.special import lambertw

from ..errors import ModelError
from ..validation import finite, finite_array, positive

__all__ = [
    "lambert_w_roots", "scalar_characteristic_function",
    "DCurves", "delayed_pd_oscillator_dcurves", "delayed_pd_oscillator_characteristic_function",
    "hayes_is_stable", "hayes_critical_b", "hayes_critical_delay", "hayes_boundary",
    "second_order_system", "characteristic_function", "chebyshev_collocation_roots",
    "newton_refine_root",
]

ComplexFunction = Callable[[np.ndarray], np.ndarray]


# --------------------------------------------------------------------------------------------
# Scalar equation x'(t) = a x(t) + b x(t - tau): Lambert W
# --------------------------------------------------------------------------------------------
def lambert_w_roots(a: float, b: float, tau: float, branches: int | Sequence[int]) -> np.ndarray:
    """Characteristic roots of x'(t) = a x(t) + b x(t - tau) from the Lambert W function.

    The characteristic equation s - a - b e^(-s tau) = 0 becomes, with z = (s - a) tau,
    z e^z = b tau e^(-a tau), hence

        s_k = a + W_k(b tau e^(-a tau)) / tau,

    one root per branch k of W.  For real a and b the principal branch k = 0 gives the
    rightmost root (Shinozaki & Mori 2006).  For k >= 1 the conjugate of branch k is branch -k
    when b > 0 and branch -k - 1 when b < 0 (scipy's convention on the branch cut); branch 0 is
    real for b tau e^(-a tau) >= -1/e (and then so is branch -1 if b < 0), otherwise branches 0
    and -1 are conjugate.

    Parameters
    ----------
    a : float
        Coefficient of the undelayed term [1/s].
    b : float
        Coefficient of the delayed term [1/s]; must be non-zero (b = 0 has the single root a).
    tau : float
        Delay [s], > 0.
    branches : int or sequence of int
        Branch indices k of W.

    Returns
    -------
    numpy.ndarray of complex
        Roots s_k [1/s] in the order of ``branches`` (shape ``(len(branches),)``, or ``()``
        for a single int).

    Examples
    --------
    Hayes' equation lambda = -e^(-lambda) (a = 0, b = -1, tau = 1):

    >>> s = complex(lambert_w_roots(0.0, -1.0, 1.0, 0))
    >>> round(s.real, 9), round(s.imag, 9)
    (-0.318131505, 1.337235701)
    """
    a = finite("a", a)
    b = finite("b", b)
    tau = positive("tau", tau)
    if b == 0.0:
        raise ModelError("b must be non-zero (b = 0 gives the single root s = a), got 0.0")
    k = np.asarray(branches)
    if k.dtype.kind not in "iu":
        raise ModelError(f"branches must be an int or a sequence of ints, got {branches!r}")
    argument = b * tau * math.exp(-a * tau)
    w = np.asarray(lambertw(argument, k), dtype=complex)
    return np.asarray(a + w / tau)


def scalar_characteristic_function(a: float, b: float, tau: float) -> ComplexFunction:
    """Vectorised Delta(s) = s - a - b e^(-s tau) of x'(t) = a x(t) + b x(t - tau).

    Parameters
    ----------
    a, b : float
        Coefficients [1/s].
    tau : float
        Delay [s], > 0.

    Returns
    -------
    callable
        ``Delta(s)`` for a complex array ``s`` (same shape out).
    """
    a = finite("a", a)
    b = finite("b", b)
    tau = positive("tau", tau)

    def delta(s: np.ndarray) -> np.ndarray:
        s = np.asarray(s, dtype=complex)
        return s - a - b * np.exp(-s * tau)

    return delta


# --------------------------------------------------------------------------------------------
# Hayes stability region of x'(t) = a x(t) + b x(t - tau)
# --------------------------------------------------------------------------------------------
def _hayes_xi(p: float) -> float:
    """Root xi in (0, pi) of xi cot(xi) = p, for p < 1 (xi = pi/2 when p = 0)."""
    # xi cos(xi) - p sin(xi) changes sign once on (0, pi) when p < 1 (xi cot xi falls
    # monotonically from 1 to -inf there).
    from scipy.optimize import brentq

    if p == 0.0:
        return math.pi / 2
    return brentq(lambda x: x * math.cos(x) - p * math.sin(x), 1e-12, math.pi - 1e-12,
                  xtol=1e-15, rtol=1e-15, maxiter=200)


def hayes_critical_b(a: float, tau: float) -> float:
    """Most negative delayed coefficient b keeping x' = a x + b x(t - tau) stable.

    Hayes (1950), in scaled form p = a tau, q = b tau: all roots lie in Re s < 0 iff
    p < 1, p + q < 0 and q > -sqrt(p^2 + xi^2), where xi in (0, pi) solves xi cot(xi) = p.

    Parameters
    ----------
    a : float
        Undelayed coefficient [1/s], with a tau < 1.
    tau : float
        Delay [s], > 0.

    Returns
    -------
    float
        b_crit = -sqrt(p^2 + xi^2) / tau [1/s]: the system is stable for b_crit < b < -a.
    """
    a = finite("a", a)
    tau = positive("tau", tau)
    p = a * tau
    if p >= 1.0:
        raise ModelError(f"a*tau must be < 1 (otherwise no b stabilises), got a*tau = {p!r}")
    xi = _hayes_xi(p)
    return -math.hypot(p, xi) / tau


def hayes_is_stable(a: float, b: float, tau: float) -> bool:
    """Whether every root of s = a + b e^(-s tau) has negative real part (Hayes 1950).

    Parameters
    ----------
    a, b : float
        Coefficients [1/s].
    tau : float
        Delay [s], > 0.

    Returns
    -------
    bool
        True iff a tau < 1, a + b < 0 and b > :func:`hayes_critical_b` (a, tau).
    """
    a = finite("a", a)
    b = finite("b", b)
    tau = positive("tau", tau)
    if a * tau >= 1.0 or a + b >= 0.0:
        return False
    return b > hayes_critical_b(a, tau)


def hayes_critical_delay(a: float, b: float) -> float:
    """Smallest delay at which x' = a x + b x(t - tau) loses stability (|b| > |a|, a + b < 0).

    On the boundary s = i omega: omega = sqrt(b^2 - a^2), cos(omega tau) = -a/b,
    sin(omega tau) = -omega/b, so tau_c = arccos(-a/b)/omega.  If b >= -|a| with a + b < 0 the
    system is stable for every delay and ``inf`` is returned.

    Parameters
    ----------
    a, b : float
        Coefficients [1/s] with a + b < 0.

    Returns
    -------
    float
        Critical delay tau_c [s] (``math.inf`` for delay-independent stability).
    """
    a = finite("a", a)
    b = finite("b", b)
    if a + b >= 0.0:
        raise ModelError("a + b must be < 0 (otherwise unstable at tau = 0), "
                         f"got a + b = {a + b!r}")
    if abs(b) <= abs(a):
        return math.inf
    omega = math.sqrt(b * b - a * a)
    return math.acos(-a / b) / omega


def hayes_boundary(tau: float, omega: np.ndarray) -> tuple[np.ndarray, np.ndarray]:
    """Oscillatory stability boundary (a(omega), b(omega)) of x' = a x + b x(t - tau).

    From i omega = a + b e^(-i omega tau): a = omega cot(omega tau), b = -omega / sin(omega tau),
    for omega tau in (0, pi); together with the static line a + b = 0 it bounds the region.

    Parameters
    ----------
    tau : float
        Delay [s], > 0.
    omega : array_like
        Crossing frequencies [rad/s] with 0 < omega tau < pi.

    Returns
    -------
    a, b : numpy.ndarray
        Boundary points [1/s].
    """
    tau = positive("tau", tau)
    omega = finite_array("omega", omega)
    nu = omega * tau
    if np.any((nu <= 0.0) | (nu >= math.pi)):
        raise ModelError(f"omega*tau must lie in (0, pi), got range [{nu.min()!r}, {nu.max()!r}]")
    return omega / np.tan(nu), -omega / np.sin(nu)


# --------------------------------------------------------------------------------------------
# Delayed PD oscillator (FORMULAS 6.2)
# --------------------------------------------------------------------------------------------
@dataclass(frozen=True)
class DCurves:
    """D-subdivision curves of the delayed PD oscillator in the (k_p, k_d) plane.

    Attributes
    ----------
    omega : numpy.ndarray
        Crossing frequencies Omega [rad/s] (a root at s = i Omega).
    proportional_gain : numpy.ndarray
        k_p(Omega) [1/s^2] (per unit mass).
    derivative_gain : numpy.ndarray
        k_d(Omega) [1/s] (per unit mass).
    static_proportional_gain : float
        The static line k_p = -omega_n^2 [1/s^2] (root s = 0, any k_d).
    """

    omega: np.ndarray
    proportional_gain: np.ndarray
    derivative_gain: np.ndarray
    static_proportional_gain: float


def delayed_pd_oscillator_dcurves(omega_n: float, zeta: float, tau: float,
                                  Omega: np.ndarray) -> DCurves:
    """Closed-form D-curves of the delayed PD oscillator (FORMULAS 6.2).

    Equation x'' + 2 zeta omega_n x' + omega_n^2 x = -k_p x(t - tau) - k_d x'(t - tau) with
    characteristic function
    Delta(s) = s^2 + 2 zeta omega_n s + omega_n^2 + (k_p + k_d s) e^(-s tau).
    Setting Delta(i Omega) = 0 and splitting real and imaginary parts (FORMULAS 6.2):

        k_p(Omega) = (Omega^2 - omega_n^2) cos(Omega tau) + 2 zeta omega_n Omega sin(Omega tau)
        k_d(Omega) = [(Omega^2 - omega_n^2) sin(Omega tau)
                      - 2 zeta omega_n Omega cos(Omega tau)] / Omega

    plus the static line k_p = -omega_n^2 (root s = 0).

    Parameters
    ----------
    omega_n : float
        Natural frequency [rad/s], > 0.
    zeta : float
        Damping ratio [-], finite.
    tau : float
        Delay [s], >= 0.
    Omega : array_like
        Crossing frequencies [rad/s], non-zero.

    Returns
    -------
    DCurves
    """
    omega_n = positive("omega_n", omega_n)
    zeta = finite("zeta", zeta)
    tau = finite("tau", tau)
    if tau < 0.0:
        raise ModelError(f"tau must be >= 0, got {tau!r}")
    Omega = finite_array("Omega", Omega)
    if np.any(Omega == 0.0):
        raise ModelError("Omega must be non-zero (Omega = 0 is the static line k_p = -omega_n^2)")
    c, s = np.cos(Omega * tau), np.sin(Omega * tau)
    A = Omega ** 2 - omega_n ** 2
    B = 2.0 * zeta * omega_n * Omega
    k_p = A * c + B * s
    k_d = (A * s - B * c) / Omega
    return DCurves(omega=Omega, proportional_gain=k_p, derivative_gain=k_d,
                   static_proportional_gain=-omega_n ** 2)


def delayed_pd_oscillator_characteristic_function(omega_n: float, zeta: float, tau: float,
                                                  k_p: float, k_d: float) -> ComplexFunction:
    """Vectorised Delta(s) = s^2 + 2 zeta omega_n s + omega_n^2 + (k_p + k_d s) e^(-s tau).

    Parameters
    ----------
    omega_n : float
        Natural frequency [rad/s], > 0.
    zeta : float
        Damping ratio [-].
    tau : float
        Delay [s], >= 0.
    k_p, k_d : float
        Delayed gains per unit mass [1/s^2], [1/s].

    Returns
    -------
    callable
        ``Delta(s)`` for a complex array ``s``.
    """
    omega_n = positive("omega_n", omega_n)
    zeta = finite("zeta", zeta)
    tau = finite("tau", tau)
    if tau < 0.0:
        raise ModelError(f"tau must be >= 0, got {tau!r}")
    k_p = finite("k_p", k_p)
    k_d = finite("k_d", k_d)

    def delta(s: np.ndarray) -> np.ndarray:
        s = np.asarray(s, dtype=complex)
        return s * s + 2.0 * zeta * omega_n * s + omega_n ** 2 + (k_p + k_d * s) * np.exp(-s * tau)

    return delta


# --------------------------------------------------------------------------------------------
# Linear DDE systems: first-order form, characteristic function, Chebyshev collocation
# --------------------------------------------------------------------------------------------
def _square(name: str, value: object, size: int | None = None) -> np.ndarray:
    array = finite_array(name, value, ndim=2)
    if array.shape[0] != array.shape[1] or (size is not None and array.shape[0] != size):
        wanted = f"({size}, {size})" if size is not None else "square"
        raise ModelError(f"{name} must be {wanted}, got shape {array.shape}")
    return array


def _delayed_list(A0: np.ndarray, delayed: Sequence[tuple[object, float]]
                  ) -> list[tuple[np.ndarray, float]]:
    if isinstance(delayed, (str, bytes)) or not isinstance(delayed, Sequence):
        raise ModelError(f"delayed must be a list of (A_k, tau_k) pairs, got {delayed!r}")
    out = []
    for k, item in enumerate(delayed):
        if not isinstance(item, (tuple, list)) or len(item) != 2:
            raise ModelError(f"delayed[{k}] must be a pair (A_k, tau_k), got {item!r}")
        matrix = _square(f"delayed[{k}] matrix", item[0], A0.shape[0])
        tau = positive(f"delayed[{k}] delay tau_k", item[1])
        out.append((matrix, tau))
    return out


def second_order_system(M: object, C: object, K: object,
                        delayed_terms: Sequence[tuple[object, object, float]]
                        ) -> tuple[np.ndarray, list[tuple[np.ndarray, float]]]:
    """First-order form of M x'' + C x' + K x = -sum_k (G_k x(t - tau_k) + H_k x'(t - tau_k)).

    With y = [x, x'] the system becomes y' = A0 y + sum_k A_k y(t - tau_k),

        A0  = [[0, I], [-M^-1 K, -M^-1 C]],
        A_k = [[0, 0], [-M^-1 G_k, -M^-1 H_k]].

    Delayed *accelerations* (neutral equations) are not supported: the form is retarded, so
    its rightmost roots are finite in number in every right half plane Re s > c.

    Parameters
    ----------
    M, C, K : array_like, shape (n, n)
        Mass [kg], damping [N s/m] and stiffness [N/m] matrices; M must be invertible.
    delayed_terms : sequence of (G_k, H_k, tau_k)
        Delayed displacement gain G_k [N/m], velocity gain H_k [N s/m] and delay tau_k [s] > 0.

    Returns
    -------
    A0 : numpy.ndarray, shape (2n, 2n)
    delayed : list of (A_k, tau_k)
        Ready for :func:`chebyshev_collocation_roots` and :func:`characteristic_function`.
    """
    M = _square("M", M)
    n = M.shape[0]
    C = _square("C", C, n)
    K = _square("K", K, n)
    try:
        Minv = np.linalg.inv(M)
    except np.linalg.LinAlgError:
        raise ModelError("M must be invertible (singular mass matrix)") from None
    zero, eye = np.zeros((n, n)), np.eye(n)
    A0 = np.block([[zero, eye], [-Minv @ K, -Minv @ C]])
    if isinstance(delayed_terms, (str, bytes)) or not isinstance(delayed_terms, Sequence):
        raise ModelError("delayed_terms must be a list of (G_k, H_k, tau_k), "
                         f"got {delayed_terms!r}")
    delayed = []
    for k, item in enumerate(delayed_terms):
        if not isinstance(item, (tuple, list)) or len(item) != 3:
            raise ModelError(f"delayed_terms[{k}] must be (G_k, H_k, tau_k), got {item!r}")
        G = _square(f"delayed_terms[{k}] G", item[0], n)
        H = _square(f"delayed_terms[{k}] H", item[1], n)
        tau = positive(f"delayed_terms[{k}] delay tau_k", item[2])
        delayed.append((np.block([[zero, zero], [-Minv @ G, -Minv @ H]]), tau))
    return A0, delayed


def characteristic_function(A0: object, delayed: Sequence[tuple[object, float]]) -> ComplexFunction:
    """Vectorised Delta(s) = det(s I - A0 - sum_k A_k e^(-s tau_k)).

    Parameters
    ----------
    A0 : array_like, shape (d, d)
        Undelayed system matrix [1/s].
    delayed : sequence of (A_k, tau_k)
        Delayed matrices [1/s] and delays [s] > 0.

    Returns
    -------
    callable
        ``Delta(s)`` for a complex array ``s`` of any shape (same shape out).
    """
    A0 = _square("A0", A0)
    terms = _delayed_list(A0, delayed)
    d = A0.shape[0]
    eye = np.eye(d)

    def delta(s: np.ndarray) -> np.ndarray:
        s = np.asarray(s, dtype=complex)
        flat = s.reshape(-1)[:, None, None]
        matrix = flat * eye - A0
        for Ak, tau in terms:
            matrix = matrix - Ak * np.exp(-flat * tau)
        return np.linalg.det(matrix).reshape(s.shape)

    return delta


def _chebyshev_nodes_and_derivative(n: int) -> tuple[np.ndarray, np.ndarray]:
    """Chebyshev extremal nodes x_j = cos(j pi / n) and differentiation matrix (Trefethen 2000)."""
    j = np.arange(n + 1)
    x = np.cos(np.pi * j / n)
    c = np.where((j == 0) | (j == n), 2.0, 1.0) * (-1.0) ** j
    dx = x[:, None] - x[None, :]
    D = np.outer(c, 1.0 / c) / (dx + np.eye(n + 1))
    D -= np.diag(D.sum(axis=1))
    return x, D


def _barycentric_row(x: np.ndarray, point: float) -> np.ndarray:
    """Lagrange basis values l_j(point) on Chebyshev extremal nodes (barycentric form)."""
    n = x.size - 1
    w = (-1.0) ** np.arange(n + 1)
    w[0] *= 0.5
    w[-1] *= 0.5
    diff = point - x
    hit = np.flatnonzero(np.abs(diff) < 1e-15)
    if hit.size:
        row = np.zeros(n + 1)
        row[hit[0]] = 1.0
        return row
    terms = w / diff
    return terms / terms.sum()


def chebyshev_collocation_roots(A0: object, delayed: Sequence[tuple[object, float]], n_nodes: int,
                                *, refine: int = 0) -> np.ndarray:
    """Rightmost characteristic roots of x' = A0 x + sum_k A_k x(t - tau_k) by collocation.

    Pseudospectral discretisation of the infinitesimal generator (Breda, Maset & Vermiglio
    2005): the state phi in C([-tau_max, 0], R^d) is represented by its values at the n_nodes + 1
    Chebyshev extremal nodes theta_j = tau_max (cos(j pi / n_nodes) - 1)/2 (theta_0 = 0).  Rows
    j >= 1 of the discrete generator are the Chebyshev derivative phi'(theta_j); the row at
    theta_0 = 0 imposes the DDE, A0 phi(0) + sum_k A_k p(-tau_k), with p the interpolating
    polynomial.  Its eigenvalues converge spectrally (geometrically in n_nodes) to the
    characteristic roots of moderate modulus, |s| tau_max < ~1.1 N; beyond, the eigenvalues are
    spurious (spectral pollution, residual O(0.01-0.1); docs/characteristic_roots.md section 5)
    and may lie to the right of true roots: these are candidates, not verified roots (use
    :func:`ctmm.reference.dde_verified.verified_roots`).

    Parameters
    ----------
    A0 : array_like, shape (d, d)
        Undelayed system matrix [1/s].
    delayed : sequence of (A_k, tau_k)
        Delayed matrices [1/s] with delays tau_k [s] > 0; an empty list gives eig(A0).
    n_nodes : int
        Number of Chebyshev intervals N (the grid has N + 1 nodes), >= 2.
    refine : int, optional
        Number of rightmost eigenvalues to polish by Newton's method on
        det(s I - A0 - sum_k A_k e^(-s tau_k)) (see :func:`newton_refine_root`).  Default 0.

    Returns
    -------
    numpy.ndarray of complex, shape (d (N + 1),)
        Eigenvalues [1/s] sorted by decreasing real part (ties: increasing imaginary part).

    Examples
    --------
    >>> roots = chebyshev_collocation_roots([[0.0]], [([[-1.0]], 1.0)], 30)
    >>> s = complex(roots[1])
    >>> round(s.real, 9), round(s.imag, 9)
    (-0.318131505, 1.337235701)
    """
    A0 = _square("A0", A0)
    terms = _delayed_list(A0, delayed)
    if isinstance(n_nodes, bool) or not isinstance(n_nodes, (int, np.integer)) or n_nodes < 2:
        raise ModelError(f"n_nodes must be an int >= 2, got {n_nodes!r}")
    if isinstance(refine, bool) or not isinstance(refine, (int, np.integer)) or refine < 0:
        raise ModelError(f"refine must be an int >= 0, got {refine!r}")
    d = A0.shape[0]
    if not terms:
        eig = np.linalg.eigvals(A0).astype(complex)
        return eig[np.lexsort((eig.imag, -eig.real))]
    n = int(n_nodes)
    tau_max = max(tau for _, tau in terms)
    x, D = _chebyshev_nodes_and_derivative(n)
    generator = np.kron((2.0 / tau_max) * D, np.eye(d))          # rows j >= 1: phi'(theta_j)
    first = np.zeros((d, d * (n + 1)))
    first[:, :d] += A0
    for Ak, tau in terms:
        row = _barycentric_row(x, 1.0 - 2.0 * tau / tau_max)     # theta = -tau  ->  x
        first += np.kron(row[None, :], Ak)
    generator[:d, :] = first
    eig = scipy.linalg.eigvals(generator)
    eig = eig[np.lexsort((eig.imag, -eig.real))]
    for i in range(min(int(refine), eig.size)):
        eig[i] = newton_refine_root(A0, terms, eig[i])
    if refine:
        eig = eig[np.lexsort((eig.imag, -eig.real))]
    return eig


def newton_refine_root(A0: object, delayed: Sequence[tuple[object, float]], s0: complex, *,
                       tol: float = 1e-14, max_iterations: int = 30) -> complex:
    """Polish a root of det(s I - A0 - sum_k A_k e^(-s tau_k)) by Newton's method.

    With T(s) = s I - A0 - sum_k A_k e^(-s tau_k) and Jacobi's formula
    d/ds det T = det T * trace(T^-1 T'), the Newton step is 1 / trace(T^-1 T'(s)), where
    T'(s) = I + sum_k tau_k A_k e^(-s tau_k).  Converges quadratically to simple roots.

    Parameters
    ----------
    A0 : array_like, shape (d, d)
        Undelayed matrix [1/s].
    delayed : sequence of (A_k, tau_k)
        Delayed matrices [1/s] and delays [s].
    s0 : complex
        Starting point [1/s].
    tol : float, optional
        Stop when |step| <= tol max(1, |s|).
    max_iterations : int, optional
        Iteration limit; the last iterate is returned if it is reached.

    Returns
    -------
    complex
        The refined root [1/s].
    """
    A0 = _square("A0", A0)
    terms = _delayed_list(A0, delayed)
    s = complex(s0)
    eye = np.eye(A0.shape[0])
    for _ in range(max_iterations):
        T = s * eye - A0
        dT = eye.astype(complex)
        for Ak, tau in terms:
            e = np.exp(-s * tau)
            T = T - Ak * e
            dT = dT + tau * Ak * e
        try:
            trace = np.trace(np.linalg.solve(T, dT))
        except np.linalg.LinAlgError:
            return s          # exactly singular: s is a root
        if trace == 0 or not np.isfinite(trace):
            return s
        step = 1.0 / trace
        s -= step
        if abs(step) <= tol * max(1.0, abs(s)):
            break
    return s
