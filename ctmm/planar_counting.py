"""Wittrick-Williams counting of planar models (rigid and flexible) on the one sweep's frequency context.

About a static operating point ``q0`` the undamped linearisation is ``(K - omega^2 M) x = 0``.  The
frequency context of the one articulated sweep (:meth:`ctmm.planar.body_forms.PlanarScene.frequency`)
at ``s = i omega`` is a block ``L D L^T`` factorisation of ``K - omega^2 M`` in the joint and modal
coordinates: for each body, tip to base, its modal block ``C_j = K_ee - omega^2 M_ee`` (children
folded in) and then its joint pivot ``D_j = S^T Phi_j S + k_j`` are eliminated.  By Sylvester's law of
inertia the number of natural frequencies strictly below ``omega`` is the number of negative
eigenvalues of all these pivots (Wittrick-Williams; the clamped-interface count ``J0`` of a modal body
is the negative eigenvalues of its ``C_j``, the rigid-body modes of a floating base the negative
eigenvalues of its ``3 x 3`` pivot at ``omega > 0``).

A pivot that is exactly zero (``omega`` a natural frequency of the substructure outboard of a joint,
or of a beam clamped at its inboard joint) spoils the elimination; such trial frequencies are
recounted beside ``omega`` and certified by :func:`ctmm.counting.certified_count`, with the sign of the
pole-free product of the pivots as its side test.  Natural frequencies follow by bisection on the
count (:mod:`ctmm.roots1d`), exact to round-off.

Valid for symmetric linearisations only: models with damping (hinge dampers, damped beams) are
refused here; loops and circulatory forces are refused by the callers
(:mod:`ctmm.planar_frequency`).
"""
from __future__ import annotations

from typing import Any

import numpy as np

from . import validation
from .counting import PIVOT_TOLERANCE, certified_count
from .errors import ModelError
from .roots1d import bisect_count, count_upper_bound

__all__ = ["FrequencyCounter", "eigenvalue_count", "natural_frequencies"]

#: Largest ``|C0|`` (damping matrices of the linearised bodies) counted as undamped, relative to
#: ``sqrt(|K0| |M0|)`` [-].
UNDAMPED_TOLERANCE = 1e-8


