"""Independent Euler-Bernoulli beam references (share no code with the transfer-matrix elements).

Three kinds of reference:

1. **Frequency equations** of uniform beams in ``β = λL`` (``λ^4 = ρA ω^2 / EI``,
   ``ω = β^2 sqrt(EI / (ρA L^4))``) with overflow-free root finding
   (:func:`frequency_equation`, :func:`beta_roots`), the exact cantilever tip receptance
   (:func:`cantilever_tip_receptance`) and the pinned-pinned beam under tension
   (:func:`pinned_pinned_tension_frequencies`).  Sources: Blevins, *Formulas for Natural
   Frequency and Mode Shape* (1979), Tables 8-1, 8-8; FORMULAS §2.4, §2.6 (tip mass/inertia
   and hub-beam equations, the hub term's sign verified there against FEM).
2. **Hermite finite elements** (:class:`HermiteBeam`): cubic Hermite beam elements
   (consistent mass, optional geometric stiffness of a constant axial force), point masses
   and rotary inertias, grounded springs, in-span elastic hinges (duplicated slope DOF),
   end conditions clamped / pinned / free / sliding; global ``K, M`` and ``scipy.linalg.eigh``.
3. **Kane-Ryan-Banerjee spin-up** (:func:`kane_spinup`, FORMULAS §6.1): assumed-modes Lagrange
   model of a clamped-free beam on a hub with prescribed angle ``θ(t)`` and the consistent
   geometric-stiffening matrix ``KG_ij = ∫ ρA (L^2 - x^2)/2 φ_i' φ_j' dx`` (switchable off),
   integrated by ``scipy.integrate.solve_ivp`` (DOP853, tight tolerances).

Equation of motion of the spin-up model (hub radius 0; deflection ``v = Σ φ_i q_i`` in the hub
frame, axial foreshortening ``u = -1/2 ∫_0^x v'^2``; Kane, Ryan, Banerjee, J. Guidance 10 (1987)
139-151)::

    M q'' + (K + θ'^2 (KG - M)) q = -θ'' p,   p_i = ∫ ρA x φ_i dx,   M_ij = ∫ ρA φ_i φ_j dx.

Without ``KG`` (the "conventional" linear model) the first mode loses stiffness once
``θ' > ω_1`` and the response diverges.
"""
from __future__ import annotations

import math
from dataclasses import dataclass, field
from typing import Sequence

import numpy as np
import scipy.integrate
import scipy.linalg
import scipy.optimize

from ..errors import ModelError

__all__ = [
    "CASES", "frequency_equation", "beta_roots", "omega_from_beta", "beta_from_omega",
    "cantilever_tip_receptance", "pinned_pinned_tension_frequencies",
    "clamped_free_mode", "Section", "HermiteBeam",
    "spinup_angle", "SpinUpResult", "kane_spinup",
]


# ======================================================================================
# 1. Frequency equations (all scaled by cosh β so nothing overflows)
def _sech(beta: np.ndarray) -> np.ndarray:
    e = np.exp(-np.abs(beta))
    return 2 * e / (1 + e * e)


def _eq_clamped_free(b, **_):
    # 1 + cos β cosh β = 0
    return np.cos(b) + _sech(b)


def _eq_pinned_free(b, **_):
    # tan β = tanh β  (also clamped-pinned); pinned-free has a rigid mode β = 0 (excluded)
    return np.sin(b) - np.cos(b) * np.tanh(b)


def _eq_free_free(b, **_):
    # 1 - cos β cosh β = 0  (also clamped-clamped); free-free has two rigid modes (excluded)
    return np.cos(b) - _sech(b)


def _eq_pinned_pinned(b, **_):
    return np.sin(b)


def _eq_clamped_sliding(b, **_):
    # tan β + tanh β = 0 (also sliding-free, which has a rigid translation mode)
    return np.sin(b) + np.cos(b) * np.tanh(b)


def _eq_pinned_sliding(b, **_):
    # cos β = 0
    return np.cos(b)


