"""Mode shapes of the modal planar beam and their modal integrals.

The floating frame of a :class:`~ctmm.flexible.beam.ModalBeam` is the **root tangent frame**:
its origin is the inboard end ``I`` and its x axis the tangent of the beam axis at ``I``.  In
that frame the deformation vanishes with its slope at the root, so the shape functions must be
**clamped at x = 0**; the outboard end is free (end forces enter as generalised forces).  The
natural choice, used by default, are the clamped-free eigenfunctions of the uniform
Euler-Bernoulli beam (seed 003 section 6.4.1, seed 000 section 4.1):

``phi_i(x) = cosh(b_i x/L) - cos(b_i x/L) - s_i (sinh(b_i x/L) - sin(b_i x/L))``,
``s_i = (cosh b_i + cos b_i)/(sinh b_i + sin b_i)``, ``1 + cos b_i cosh b_i = 0``,

scaled so that ``int_0^L phi_i^2 dx = L`` (``|phi_i(L)| = 2``): the modal coordinate is a length
[m] and the modal mass is ``rhoA L``.  Axial shapes (optional): ``psi_k(x) = sqrt(2)
sin((2k - 1) pi x / (2 L))`` (clamped-free rod), same scaling.  Both sets are orthogonal in
mass and stiffness, so ``M`` and ``K`` are diagonal (checked at construction).

Shape sets that do not vanish with their slope at the root (pinned-free, free-free, ...) do
not describe deformation relative to the root tangent frame and are rejected with
:class:`~ctmm.errors.ModelError`.

The evaluation avoids overflow for large ``b`` (``cosh y - s sinh y = ((1 - s) e^y + (1 + s)
e^-y)/2`` with ``1 - s`` computed without cancellation).  This module shares no code with the
independent references (:mod:`ctmm.reference.beams`).
"""
from __future__ import annotations

import functools
import math
from dataclasses import dataclass, field
from typing import Callable, Sequence

import numpy as np

from ..errors import ModelError

SUPPORTED_BOUNDARY = "clamped-free"
"""The only boundary condition of the floating (root tangent) frame."""

KNOWN_SHAPE_SETS = ("clamped-free", "pinned-free", "free-free", "clamped-clamped",
                    "pinned-pinned", "custom")


def clamped_free_betas(count: int) -> np.ndarray:
    """First ``count`` roots of ``1 + cos b cosh b = 0`` (Newton from ``(2k - 1) pi / 2``).

    Written as ``cos b + sech b = 0`` (bounded); converges to round-off in a few steps.
    """
    roots = np.empty(count)
    for k in range(1, count + 1):
        b = (2 * k - 1) * math.pi / 2
        if k == 1:
            b = 1.875
        for _ in range(50):
            e = math.exp(-b)
            sech = 2 * e / (1 + e * e)
            f = math.cos(b) + sech
            df = -math.sin(b) - sech * math.tanh(b)
            step = f / df
            b -= step
            if abs(step) < 1e-15 * b:
                break
        roots[k - 1] = b
    return roots


def _clamped_free_shape(beta: float, xi: np.ndarray, derivative: int) -> np.ndarray:
    """``d^k phi / d xi^k`` on ``xi = x/L`` in [0, 1] (overflow-free)."""
    y = beta * xi
    eb = math.exp(-beta)
    # sinh b + sin b = (1 - e^-2b + 2 e^-b sin b) e^b / 2
    den = 1.0 - eb * eb + 2.0 * math.sin(beta) * eb
    # (1 - s) e^b = 2 (sin b - cos b - e^-b) / den
    one_minus_s_eb = 2.0 * (math.sin(beta) - math.cos(beta) - eb) / den
    s = 1.0 - one_minus_s_eb * eb
    grow = 0.5 * one_minus_s_eb * np.exp(y - beta)
    decay = 0.5 * (1.0 + s) * np.exp(-y)
    c, sn = np.cos(y), np.sin(y)
    hyper = grow + (decay if derivative % 2 == 0 else -decay)
    trig = (-c + s * sn, sn + s * c, c - s * sn, -sn - s * c)[derivative]
    return beta ** derivative * (hyper + trig)