class FrequencyCounter:
    """Counts of the undamped natural frequencies of a planar model about a static operating point.

    Parameters
    ----------
    model : PlanarModel
        Rigid bodies and modal beams, no hinges with translational springs.
    q0 : array_like (n_coordinates,)
        A static equilibrium (else :class:`ModelError`).
    t : float
        Time of the operating point [s].
    verb : str
        The verb named in refusals.

    Raises
    ------
    ModelError
        ``q0`` not an equilibrium; a damped model (hinge or beam damping).
    """

    def __init__(self, model: Any, q0: Any, t: float = 0.0, *, verb: str = "natural_frequencies") -> None:
        from .planar.body_forms import PlanarScene

        self.model = model
        self.q0 = np.asarray(q0, dtype=float)
        self.terms = PlanarScene(model).linear_terms(q0, t)
        for name, damping in zip(model.joint_names, model.damping):
            if damping:
                raise ModelError(f"{verb} needs an undamped system, but {name!r} has damping={float(damping)!r}")
        for j, (M0, C0, K0, _, _) in enumerate(self.terms.bodies):
            size = np.sqrt(max(float(np.max(np.abs(K0))) * float(np.max(np.abs(M0))), 1e-300))
            if np.max(np.abs(C0)) > UNDAMPED_TOLERANCE * size:
                raise ModelError(f"{verb} needs an undamped system, but body {model.body_names[j]!r} of "
                                 f"{model.name!r} has velocity-dependent forces at the operating point (largest "
                                 f"|C0| = {np.max(np.abs(C0)):.3e}: a damped beam)")

    def _sweep(self, squared: np.ndarray) -> tuple[list, list, list]:
        """Joint pivots ``D_j``, modal blocks ``C_j`` and inertias ``Phi_j`` (batched, ``None`` where
        absent) at ``omega^2 = squared`` (B,) [rad^2/s^2] (``s = sqrt(-omega^2)``; ``omega^2 < 0`` counts
        negative stiffness).  An exactly singular multi-dimensional pivot (``LinAlgError``) gives ``nan``
        at that frequency (the count's margin is then ``nan`` and it is recounted beside it)."""
        s = np.sqrt(-squared.astype(complex))
        try:
            with np.errstate(all="ignore"):
                result = self.terms.sweep(s)
            return result.pivot, result.modal, result.inertia
        except np.linalg.LinAlgError:
            pass
        nb = len(self.terms.bodies)
        parts = [[], [], []]
        for value in s:
            try:
                with np.errstate(all="ignore"):
                    result = self.terms.sweep(np.array([value]))
                found = (result.pivot, result.modal, result.inertia)
            except np.linalg.LinAlgError:
                found = None
            for k in range(3):
                parts[k].append(found[k] if found is not None else None)
        out = []
        for k, shape in enumerate((self._pivot_shape, self._modal_shape, lambda j: (3, 3))):
            stacked = []
            for j in range(nb):
                size = shape(j)
                if size is None:
                    stacked.append(None)
                    continue
                rows = [np.full((1,) + size, np.nan, dtype=complex) if p is None else p[j] for p in parts[k]]
                stacked.append(np.concatenate(rows, axis=0))
            out.append(stacked)
        return out[0], out[1], out[2]

    def _pivot_shape(self, j: int) -> tuple[int, int] | None:
        joint = self.terms.joints[j]
        return None if joint.prescribed is not None or joint.free == 0 else (joint.free, joint.free)

    def _modal_shape(self, j: int) -> tuple[int, int] | None:
        size = self.terms.bodies[j][0].shape[0] - 3
        return (size, size) if size > 0 else None

    def _pivots(self, squared: np.ndarray) -> list[tuple[np.ndarray, np.ndarray, bool]]:
        """``(pivot, scale, eliminated)`` for every joint and modal pivot at ``omega^2 = squared`` (B,):
        symmetric real parts ``(B, k, k)``, the size of the terms each is the sum of ``(B,)``, and
        whether it is eliminated into a parent (a zero pivot at the ground is a natural frequency of
        the whole model and cannot spoil the count)."""
        pivots, modal, inertias = self._sweep(squared)
        out = []
        for j, ((M0, _, K0, _, _), D, C) in enumerate(zip(self.terms.bodies, pivots, modal)):
            if C is not None:
                n = C.shape[-1]
                own = np.abs(K0[3:, 3:]).max() + np.abs(squared) * np.abs(M0[3:, 3:]).max()
                out.append((_symmetric(C, n), np.maximum(own, np.abs(C).max(axis=(-2, -1))), True))
            if D is not None:
                S = self.terms.joints[j].S
                inertia = np.swapaxes(S, -1, -2) @ inertias[j] @ S
                scale = np.abs(inertia).max(axis=(-2, -1)) + np.abs(D - inertia).max(axis=(-2, -1))
                out.append((_symmetric(D, D.shape[-1]), scale, self.terms.tree.parent[j] >= 0))
        return out

    def negative_count(self) -> int:
        """Number of modes with ``omega^2 < 0`` (negative stiffness: an unstable operating point): the
        count below ``omega^2 = -1e-10 omega_ref^2`` (``omega_ref^2``: largest stiffness over largest
        inertia of the bodies and hinges), so rigid-body modes (``omega^2 = 0``) are not counted."""
        stiffness = max([float(np.max(np.abs(K0))) for _, _, K0, _, _ in self.terms.bodies]
                        + [float(np.max(np.abs(self.model.stiffness), initial=0.0))])
        inertia = max(float(np.max(np.abs(M0))) for M0, _, _, _, _ in self.terms.bodies)
        reference = max(stiffness / inertia, 1e-300)
        return int(self._raw(np.array([-1e-10 * reference]))[0][0])

    def raw(self, omega: np.ndarray) -> tuple[np.ndarray, np.ndarray]:
        """Sylvester count and smallest relative pivot (``nan`` if non-finite) at ``omega`` (B,) [rad/s]."""
        omega = np.asarray(omega, dtype=float)
        return self._raw(omega * omega)

    def _raw(self, squared: np.ndarray) -> tuple[np.ndarray, np.ndarray]:
        count = np.zeros(squared.shape, dtype=np.int64)
        margin = np.full(squared.shape, np.inf)
        for pivot, scale, eliminated in self._pivots(squared):
            bad = ~np.all(np.isfinite(pivot), axis=(-2, -1))
            safe = np.where(bad[:, None, None], 0.0, pivot)
            values = safe[:, 0, 0][:, None] if safe.shape[-1] == 1 else np.linalg.eigvalsh(safe)
            count = count + np.sum(values < 0.0, axis=-1)
            if eliminated:
                scale = np.where(np.isfinite(scale) & (scale > 0), scale, 1.0)
                margin = np.minimum(margin, np.min(np.abs(values), axis=-1) / scale)
            margin = np.where(bad, np.nan, margin)
        return count, margin

    def determinant_sign(self, omega: np.ndarray) -> np.ndarray:
        """Sign of ``det(K - omega^2 M)`` up to a fixed factor: the product of all pivot determinants
        (no poles: near a substructure resonance a tiny pivot times the huge next one stays exact)."""
        sign = np.ones(np.shape(omega))
        for pivot, _, _ in self._pivots(np.asarray(omega, dtype=float) ** 2):
            with np.errstate(all="ignore"):
                sign = sign * np.sign(np.linalg.det(np.where(np.isfinite(pivot), pivot, 0.0)))
        return sign

    def count(self, omega: Any) -> np.ndarray:
        """Number of natural frequencies strictly below each ``omega`` [rad/s] (>= 0), certified at
        substructure resonances (:func:`ctmm.counting.certified_count`)."""
        omega = np.atleast_1d(validation.finite_array("omega", omega)).reshape(-1)
        if np.any(omega < 0):
            raise ModelError(f"omega must be >= 0 rad/s, got {omega[omega < 0][0]!r}")
        return certified_count(self.raw, omega, tolerance=PIVOT_TOLERANCE, side=self._root_below)

    def _root_below(self, lower: np.ndarray, omega: np.ndarray) -> np.ndarray:
        """True where the single natural frequency in ``(lower, ~omega)`` lies below ``omega``: the
        determinant changes sign between ``lower`` and ``omega (1 - 1e-12)``."""
        return self.determinant_sign(lower) != self.determinant_sign(omega * (1.0 - 1e-12))

    def frequencies(self, *, n_modes: int | None = None, omega_max: float | None = None,
                    rtol: float = 1e-15) -> np.ndarray:
        """The lowest ``n_modes`` natural frequencies, or all below ``omega_max`` [rad/s], ascending,
        rigid-body modes as 0, by bisection on :meth:`count`.

        Raises
        ------
        ModelError
            Not exactly one of ``n_modes`` / ``omega_max``; fewer natural frequencies than asked for;
            a statically unstable operating point (``omega^2 < 0``).
        """
        model = self.model
        if (n_modes is None) == (omega_max is None):
            raise ModelError("give exactly one of n_modes (int >= 1) or omega_max (rad/s > 0)")
        n_negative = self.negative_count()
        if n_negative > 0:
            raise ModelError(f"model {model.name!r} is statically unstable about q = "
                             f"{self.q0.tolist()}: {n_negative} mode(s) with negative stiffness "
                             "(omega^2 < 0, e.g. a link held against gravity); natural frequencies exist only "
                             "about a stable equilibrium")
        if omega_max is not None:
            n_modes = int(self.count([validation.positive("omega_max", omega_max)])[0])
            if n_modes == 0:
                return np.zeros(0)
            hi = float(omega_max)
        else:
            n_modes = validation.integer("n_modes", n_modes, minimum=1)
            if n_modes > model.n_coordinates:
                raise ModelError(f"model {model.name!r} has {model.n_coordinates} natural frequencies (one per "
                                 f"coordinate), n_modes={n_modes} requested")
            hi = count_upper_bound(self.count, n_modes, limit=1e12, what=f"model {model.name!r}")
        k = np.arange(1, n_modes + 1)
        lo, up = np.zeros(n_modes), np.full(n_modes, hi)
        n_rigid = int(self.count([hi * 1e-13])[0])
        counts = np.zeros(n_modes, dtype=np.int64)
        bisect_count(self.count, k, lo, up, counts, counts.copy(), rtol, max_iterations=200)
        out = 0.5 * (lo + up)
        out[k <= n_rigid] = 0.0
        return out


def _symmetric(block: np.ndarray, n: int) -> np.ndarray:
    """Real symmetric part of a batch of ``(n, n)`` pivots."""
    block = np.asarray(block).reshape(-1, n, n)
    return 0.5 * (block + np.swapaxes(block, -1, -2)).real


def eigenvalue_count(model: Any, q0: Any, omega: Any, *, t: float = 0.0) -> np.ndarray:
    """Number of undamped natural frequencies of ``model`` about ``q0`` strictly below each ``omega``
    [rad/s] (:class:`FrequencyCounter`)."""
    return FrequencyCounter(model, q0, t, verb="eigenvalue_count").count(omega)


def natural_frequencies(model: Any, q0: Any, *, n_modes: int | None = None, omega_max: float | None = None,
                        t: float = 0.0, rtol: float = 1e-15) -> np.ndarray:
    """Lowest ``n_modes`` undamped natural frequencies (or all below ``omega_max``) [rad/s] of ``model``
    about ``q0``, rigid-body modes as 0 (:class:`FrequencyCounter`)."""
    return FrequencyCounter(model, q0, t).frequencies(n_modes=n_modes, omega_max=omega_max, rtol=rtol)