def _eq_tip_mass(b, *, tip_mass_ratio=0.0, tip_inertia_ratio=0.0, **_):
    # FORMULAS §2.6: 1 + cos β cosh β + μβ(cos β sinh β - sin β cosh β)
    #   - jβ^3 (cosh β sin β + sinh β cos β) + μjβ^4 (1 - cos β cosh β) = 0,  divided by cosh β
    mu, j = tip_mass_ratio, tip_inertia_ratio
    c, s, t, h = np.cos(b), np.sin(b), np.tanh(b), _sech(b)
    return (h + c + mu * b * (c * t - s) - j * b ** 3 * (s + t * c)
            + mu * j * b ** 4 * (h - c))


def _eq_hub(b, *, hub_inertia_ratio=0.0, **_):
    # FORMULAS §2.6: (cos β sinh β - sin β cosh β) - η β^3 (1 + cos β cosh β) = 0, / cosh β
    eta = hub_inertia_ratio
    c, s, t, h = np.cos(b), np.sin(b), np.tanh(b), _sech(b)
    return (c * t - s) - eta * b ** 3 * (h + c)


_EQUATIONS = {
    "clamped-free": _eq_clamped_free,
    "pinned-free": _eq_pinned_free,
    "clamped-pinned": _eq_pinned_free,
    "free-free": _eq_free_free,
    "clamped-clamped": _eq_free_free,
    "pinned-pinned": _eq_pinned_pinned,
    "sliding-sliding": _eq_pinned_pinned,
    "clamped-sliding": _eq_clamped_sliding,
    "sliding-free": _eq_clamped_sliding,
    "pinned-sliding": _eq_pinned_sliding,
    "tip-mass": _eq_tip_mass,
    "hub-beam": _eq_hub,
}
CASES = tuple(_EQUATIONS)
"""Supported cases.  ``"tip-mass"``: clamped-free with tip mass ratio ``μ = M_t/(ρA L)`` and tip
inertia ratio ``j = J_t/(ρA L^3)``; ``"hub-beam"``: rigid hub of inertia ratio
``η = J_h/(ρA L^3)`` pivoting at the beam root (hub radius 0), free tip."""


def _check_case(case: str) -> None:
    if case not in _EQUATIONS:
        raise ModelError(f"unknown beam case {case!r}; available: {', '.join(CASES)}")


def frequency_equation(case: str, beta, *, tip_mass_ratio: float = 0.0, tip_inertia_ratio: float = 0.0,
                       hub_inertia_ratio: float = 0.0) -> np.ndarray:
    """Scaled frequency function of ``case`` at ``beta`` (zero at the natural frequencies).

    The classical equations are divided by ``cosh β`` so they stay O(1) for any ``β``.
    """
    _check_case(case)
    b = np.asarray(beta, dtype=float)
    return _EQUATIONS[case](b, tip_mass_ratio=tip_mass_ratio, tip_inertia_ratio=tip_inertia_ratio,
                            hub_inertia_ratio=hub_inertia_ratio)