@dataclass(frozen=True)
class _ClampedFreeShape:
    """One clamped-free eigenfunction ``f(xi, derivative)`` (:func:`_clamped_free_shape`) as an object of numbers: a
    model holding it is described exactly (:func:`ctmm.model_description.describe`; a lambda is not)."""

    beta: float

    def __call__(self, xi, derivative: int) -> np.ndarray:
        return _clamped_free_shape(self.beta, np.asarray(xi, float), derivative)


@dataclass(frozen=True)
class ModeSet:
    """Transverse shape functions of a beam in its floating frame.

    Parameters
    ----------
    name : str
        ``"clamped-free"`` (default set), another name of :data:`KNOWN_SHAPE_SETS` for
        information, or ``"custom"``.
    functions : sequence of callable, optional
        For custom sets: ``f(xi, derivative) -> array`` on ``xi = x/L`` in [0, 1],
        ``derivative`` 0..2 (derivatives with respect to ``xi``).
    boundary : str
        Boundary condition the shapes satisfy, e.g. ``"clamped-free"``.

    Use :meth:`clamped_free` for the default set.
    """

    name: str
    functions: tuple = field(default=(), repr=False)
    boundary: str = "clamped-free"
    betas: tuple = ()

    @classmethod
    def clamped_free(cls, count: int) -> "ModeSet":
        """The first ``count`` clamped-free eigenfunctions (``int_0^1 phi^2 d xi = 1``)."""
        betas = clamped_free_betas(count)
        funcs = tuple(_ClampedFreeShape(float(b)) for b in betas)
        return cls("clamped-free", funcs, "clamped-free", tuple(float(b) for b in betas))

    @classmethod
    def pinned_free(cls, count: int) -> "ModeSet":
        """Pinned-free eigenfunctions: the rigid rotation ``sqrt(3) xi`` and
        ``sin(b xi) + (sin b / sinh b) sinh(b xi)`` with ``tan b = tanh b``.

        **Not** admissible for the root tangent frame (``phi'(0) != 0``): a beam given this set
        raises :class:`ModelError`.  Provided for pinned-frame studies and to show the check.
        """
        funcs = [lambda xi, d: (math.sqrt(3.0) * np.asarray(xi, float) if d == 0 else
                                math.sqrt(3.0) * np.ones_like(np.asarray(xi, float)) if d == 1
                                else np.zeros_like(np.asarray(xi, float)))]
        for k in range(1, count):
            b = (4 * k + 1) * math.pi / 4
            for _ in range(50):
                f = math.sin(b) - math.cos(b) * math.tanh(b)
                df = math.cos(b) + math.sin(b) * math.tanh(b) - math.cos(b) / math.cosh(b) ** 2
                b -= f / df
            ratio = math.sin(b) / math.sinh(b)

            def shape(xi, d, b=b, ratio=ratio):
                y = b * np.asarray(xi, float)
                trig = (np.sin(y), np.cos(y), -np.sin(y))[d]
                hyp = (np.sinh(y), np.cosh(y), np.sinh(y))[d]
                return b ** d * (trig + ratio * hyp)
            funcs.append(shape)
        return cls("pinned-free", tuple(funcs[:count]), "pinned-free")

    @classmethod
    def custom(cls, functions: Sequence[Callable], *, boundary: str = "clamped-free"
               ) -> "ModeSet":
        """User shapes ``f(xi, derivative)``; checked against ``boundary`` by the beam."""
        functions = tuple(functions)
        if not functions or not all(callable(f) for f in functions):
            raise ModelError("custom mode set needs a non-empty sequence of callables "
                             "f(xi, derivative)")
        return cls("custom", functions, boundary)

    def __len__(self) -> int:
        return len(self.functions)

    def evaluate(self, xi, derivative: int = 0) -> np.ndarray:
        """All shapes at ``xi``: array ``(n_modes, len(xi))`` of ``d^k phi / d xi^k``."""
        xi = np.atleast_1d(np.asarray(xi, dtype=float))
        return np.array([np.broadcast_to(f(xi, derivative), xi.shape) for f in self.functions],
                        dtype=float)