def beta_roots(case: str, count: int, *, tip_mass_ratio: float = 0.0, tip_inertia_ratio: float = 0.0,
               hub_inertia_ratio: float = 0.0, step: float = 0.01) -> np.ndarray:
    """The first ``count`` positive roots ``β_k`` of the frequency equation of ``case``.

    Rigid-body modes (``β = 0``) are excluded.  Roots are bracketed on a grid of spacing
    ``step`` from ``β = 1e-3`` and refined by Brent's method to ``xtol = 1e-15``.

    Examples
    --------
    >>> beta_roots("clamped-free", 3).round(6).tolist()
    [1.875104, 4.694091, 7.854757]
    """
    _check_case(case)
    if isinstance(count, bool) or not isinstance(count, (int, np.integer)) or count < 1:
        raise ModelError(f"count must be an integer >= 1, got {count!r}")
    for name, value in (("tip_mass_ratio", tip_mass_ratio), ("tip_inertia_ratio", tip_inertia_ratio),
                        ("hub_inertia_ratio", hub_inertia_ratio)):
        if not (np.isfinite(value) and value >= 0):
            raise ModelError(f"{name} must be finite and >= 0, got {value!r}")
    kwargs = dict(tip_mass_ratio=tip_mass_ratio, tip_inertia_ratio=tip_inertia_ratio,
                  hub_inertia_ratio=hub_inertia_ratio)
    f = _EQUATIONS[case]
    roots: list[float] = []
    lo = 1e-3
    while len(roots) < count:
        hi = lo + max(10.0, 1.2 * np.pi * (count - len(roots)))
        grid = np.arange(lo, hi + step, step)
        values = f(grid, **kwargs)
        for i in np.flatnonzero(np.sign(values[:-1]) * np.sign(values[1:]) <= 0):
            a, b = grid[i], grid[i + 1]
            if values[i] == 0.0:
                root = a
            elif values[i + 1] == 0.0:
                continue  # picked up as the left end of the next interval
            else:
                root = scipy.optimize.brentq(lambda x: float(f(np.asarray(x), **kwargs)), a, b,
                                             xtol=1e-15, rtol=4 * np.finfo(float).eps, maxiter=200)
            roots.append(root)
            if len(roots) == count:
                break
        lo = grid[-1]
    return np.array(roots)


def omega_from_beta(beta, length: float, bending_stiffness: float, mass_per_length: float) -> np.ndarray:
    """``ω = (β/L)^2 sqrt(EI/ρA)`` [rad/s]."""
    return (np.asarray(beta) / length) ** 2 * math.sqrt(bending_stiffness / mass_per_length)


def beta_from_omega(omega, length: float, bending_stiffness: float, mass_per_length: float) -> np.ndarray:
    """``β = L (ρA ω^2 / EI)^(1/4)``."""
    return length * (mass_per_length * np.asarray(omega, dtype=float) ** 2 / bending_stiffness) ** 0.25


def cantilever_tip_receptance(omega, length: float, bending_stiffness: float, mass_per_length: float
                              ) -> np.ndarray:
    """Exact tip receptance ``w(L)/F`` [m/N] of an undamped clamped-free beam, tip force ``F``.

    ``α = (sin β cosh β - cos β sinh β) / (EI λ^3 (1 + cos β cosh β))`` (Bishop & Johnson,
    *The Mechanics of Vibration*, 1960, receptance tables), evaluated divided by ``cosh β``;
    static limit ``L^3/(3 EI)``.
    """
    w = np.asarray(omega, dtype=float)
    beta = beta_from_omega(w, length, bending_stiffness, mass_per_length)
    small = beta < 1e-3
    b = np.where(small, 1.0, beta)
    lam = b / length
    num = np.sin(b) - np.cos(b) * np.tanh(b)
    den = bending_stiffness * lam ** 3 * (_sech(b) + np.cos(b))
    static = length ** 3 / (3 * bending_stiffness)
    return np.where(small, static * (1 + 33 * beta ** 4 / 420), num / den)


def pinned_pinned_tension_frequencies(count: int, length: float, bending_stiffness: float,
                                      mass_per_length: float, axial_force: float) -> np.ndarray:
    """``ω_n = (nπ/L)^2 sqrt(EI/ρA) sqrt(1 + T L^2/(EI n^2 π^2))`` (FORMULAS §2.4; Blevins 8-8)."""
    n = np.arange(1, count + 1)
    return ((n * np.pi / length) ** 2 * math.sqrt(bending_stiffness / mass_per_length)
            * np.sqrt(1 + axial_force * length ** 2 / (bending_stiffness * n ** 2 * np.pi ** 2)))