def check_root_clamped(mode_set: ModeSet, owner: str) -> None:
    """Raise :class:`ModelError` unless every shape has ``phi(0) = phi'(0) = 0`` and is finite."""
    if mode_set.boundary != SUPPORTED_BOUNDARY:
        raise ModelError(
            f"{owner}: mode set {mode_set.name!r} has boundary {mode_set.boundary!r}; the modal "
            f"beam's floating frame is the root tangent frame (clamped at the inboard end, free "
            f"outboard), so the shapes must be {SUPPORTED_BOUNDARY!r} (phi(0) = phi'(0) = 0)")
    xi = np.array([0.0])
    values = mode_set.evaluate(xi, 0)[:, 0]
    slopes = mode_set.evaluate(xi, 1)[:, 0]
    probe = mode_set.evaluate(np.linspace(0.0, 1.0, 11), 0)
    scale = max(1.0, float(np.max(np.abs(probe))))
    bad = [i + 1 for i in range(len(mode_set))
           if abs(values[i]) > 1e-9 * scale or abs(slopes[i]) > 1e-9 * scale]
    if bad or not np.all(np.isfinite(probe)):
        raise ModelError(
            f"{owner}: mode set {mode_set.name!r} does not match the clamped root of the floating "
            f"frame: shapes {bad} have phi(0) = {values.tolist()} / phi'(0) = {slopes.tolist()} "
            f"(must be 0); use ModeSet.clamped_free(n)")


@functools.lru_cache(maxsize=16)
def _legendre_rule(count: int) -> tuple[np.ndarray, np.ndarray]:
    """numpy's ``leggauss(count)`` on [-1, 1], read-only: a table of constants computed once per count (an
    eigenproblem of size ``count``: ~20 ms at the beams' default 160 points, paid by every beam and every station
    before); never returned to a caller, so nothing outside can change it."""
    x, w = np.polynomial.legendre.leggauss(count)
    x.flags.writeable = w.flags.writeable = False
    return x, w


def gauss_points(count: int, length: float) -> tuple[np.ndarray, np.ndarray]:
    """Gauss-Legendre abscissae on ``[0, length]`` [m] and weights [m] (new arrays, numpy's ``leggauss`` rule)."""
    x, w = _legendre_rule(count)
    return (x + 1.0) * 0.5 * length, w * 0.5 * length


MAXIMUM_QUADRATURE = 4000
"""Most Gauss-Legendre points of a beam's modal integrals (:func:`check_quadrature`): 1996 modes."""


def check_quadrature(owner: str, n_modes: int, n_axial_modes: int, quadrature: int) -> None:
    """Raise :class:`ModelError` unless ``2 max(n_modes, n_axial_modes) + 8 <= quadrature <=`` :data:`MAXIMUM_QUADRATURE`
    Gauss points.

    The k-th shape has about k half-waves: with fewer points the modal integrals are wrong without
    any error (100 clamped-free modes on 160 points give a modal mass matrix 4 % off the identity).
    """
    needed = 2 * max(n_modes, n_axial_modes) + 8
    if quadrature > MAXIMUM_QUADRATURE:
        raise ModelError(f"{owner}: quadrature={quadrature} Gauss points; at most {MAXIMUM_QUADRATURE} are taken "
                         f"(numpy's Gauss-Legendre rule is an eigenproblem of that size: its memory grows with the square), "
                         f"enough for {(MAXIMUM_QUADRATURE - 8) // 2} modes")
    if quadrature < needed:
        raise ModelError(f"{owner}: quadrature={quadrature} Gauss points cannot integrate n_modes={n_modes} "
                         f"(n_axial_modes={n_axial_modes}) accurately; use quadrature >= {needed} (2 points per "
                         "mode + 8) or fewer modes")


__all__ = ["MAXIMUM_QUADRATURE", "ModeSet", "clamped_free_betas", "check_root_clamped", "check_quadrature", "gauss_points",
           "SUPPORTED_BOUNDARY"]