def clamped_free_mode(beta: float, xi, derivative: int = 0) -> np.ndarray:
    """Clamped-free mode ``φ(ξ) = cosh βξ - cos βξ - σ (sinh βξ - sin βξ)`` and derivatives in ``ξ = x/L``.

    ``σ = (cosh β + cos β)/(sinh β + sin β)``; with this scaling ``∫_0^1 φ^2 dξ = 1`` and
    ``|φ(1)| = 2``.  Evaluated overflow- and cancellation-free through
    ``cosh y - σ sinh y = ((1-σ) e^y + (1+σ) e^-y)/2``,
    ``1 - σ = (sin β - cos β - e^-β) / (sinh β + sin β)``.

    Parameters
    ----------
    beta : float
        Root of ``1 + cos β cosh β = 0``.
    xi : array
        Positions ``x/L`` in [0, 1].
    derivative : int
        0..3: order of the derivative with respect to ``ξ``.
    """
    xi = np.asarray(xi, dtype=float)
    y = beta * xi
    eb = math.exp(-beta)
    den = 1 - eb * eb + 2 * math.sin(beta) * eb          # (sinh β + sin β) * 2 e^-β
    one_minus = (math.sin(beta) - math.cos(beta) - eb) * 2 / den   # (1-σ) e^β
    sigma = 1 - one_minus * eb
    grow = one_minus * np.exp(y - beta) / 2               # (1-σ) e^y / 2
    decay = (1 + sigma) * np.exp(-y) / 2                  # (1+σ) e^-y / 2
    cs, sn = np.cos(y), np.sin(y)
    # d^k/dy^k of [cosh y - σ sinh y] = grow + (-1)^k decay ; of [-cos y + σ sin y]:
    trig = [-cs + sigma * sn, sn + sigma * cs, cs - sigma * sn, -sn - sigma * cs]
    k = int(derivative)
    if k not in (0, 1, 2, 3):
        raise ModelError(f"derivative must be 0, 1, 2 or 3, got {derivative!r}")
    hyper = grow + (-1) ** k * decay
    return beta ** k * (hyper + trig[k])


# ======================================================================================
# 2. Hermite finite-element beam
@dataclass(frozen=True)
class Section:
    """A uniform stretch of beam: ``length`` [m], ``bending_stiffness`` EI [N m^2],
    ``mass_per_length`` ρA [kg/m], optional constant ``axial_force`` T [N] (tension > 0)."""

    length: float
    bending_stiffness: float
    mass_per_length: float
    axial_force: float = 0.0

    def __post_init__(self) -> None:
        for name in ("length", "bending_stiffness", "mass_per_length"):
            value = getattr(self, name)
            if not (np.isfinite(value) and value > 0):
                raise ModelError(f"Section: {name} must be > 0, got {value!r}")
        if not np.isfinite(self.axial_force):
            raise ModelError(f"Section: axial_force must be finite, got {self.axial_force!r}")


def _hermite_matrices(h: float, EI: float, rhoA: float, T: float) -> tuple[np.ndarray, np.ndarray]:
    """Element stiffness (bending + geometric) and consistent mass, DOFs [w1, θ1, w2, θ2]."""
    K = EI / h ** 3 * np.array([[12, 6 * h, -12, 6 * h],
                                [6 * h, 4 * h * h, -6 * h, 2 * h * h],
                                [-12, -6 * h, 12, -6 * h],
                                [6 * h, 2 * h * h, -6 * h, 4 * h * h]])
    Kg = T / (30 * h) * np.array([[36, 3 * h, -36, 3 * h],
                                  [3 * h, 4 * h * h, -3 * h, -h * h],
                                  [-36, -3 * h, 36, -3 * h],
                                  [3 * h, -h * h, -3 * h, 4 * h * h]])
    M = rhoA * h / 420 * np.array([[156, 22 * h, 54, -13 * h],
                                   [22 * h, 4 * h * h, 13 * h, -3 * h * h],
                                   [54, 13 * h, 156, -22 * h],
                                   [-13 * h, -3 * h * h, -22 * h, 4 * h * h]])
    return K + Kg, M


_END_CONSTRAINTS = {"clamped": ("w", "theta"), "pinned": ("w",), "free": (), "sliding": ("theta",)}


class HermiteBeam:
    """Global finite-element model of a straight beam assembly (Hermite cubic elements).

    Parameters
    ----------
    sections : sequence of Section
        Consecutive uniform stretches from ``x = 0``.
    left, right : {"clamped", "pinned", "free", "sliding"}
        End conditions at ``x = 0`` and ``x = L``.
    point_masses : sequence of (x, mass, rotary_inertia)
        Lumped inertia at ``x`` [m]: mass [kg], rotary inertia [kg m^2].
    springs : sequence of (x, translational, rotational)
        Grounded springs at ``x``: [N/m], [N m/rad].
    hinges : sequence of (x, rotational_stiffness)
        In-span elastic hinges (0 < x < L): the slope on the two sides are separate DOFs
        coupled by a rotational spring [N m/rad].  Masses/springs at a hinge act on the
        outboard slope.
    elements : int
        Approximate total number of elements, distributed over the stretches between
        breakpoints in proportion to their length (at least one each).

    Attributes
    ----------
    K, M : numpy.ndarray
        Global stiffness and mass matrices after removing constrained DOFs.
    nodes : numpy.ndarray
        Node positions [m].
    """

    def __init__(self, sections: Sequence[Section], *, left: str = "clamped", right: str = "free",
                 point_masses: Sequence[tuple[float, float, float]] = (),
                 springs: Sequence[tuple[float, float, float]] = (),
                 hinges: Sequence[tuple[float, float]] = (), elements: int = 60) -> None:
        sections = list(sections)
        if not sections or not all(isinstance(s, Section) for s in sections):
            raise ModelError("sections must be a non-empty sequence of Section")
        for side, cond in (("left", left), ("right", right)):
            if cond not in _END_CONSTRAINTS:
                raise ModelError(f"{side} must be one of {', '.join(_END_CONSTRAINTS)}, got {cond!r}")
        if isinstance(elements, bool) or not isinstance(elements, (int, np.integer)) or elements < 1:
            raise ModelError(f"elements must be an integer >= 1, got {elements!r}")
        ends = np.cumsum([0.0] + [s.length for s in sections])
        total = ends[-1]
        tol = 1e-12 * total

        def check_x(kind, x, open_ends=False):
            if not np.isfinite(x) or x < -tol or x > total + tol or (open_ends and (x <= tol or x >= total - tol)):
                where = "inside (0, L)" if open_ends else "in [0, L]"
                raise ModelError(f"{kind} position must be {where} with L = {total}, got {x!r}")
            return min(max(float(x), 0.0), total)

        masses = [(check_x("point mass", x), float(m), float(j)) for x, m, j in point_masses]
        springs_ = [(check_x("spring", x), float(kt), float(kr)) for x, kt, kr in springs]
        hinges_ = [(check_x("hinge", x, open_ends=True), float(k)) for x, k in hinges]
        for kind, items in (("point mass", masses), ("spring", springs_), ("hinge", hinges_)):
            for item in items:
                if any(v < 0 or not np.isfinite(v) for v in item[1:]):
                    raise ModelError(f"{kind} parameters must be finite and >= 0, got {item[1:]}")
        for _, k in hinges_:
            if k <= 0:
                raise ModelError(f"hinge rotational_stiffness must be > 0, got {k!r}")

        breaks = sorted(set(np.round(np.concatenate(
            [ends, [x for x, *_ in masses], [x for x, *_ in springs_], [x for x, _ in hinges_]]) / tol) * tol))
        breaks = np.array(breaks)
        nodes = [breaks[0]]
        elem_props = []
        for x0, x1 in zip(breaks[:-1], breaks[1:]):
            if x1 - x0 <= tol:
                continue
            mid = 0.5 * (x0 + x1)
            sec = sections[min(int(np.searchsorted(ends, mid) - 1), len(sections) - 1)]
            n = max(1, int(round(elements * (x1 - x0) / total)))
            for xi in np.linspace(x0, x1, n + 1)[1:]:
                nodes.append(xi)
                elem_props.append(sec)
        nodes = np.array(nodes)
        self.nodes = nodes

        def node_at(x):
            i = int(np.argmin(np.abs(nodes - x)))
            return i

        hinge_nodes = {node_at(x): k for x, k in hinges_}
        # DOF numbering: node i has w_i, theta_i (inboard side); hinge nodes get theta_out too
        dof_w, dof_t_in, dof_t_out = [], [], []
        names: list[str] = []
        count = 0
        for i in range(len(nodes)):
            dof_w.append(count)
            dof_t_in.append(count + 1)
            names += [f"w{i}", f"theta{i}"]
            count += 2
            if i in hinge_nodes:
                dof_t_out.append(count)
                names.append(f"theta{i}+")
                count += 1
            else:
                dof_t_out.append(count - 1)
        K = np.zeros((count, count))
        M = np.zeros((count, count))
        for e, sec in enumerate(elem_props):
            h = nodes[e + 1] - nodes[e]
            Ke, Me = _hermite_matrices(h, sec.bending_stiffness, sec.mass_per_length, sec.axial_force)
            idx = [dof_w[e], dof_t_out[e], dof_w[e + 1], dof_t_in[e + 1]]
            K[np.ix_(idx, idx)] += Ke
            M[np.ix_(idx, idx)] += Me
        for i, k in hinge_nodes.items():
            idx = [dof_t_in[i], dof_t_out[i]]
            K[np.ix_(idx, idx)] += k * np.array([[1, -1], [-1, 1]])
        for x, m, j in masses:
            i = node_at(x)
            M[dof_w[i], dof_w[i]] += m
            M[dof_t_out[i], dof_t_out[i]] += j
        for x, kt, kr in springs_:
            i = node_at(x)
            K[dof_w[i], dof_w[i]] += kt
            K[dof_t_out[i], dof_t_out[i]] += kr
        fixed = set()
        for cond, i in ((left, 0), (right, len(nodes) - 1)):
            for comp in _END_CONSTRAINTS[cond]:
                fixed.add(dof_w[i] if comp == "w" else (dof_t_out[i] if i == 0 else dof_t_in[i]))
        keep = [d for d in range(count) if d not in fixed]
        self._keep = np.array(keep)
        self._dof_w = dof_w
        self._dof_t_in, self._dof_t_out = dof_t_in, dof_t_out
        self.dof_names = tuple(names[d] for d in keep)
        self.K = K[np.ix_(keep, keep)]
        self.M = M[np.ix_(keep, keep)]
        self.length = total

    def eigen(self) -> tuple[np.ndarray, np.ndarray]:
        """All ``(ω^2, modes)`` of ``K v = ω^2 M v`` (ascending), modes mass-normalised."""
        return scipy.linalg.eigh(self.K, self.M)

    def frequencies(self, count: int | None = None, *, include_rigid: bool = True) -> np.ndarray:
        """Natural frequencies [rad/s] (ascending; tiny negative round-off clipped to 0)."""
        lam = scipy.linalg.eigh(self.K, self.M, eigvals_only=True)
        omega = np.sqrt(np.clip(lam, 0.0, None))
        if not include_rigid:
            omega = omega[lam > 1e-8 * np.max(np.abs(lam))]
        return omega if count is None else omega[:count]

    def _reduced_index(self, x: float, component: str) -> int:
        i = int(np.argmin(np.abs(self.nodes - x)))
        if abs(self.nodes[i] - x) > 1e-9 * self.length:
            raise ModelError(f"no node at x = {x!r}; put a breakpoint there (e.g. a zero point mass)")
        full = {"w": self._dof_w[i], "theta": self._dof_t_out[i]}.get(component)
        if full is None:
            raise ModelError(f"component must be 'w' or 'theta', got {component!r}")
        where = np.flatnonzero(self._keep == full)
        if where.size == 0:
            raise ModelError(f"{component} at x = {x!r} is constrained by the boundary")
        return int(where[0])

    def receptance(self, omega, *, force_at: float, response_at: float, load: str = "w",
                   response: str = "w", damping: np.ndarray | None = None) -> np.ndarray:
        """Harmonic response ``response(response_at) / load(force_at)`` [SI] over ``omega``.

        ``load`` is ``"w"`` (force [N] in +w) or ``"theta"`` (moment [N m] in +θ);
        ``damping`` an optional global damping matrix (reduced DOFs).
        """
        omega = np.atleast_1d(np.asarray(omega, dtype=float))
        i = self._reduced_index(force_at, load)
        j = self._reduced_index(response_at, response)
        f = np.zeros(self.K.shape[0])
        f[i] = 1.0
        C = np.zeros_like(self.K) if damping is None else np.asarray(damping, dtype=float)
        out = np.array([np.linalg.solve(self.K - w * w * self.M + 1j * w * C, f)[j] for w in omega])
        return out


# ======================================================================================
# 3. Kane-Ryan-Banerjee spin-up
def spinup_angle(t, *, final_rate: float = 6.0, ramp_time: float = 15.0
                 ) -> tuple[np.ndarray, np.ndarray, np.ndarray]:
    """Prescribed hub angle of FORMULAS §6.1 and its derivatives ``(θ, θ', θ'')``.

    ``θ = (Ω/T)[t^2/2 + (T/2π)^2 (cos(2πt/T) - 1)]`` for ``t <= T``, ``Ω (t - T/2)`` after.
    """
    W, T = final_rate, ramp_time
    w = 2 * np.pi / T
    if isinstance(t, (float, int, np.floating, np.integer)):     # one time (a driving law): its branch only
        t = float(t)
        one = ((W / T * (t * t / 2 + (np.cos(w * t) - 1) / w ** 2), W / T * (t - np.sin(w * t) / w),
                W / T * (1 - np.cos(w * t))) if t <= T else (W * (t - T / 2), W, 0.0))
        return tuple(np.asarray(value, dtype=float) for value in one)
    t = np.asarray(t, dtype=float)
    ramp = t <= T
    theta = np.where(ramp, W / T * (t * t / 2 + (np.cos(w * t) - 1) / w ** 2), W * (t - T / 2))
    rate = np.where(ramp, W / T * (t - np.sin(w * t) / w), W)
    accel = np.where(ramp, W / T * (1 - np.cos(w * t)), 0.0)
    return theta, rate, accel


@dataclass(frozen=True)
class SpinUpResult:
    """Result of :func:`kane_spinup`.

    Attributes
    ----------
    t : numpy.ndarray
        Times [s].
    tip_deflection : numpy.ndarray
        Tip deflection in the hub frame [m] (positive in the direction of rotation).
    modal_coordinates : numpy.ndarray
        ``q`` [m], shape ``(n_modes, len(t))``.
    hub_rate : numpy.ndarray
        Prescribed ``θ'(t)`` [rad/s].
    first_frequency : float
        First clamped-free frequency ``ω_1`` [rad/s] of the non-rotating beam.
    geometric_stiffening : bool
        Whether ``KG`` was included.
    matrices : dict
        ``M``, ``K``, ``KG``, ``p`` and the tip mode values ``phi_tip``.
    """

    t: np.ndarray
    tip_deflection: np.ndarray
    modal_coordinates: np.ndarray
    hub_rate: np.ndarray
    first_frequency: float
    geometric_stiffening: bool
    matrices: dict = field(repr=False)


def kane_spinup(*, length: float = 10.0, bending_stiffness: float = 1.4e4, mass_per_length: float = 1.2,
                final_rate: float = 6.0, ramp_time: float = 15.0, t_final: float = 20.0, n_modes: int = 4,
                geometric_stiffening: bool = True, t_eval=None, rtol: float = 1e-10,
                atol: float = 1e-12) -> SpinUpResult:
    """Assumed-modes reference of the Kane-Ryan-Banerjee spin-up beam (FORMULAS §6.1).

    Clamped-free modes ``φ_i`` of the non-rotating beam (exact, :func:`clamped_free_mode`),
    ``M q'' + (K + θ'^2 (KG - M)) q = -θ'' p`` integrated with DOP853 from rest.

    Parameters
    ----------
    length, bending_stiffness, mass_per_length : float
        ``L`` [m], ``EI`` [N m^2], ``ρA`` [kg/m] (defaults: Kane et al.).
    final_rate, ramp_time : float
        ``Ω_s`` [rad/s] and ``T_s`` [s] of the spin-up law (:func:`spinup_angle`).
    t_final : float
        End time [s].
    n_modes : int
        Number of assumed modes.
    geometric_stiffening : bool
        Include ``KG`` (True: bounded response; False: the conventional model diverges
        once ``θ' > ω_1``).
    t_eval : array, optional
        Output times (default 2001 points on [0, t_final]).
    rtol, atol : float
        Integrator tolerances.
    """
    for name, value in (("length", length), ("bending_stiffness", bending_stiffness),
                        ("mass_per_length", mass_per_length), ("ramp_time", ramp_time),
                        ("t_final", t_final)):
        if not (np.isfinite(value) and value > 0):
            raise ModelError(f"{name} must be > 0, got {value!r}")
    if isinstance(n_modes, bool) or not isinstance(n_modes, (int, np.integer)) or n_modes < 1:
        raise ModelError(f"n_modes must be an integer >= 1, got {n_modes!r}")
    L, EI, rhoA = length, bending_stiffness, mass_per_length
    betas = beta_roots("clamped-free", n_modes)
    omegas = omega_from_beta(betas, L, EI, rhoA)
    xg, wg = np.polynomial.legendre.leggauss(400)
    xi = (xg + 1) / 2
    wq = wg / 2 * L                                # weights for ∫ dx
    x = xi * L
    phi = np.array([clamped_free_mode(b, xi) for b in betas])
    dphi = np.array([clamped_free_mode(b, xi, 1) for b in betas]) / L
    M = rhoA * (phi * wq) @ phi.T
    K = np.diag(omegas ** 2) @ M
    K = (K + K.T) / 2
    KG = (rhoA * (L * L - x * x) / 2 * dphi * wq) @ dphi.T
    p = rhoA * (phi * wq) @ x
    phi_tip = np.array([clamped_free_mode(b, 1.0) for b in betas])
    Minv = np.linalg.inv(M)
    softening = (KG if geometric_stiffening else np.zeros_like(KG)) - M     # of the spin rate squared, once

    def rhs(t, y):
        _, rate, accel = spinup_angle(t, final_rate=final_rate, ramp_time=ramp_time)
        return np.concatenate([y[n_modes:], Minv @ (-(K + rate * rate * softening) @ y[:n_modes] - accel * p)])

    t_eval = np.asarray(np.linspace(0.0, t_final, 2001) if t_eval is None else t_eval, dtype=float)
    # integrate the ramp and the constant-rate phase separately (θ'' has a kink at T_s)
    pieces_t, pieces_y = [], []
    y0 = np.zeros(2 * n_modes)
    bounds = [0.0, min(ramp_time, t_final), t_final] if t_final > ramp_time else [0.0, t_final]
    for k, (t0, t1) in enumerate(zip(bounds[:-1], bounds[1:])):
        last = k == len(bounds) - 2
        mask = (t_eval >= t0) & ((t_eval <= t1) if last else (t_eval < t1))
        sol = scipy.integrate.solve_ivp(rhs, (t0, t1), y0, method="DOP853", rtol=rtol, atol=atol,
                                        t_eval=t_eval[mask], dense_output=True)
        if not sol.success:  # pragma: no cover - integrator failure is reported, not hidden
            raise RuntimeError(f"spin-up integration failed: {sol.message}")
        pieces_t.append(sol.t)
        pieces_y.append(sol.y)
        y0 = sol.sol(t1)
    t_out = np.concatenate(pieces_t)
    q = np.concatenate(pieces_y, axis=1)[:n_modes]
    _, rate, _ = spinup_angle(t_out, final_rate=final_rate, ramp_time=ramp_time)
    return SpinUpResult(t=t_out, tip_deflection=phi_tip @ q, modal_coordinates=q, hub_rate=rate,
                        first_frequency=float(omegas[0]), geometric_stiffening=geometric_stiffening,
                        matrices={"M": M, "K": K, "KG": KG, "p": p, "phi_tip": phi_tip})
