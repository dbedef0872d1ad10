"""Stability charts over two loop parameters: D-subdivision curves and root counts.

``stability_chart(system, x=("gain", grid), y=("delay", grid), loop="pd")`` computes, from the
transfer-matrix characteristic function of the closed loop,

* the **D-subdivision curves**: parameter pairs for which a root lies on the imaginary axis,
  traced from ``Delta(i Omega; p) = 0`` for each crossing frequency ``Omega`` in closed form
  (the loop enters ``Delta`` affinely, see :mod:`ctmm.stability`), plus the static curve of the
  root ``s = 0``;
* the **number of unstable roots** at every grid point: along each grid row the crossings of
  the linear parameter are located exactly and one point of every interval between them is
  counted by the argument principle (:func:`ctmm.stability.unstable_root_count`); the count is
  constant between crossings.  ``verify=True`` counts every grid point directly as well;
* optionally the **spectral abscissa** bracketed by levels ``sigma_l`` (roots right of each
  level counted the same way).

Parameters of a loop are named ``"gain"`` (the gain factor ``k``), ``"delay"`` and the loop's
sensor signal names (their weights: ``"m.x"`` is ``k_p`` and ``"m.v"`` is ``k_d`` of a PD
loop ``Feedback("pd", [("m.x", kp), ("m.v", kd)], "m", gain=1.0)``).  A chart can also be
made from a function ``make_system(x, y) -> ControlledChain``; when all its systems share one
plant and differ only in one loop's parameters, the same batched evaluation is used (grid
boundaries then come from the counts), otherwise every point is counted separately (slow;
pass an ``executor``).
"""
from __future__ import annotations

import math
import time
from dataclasses import dataclass, field
from typing import Any, Callable, Sequence

import numpy as np

from . import validation
from .control.loops import ControlledChain
from .certification import ContourCertificate
from .errors import ModelError, unknown_name
from .parameter_crossings import row_crossings
from .root_counts import unstable_root_count
from .counting_contour import build_contour, count
from .state_space_characteristic import is_loop_system, loop_characteristic
from .sweeps import (LoopCharacteristic, as_controlled, find_loop, loop_weight_bound, managed_executor,
                     parallel_map)

__all__ = ["Boundary", "StabilityChart", "stability_chart"]


@dataclass(frozen=True)
class Boundary:
    """One D-subdivision curve in chart coordinates.

    Attributes
    ----------
    x, y : numpy.ndarray
        Curve points (NaN breaks the line where it leaves the chart or does not exist).
    omega : numpy.ndarray
        Crossing frequency [rad/s] of each point (0 on the static curve).
    kind : str
        ``"oscillatory"`` (a conjugate pair on the imaginary axis), ``"static"`` (root ``s = 0``)
        or ``"grid"`` (interpolated from counts on the grid, for charts of general functions).
    """

    x: np.ndarray
    y: np.ndarray
    omega: np.ndarray
    kind: str


@dataclass
class StabilityChart:
    """Stability chart over two parameters.

    Attributes
    ----------
    x_name, y_name : str
        Parameter names; ``x_label``, ``y_label`` axis labels.
    x, y : numpy.ndarray
        Grids; arrays below have shape ``(y.size, x.size)``.
    unstable_roots : numpy.ndarray of int
        Number of roots with ``Re s > 0`` (with multiplicity); -1 on a boundary (a root on
        the imaginary axis at that grid point).
    boundaries : tuple of Boundary
        D-subdivision curves.
    crossings : dict
        Boundary points on the grid rows: ``"row"``, ``"value"`` (of the row's linear parameter
        ``crossing_parameter``), ``"omega"``, ``"error"``, ``"static"``.
    abscissa : numpy.ndarray or None
        Spectral abscissa bracketed by ``abscissa_levels`` [1/s]: the midpoint of the bracket,
        ``levels[0]`` when below the lowest level, ``levels[-1]`` when above the highest.
    im_max : float
        Imaginary extent of the counting contour [rad/s].
    method : str
        How the grid was classified.
    wall_time_s : float
        Wall-clock time of :func:`stability_chart` [s].
    n_evaluations : int
        Laplace variables ``s`` at which the transfer-matrix model was evaluated.
    verified : bool or None
        With ``verify=True``: every grid point counted directly agrees.
    notes : list of str
        Diagnostics.
    certificate : ContourCertificate or None
        Region counted and whether no root outside it can exist, for the whole parameter box
        (:mod:`ctmm.certification`); per-point charts of a function: the least certain point.
    """

    x_name: str
    y_name: str
    x: np.ndarray
    y: np.ndarray
    unstable_roots: np.ndarray
    boundaries: tuple[Boundary, ...]
    crossings: dict
    crossing_parameter: str | None
    x_label: str
    y_label: str
    system_name: str
    loop: str | None
    im_max: float
    method: str
    wall_time_s: float
    n_evaluations: int
    abscissa: np.ndarray | None = None
    abscissa_levels: np.ndarray | None = None
    verified: bool | None = None
    notes: list = field(default_factory=list)
    certificate: ContourCertificate | None = None

    @property
    def stable(self) -> np.ndarray:
        """Boolean map: no root in the closed right half plane."""
        return self.unstable_roots == 0

    @property
    def stable_fraction(self) -> float:
        """Fraction of grid points that are stable."""
        return float(np.mean(self.stable))

    def plot(self, ax=None, *, abscissa: bool = False, counts: bool = True):
        """Stability chart: shaded stable region, D-curves, optional spectral abscissa map.

        Parameters
        ----------
        ax : matplotlib axes, optional
        abscissa : bool
            Colour map of the spectral abscissa (needs ``abscissa_levels`` in
            :func:`stability_chart`) with its zero contour.
        counts : bool
            Write the number of unstable roots in each region.

        Returns
        -------
        matplotlib axes
        """
        import matplotlib.pyplot as plt

        if ax is None:
            _, ax = plt.subplots(figsize=(6.4, 4.8))
        X, Y = np.meshgrid(self.x, self.y)
        if abscissa:
            if self.abscissa is None:
                raise ModelError("this chart has no spectral abscissa; compute it with "
                                 "stability_chart(..., abscissa_levels=np.linspace(-1, 0.5, 31))")
            limit = float(np.nanmax(np.abs(self.abscissa))) or 1.0
            mesh = ax.pcolormesh(X, Y, self.abscissa, cmap="RdBu_r", vmin=-limit, vmax=limit,
                                 shading="nearest")
            ax.figure.colorbar(mesh, ax=ax, label="spectral abscissa [1/s]")
            ax.contour(X, Y, self.abscissa, levels=[0.0], colors="k", linewidths=0.8)
        else:
            from matplotlib.colors import ListedColormap

            shade = np.where(self.stable, 1.0, np.nan)
            ax.pcolormesh(X, Y, shade, cmap=ListedColormap(["0.78"]), shading="nearest",
                          rasterized=True)
        for b in self.boundaries:
            style = {"oscillatory": dict(color="k", lw=1.0), "static": dict(color="k", lw=1.0, ls="--"),
                     "grid": dict(color="k", lw=1.0)}[b.kind]
            ax.plot(b.x, b.y, **style)
        if counts and not abscissa:
            self._annotate_counts(ax)
        ax.set_xlim(self.x.min(), self.x.max())
        ax.set_ylim(self.y.min(), self.y.max())
        ax.set_xlabel(self.x_label)
        ax.set_ylabel(self.y_label)
        ax.set_title(f"{self.system_name}: stable region shaded" if not abscissa
                     else f"{self.system_name}: spectral abscissa", fontsize=10)
        return ax

    def _annotate_counts(self, ax) -> None:
        from scipy import ndimage

        field_ = self.unstable_roots
        for value in np.unique(field_[field_ >= 0]):
            labels, n = ndimage.label(field_ == value)
            for region in range(1, n + 1):
                iy, ix = np.nonzero(labels == region)
                if iy.size < max(4, field_.size // 400):
                    continue
                k = np.argmin((iy - iy.mean()) ** 2 + (ix - ix.mean()) ** 2)
                ax.text(self.x[ix[k]], self.y[iy[k]], str(int(value)), ha="center", va="center",
                        fontsize=8, color="0.25")

    def summary(self) -> dict:
        """JSON-friendly summary (no large arrays)."""
        values, counts = np.unique(self.unstable_roots, return_counts=True)
        return {
            "system": self.system_name, "loop": self.loop, "method": self.method,
            "x": {"name": self.x_name, "min": float(self.x.min()), "max": float(self.x.max()),
                  "points": int(self.x.size)},
            "y": {"name": self.y_name, "min": float(self.y.min()), "max": float(self.y.max()),
                  "points": int(self.y.size)},
            "stable_fraction": self.stable_fraction,
            "unstable_root_histogram": {str(int(v)): int(c) for v, c in zip(values, counts)},
            "n_boundary_curves": len(self.boundaries),
            "n_row_crossings": int(len(self.crossings.get("value", ()))),
            "max_crossing_error": float(np.max(self.crossings["error"])) if len(self.crossings.get("error", ())) else 0.0,
            "im_max": self.im_max, "wall_time_s": self.wall_time_s,
            "n_evaluations": self.n_evaluations, "verified": self.verified, "notes": list(self.notes),
            "certificate": None if self.certificate is None else self.certificate.as_dict(),
        }


# --------------------------------------------------------------------------------------------
# axes
# --------------------------------------------------------------------------------------------
def _axis(label: str, spec: Any) -> tuple[str, np.ndarray, str]:
    if not isinstance(spec, (tuple, list)) or len(spec) not in (2, 3) or not isinstance(spec[0], str):
        raise ModelError(f"{label} must be (name, values) or (name, values, label), got {spec!r}")
    name, values = spec[0], spec[1]
    try:
        grid = np.asarray(values, dtype=float)
    except (TypeError, ValueError):
        raise ModelError(f"{label} grid {name!r} must be an array of real numbers, got {values!r}") from None
    if grid.ndim != 1 or grid.size < 2:
        raise ModelError(f"{label} grid {name!r} must be 1-D with at least 2 values, got shape {grid.shape}")
    bad = np.flatnonzero(~np.isfinite(grid))
    if bad.size:
        raise ModelError(f"{label} grid {name!r} must be finite, got {float(grid[bad[0]])!r} at index {bad[0]}")
    if len(np.unique(grid)) != grid.size:
        raise ModelError(f"{label} grid {name!r} has repeated values")
    text = spec[2] if len(spec) == 3 else name
    if not isinstance(text, str):
        raise ModelError(f"{label} label must be a string, got {text!r}")
    return name, grid, text


# --------------------------------------------------------------------------------------------
# the chart
# --------------------------------------------------------------------------------------------
def stability_chart(system: ControlledChain | Callable[[float, float], Any], x: Any, y: Any, *,
                    loop: str | None = None, im_max: float | None = None,
                    abscissa_levels: Any = None, verify: bool = False, executor: Any = None,
                    progress: bool | None = None) -> StabilityChart:
    """Stability chart of a controlled chain or linear(ised) model over two parameters.

    Parameters
    ----------
    system : ControlledChain, LinearizedSystem, ControlledModel or callable
        The closed loop (parameters of ``loop`` vary; a ``ctmm.linearize`` result or a planar
        ``ControlledModel`` too), or ``make_system(x, y)`` returning a ControlledChain per point.
    x, y : (str, array_like) or (str, array_like, str)
        Parameter name, grid values and optional axis label.  For a ControlledChain the names
        are ``"gain"``, ``"delay"`` [s] (>= 0) or a sensor signal of the loop (its weight).
    loop : str, optional
        The loop whose parameters vary (default: the only loop).
    im_max : float, optional
        Imaginary extent of the counting contour [rad/s]; default chosen from the decay of the
        loop term (required for the per-point fallback of general functions).
    abscissa_levels : array_like, optional
        Levels ``sigma`` [1/s] at which roots right of ``Re s = sigma`` are counted at every grid
        point, giving the spectral abscissa to within the level spacing.
    verify : bool
        Also count every grid point directly and record agreement in ``verified``.
    executor : concurrent.futures.Executor or {"threads", "processes"}, optional
        Runs the transfer-matrix evaluations (or the per-point fallback) in parallel; a
        ``distributed.Client.get_executor()`` works too.
    progress : bool, optional
        Progress bar (default: on terminals, for long per-point sweeps).

    Returns
    -------
    StabilityChart

    Examples
    --------
    >>> import numpy as np, ctmm
    >>> from ctmm.elements import Free, Mass
    >>> from ctmm.control import ControlledChain, Feedback
    >>> plant = ctmm.Chain("mass", [Free("a"), Mass("m", 1.0), Free("b")])
    >>> pd = Feedback("pd", [("m.x", 1.0), ("m.v", 1.0)], "m", gain=1.0, delay=0.2)
    >>> chart = stability_chart(ControlledChain(plant, [pd]), x=("m.x", np.linspace(-0.5, 2, 26)),
    ...                         y=("m.v", np.linspace(-0.5, 2, 26)))
    >>> bool(chart.stable[20, 10]), bool(chart.stable[2, 2])      # kp=0.5, kd=1.5; kp=kd=-0.3
    (True, False)
    """
    started = time.perf_counter()
    x_name, x_grid, x_label = _axis("x", x)
    y_name, y_grid, y_label = _axis("y", y)
    if x_name == y_name:
        raise ModelError(f"x and y must be different parameters, both are {x_name!r}")
    levels = None
    if abscissa_levels is not None:
        levels = np.sort(validation.finite_array("abscissa_levels", abscissa_levels, ndim=1))
        if levels.size < 2:
            raise ModelError("abscissa_levels needs at least 2 levels")
    if not isinstance(verify, bool):
        raise ModelError(f"verify must be True or False, got {verify!r}")
    with managed_executor(executor) as pool:
        if is_loop_system(system):
            chart = _loop_chart(system, loop, (x_name, x_grid, x_label), (y_name, y_grid, y_label),
                                im_max, levels, verify, pool, progress)
        elif callable(system):
            chart = _function_chart(system, loop, (x_name, x_grid, x_label), (y_name, y_grid, y_label),
                                    im_max, levels, pool, progress)
        else:
            loop_characteristic(system, loop, "a stability chart")    # raises: no model with a loop
    chart.wall_time_s = time.perf_counter() - started
    return chart


def _sets_for(model: LoopCharacteristic, assignments: dict[str, np.ndarray], n: int):
    """Parameter arrays (gain, delay, weights) of n sets from named values (others current)."""
    k, tau, w = model.parameters(n)
    k, tau, w = k.copy(), tau.copy(), w.copy()
    for name, values in assignments.items():
        values = np.broadcast_to(np.asarray(values, float), (n,))
        if name == "gain":
            k = values.copy()
        elif name == "delay":
            tau = values.copy()
        else:
            w[:, model.term_names.index(name)] = values
    return k, tau, w


def _check_names(model: LoopCharacteristic, names: Sequence[str], grids: Sequence[np.ndarray]) -> None:
    for name, grid in zip(names, grids):
        if name not in model.parameter_names:
            raise unknown_name(f"parameter of loop {model.loop.name!r}", name, list(model.parameter_names))
        if name == "delay" and np.any(grid < 0):
            raise ModelError(f"delays must be >= 0 [s], got {grid[grid < 0][0]!r} in the delay grid")
    if model.loop.is_lti and "gain" in names:
        pass  # gain is then a factor multiplying C(s)


def _loop_chart(system, loop, xs, ys, im_max, levels, verify, pool, progress) -> StabilityChart:
    model = loop_characteristic(system, loop)
    model.executor = pool
    (x_name, x_grid, x_label), (y_name, y_grid, y_label) = xs, ys
    _check_names(model, (x_name, y_name), (x_grid, y_grid))
    notes: list[str] = []
    if model.delay == 0.0 and "delay" not in (x_name, y_name):
        notes.append("the loop has no delay: this is the delay-free chart")
    linear_x = x_name != "delay"
    p_name, p_grid, q_name, q_grid = (x_name, x_grid, y_name, y_grid) if linear_x else \
        (y_name, y_grid, x_name, x_grid)
    nq, npp = q_grid.size, p_grid.size
    # the parameter box (for the contour radius) and the largest delay (for the sampling)
    P, Q = np.meshgrid(p_grid, q_grid)
    k_all, tau_all, w_all = _sets_for(model, {p_name: P.ravel(), q_name: Q.ravel()}, P.size)
    tau_max = float(tau_all.max())   # largest delay of the chart [s]
    contour = build_contour(model, loop_weight_bound(k_all, w_all), tau_max, im_max=im_max)
    notes += contour.notes
    _resolve_curves(model, contour, p_name, q_name, p_grid, q_grid, tau_max)
    sets0 = _sets_for(model, {p_name: 0.0, q_name: q_grid}, nq)
    sets1 = _sets_for(model, {p_name: 1.0, q_name: q_grid}, nq)
    p_range = (float(p_grid.min()), float(p_grid.max()))
    crossings = row_crossings(contour, sets0, sets1, p_range, grid=p_grid)
    counts = _classify_rows(model, contour, crossings, p_name, p_grid, q_name, q_grid, notes)
    verified = None
    if verify:
        direct, _ = count(contour, k_all, tau_all, w_all)
        direct = direct.reshape(nq, npp)
        mismatch = int(np.sum((direct != counts) & (counts >= 0)))    # -1: on a boundary
        verified = mismatch == 0
        if mismatch:
            notes.append(f"verify: {mismatch} grid points differ between row classification and direct counts")
    if not linear_x:
        counts = counts.T
    boundaries = _dcurves(model, contour, p_name, q_name, p_grid, q_grid, linear_x, tau_max)
    abscissa = None
    if levels is not None:
        abscissa = _abscissa_levels(model, k_all, tau_all, w_all, levels, im_max,
                                    progress).reshape(nq, npp)
        if not linear_x:
            abscissa = abscissa.T
    cross = {"row": crossings.row, "value": crossings.value, "omega": crossings.omega,
             "error": crossings.error, "static": crossings.static, "direction": crossings.direction,
             "row_parameter": q_name}
    return StabilityChart(x_name, y_name, x_grid, y_grid, counts, tuple(boundaries), cross, p_name,
                          x_label, y_label, model.system_name, model.loop.name, contour.radius,
                          "rows (exact crossings + argument principle)", 0.0, model.n_evaluations,
                          abscissa, levels, verified, notes, contour.certificate)


def _classify_rows(model, contour, crossings, p_name, p_grid, q_name, q_grid, notes) -> np.ndarray:
    """Unstable-root counts on the grid from the crossings of each row.

    Between two crossings of a row the count is constant; across a crossing it jumps by
    ``direction * multiplicity``.  One grid point of every interval (the one farthest from the
    crossings) is counted by the argument principle; an interval whose count is not reliable
    takes the value carried over the jumps from the nearest counted interval, and counts that
    disagree with the jumps between them are reported in ``notes``."""
    nq, npp = q_grid.size, p_grid.size
    order = np.argsort(p_grid)
    p_sorted = p_grid[order]
    span = float(p_sorted[-1] - p_sorted[0])
    rows, requests = [], []
    for r in range(nq):
        c = crossings.for_row(r)
        interval = np.searchsorted(c.value, p_sorted, side="right")
        if c.value.size:
            dist = np.abs(p_sorted[:, None] - c.value[None, :])
            tol = c.error + 1e-10 * max(span, 1e-300)
            on_boundary = np.any(dist <= tol[None, :], axis=1)
            nearest = dist.min(axis=1)
        else:
            on_boundary = np.zeros(npp, bool)
            nearest = np.full(npp, np.inf)
        best: dict[int, tuple[float, int]] = {}
        for i in np.flatnonzero(~on_boundary):
            if interval[i] not in best or nearest[i] > best[interval[i]][0]:
                best[interval[i]] = (nearest[i], i)
        rows.append((c, interval, on_boundary))
        requests += [(r, iv, i) for iv, (_, i) in best.items()]
    anchor: dict[tuple[int, int], int] = {}
    if requests:
        idx = np.array([(r, i) for r, _, i in requests])
        k, tau, w = _sets_for(model, {p_name: p_sorted[idx[:, 1]], q_name: q_grid[idx[:, 0]]}, len(requests))
        values, reliable = count(contour, k, tau, w, min_step=1e-9 * contour.radius)
        unreliable = 0
        for (r, iv, _), v, ok in zip(requests, values, reliable):
            if ok and v >= 0:
                anchor[(r, iv)] = int(v)
            else:
                unreliable += 1
        if unreliable:
            notes.append(f"{unreliable} interval count(s) not reliable; taken over the crossing jumps")
    counts = np.full((nq, npp), -1, int)
    inconsistent = 0
    for r, (c, interval, on_boundary) in enumerate(rows):
        n_int = c.value.size + 1
        cumulative = np.concatenate([[0], np.cumsum(c.jump)])
        known = np.array(sorted(iv for (row, iv) in anchor if row == r), int)
        value = np.full(n_int, -1)
        for iv in range(n_int):
            if (r, iv) in anchor:
                value[iv] = anchor[(r, iv)]
            elif known.size:
                src = int(known[np.argmin(np.abs(known - iv))])
                between = slice(min(src, iv), max(src, iv))
                if np.all(c.direction[between] != 0):
                    value[iv] = anchor[(r, src)] + cumulative[iv] - cumulative[src]
        for a_, b_ in zip(known[:-1], known[1:]):
            if np.all(c.direction[a_:b_] != 0) and \
                    anchor[(r, b_)] - anchor[(r, a_)] != cumulative[b_] - cumulative[a_]:
                inconsistent += 1
        row_counts = np.where(value[interval] >= 0, value[interval], -1)
        row_counts[on_boundary] = -1
        counts[r, order] = row_counts
    if inconsistent:
        notes.append(f"{inconsistent} pair(s) of neighbouring interval counts disagree with the "
                     "crossing jumps between them (a crossing may be missed between line samples)")
    return counts


# --------------------------------------------------------------------------------------------
# D-subdivision curves
# --------------------------------------------------------------------------------------------
def _window(grid: np.ndarray, *, nonnegative: bool = False) -> tuple[float, float]:
    """Plot window of a grid, padded by 2 % (not below 0 for delays)."""
    lo, hi = float(grid.min()), float(grid.max())
    pad = 0.02 * (hi - lo)
    return (max(lo - pad, 0.0) if nonnegative else lo - pad), hi + pad


def _clip(values: np.ndarray, window: tuple[float, float]) -> np.ndarray:
    return np.where((values >= window[0]) & (values <= window[1]), values, np.nan)


def _segments(mask: np.ndarray) -> list[slice]:
    """Contiguous runs of True."""
    edges = np.diff(np.concatenate([[0], mask.astype(int), [0]]))
    return [slice(a, b) for a, b in zip(np.flatnonzero(edges == 1), np.flatnonzero(edges == -1))]


def _at(model, assign, s, base, terms):
    return LoopCharacteristic.combine(s, base, terms, *_sets_for(model, assign, 1))[0]


def _branches(model, s, base, terms, p_name, q_name, tau_max: float) -> list[tuple[np.ndarray, np.ndarray]]:
    """D-curve branches ``(p(omega), q(omega))`` on samples ``s = i omega`` (omega > 0).

    Linear ``p`` and delay ``q``: ``Delta = F0 + e^{-s tau} (p G + H)`` vanishes iff
    ``|p G + H| = |F0|`` (a quadratic in ``p``) and ``e^{-i omega tau} = -F0 / (p G + H)``, whose
    phase ``theta`` gives ``tau_k = (-theta + 2 pi k) / omega`` (``theta`` unwrapped along omega,
    one branch per ``k``).  Two linear parameters: ``Delta = F0 + p Fp + q Fq + p q Fpq`` and
    ``Im((F0 + q Fq) conj(Fp + q Fpq)) = 0`` is a quadratic in ``q``, then ``p`` is real.
    ``tau_max`` [s]: the largest delay of the chart (delay branches are listed up to it)."""
    omega = s.imag
    out = []
    if q_name == "delay":
        d00 = _at(model, {p_name: 0.0, "delay": 0.0}, s, base, terms)
        d10 = _at(model, {p_name: 1.0, "delay": 0.0}, s, base, terms)
        F0, H, G = base, d00 - base, d10 - d00
        a, b, c = np.abs(G) ** 2, 2 * np.real(G * np.conj(H)), np.abs(H) ** 2 - np.abs(F0) ** 2
        with np.errstate(all="ignore"):
            root = np.sqrt(b * b - 4 * a * c)
            for sign in (1.0, -1.0):
                p = np.where(a > 0, (-b + sign * root) / (2 * a), np.nan)
                theta = np.angle(-F0 / (p * G + H))
                ok = np.isfinite(p) & np.isfinite(theta)
                unwrapped = np.full(theta.size, np.nan)
                for seg in _segments(ok):
                    unwrapped[seg] = np.unwrap(theta[seg])
                if not ok.any():
                    continue
                k_lo = math.floor(np.nanmin(unwrapped) / (2 * math.pi)) - 1
                k_hi = math.ceil(np.nanmax(unwrapped + tau_max * omega) / (2 * math.pi)) + 1
                for k in range(k_lo, k_hi + 1):
                    out.append((p, (-unwrapped + 2 * math.pi * k) / omega))
    else:
        tau = model.delay
        v = {(i, j): _at(model, {p_name: float(i), q_name: float(j), "delay": tau}, s, base, terms)
             for i in (0, 1) for j in (0, 1)}
        F0, Fp, Fq = v[0, 0], v[1, 0] - v[0, 0], v[0, 1] - v[0, 0]
        Fpq = v[1, 1] - v[1, 0] - v[0, 1] + v[0, 0]
        a0 = np.imag(F0 * np.conj(Fp))
        a1 = np.imag(F0 * np.conj(Fpq)) + np.imag(Fq * np.conj(Fp))
        a2 = np.imag(Fq * np.conj(Fpq))
        scale = np.abs(a0) + np.abs(a1) + np.abs(a2)
        with np.errstate(all="ignore"):
            quadratic = np.abs(a2) > 1e-12 * scale
            roots = [np.where(quadratic, np.nan, -a0 / a1)]
            if quadratic.any():
                disc = np.sqrt(a1 * a1 - 4 * a2 * a0)
                roots = [np.where(quadratic, (-a1 + sg * disc) / (2 * a2), roots[0]) for sg in (1.0, -1.0)]
            for q in roots:
                coefficient = Fp + q * Fpq
                out.append((-np.real((F0 + q * Fq) * np.conj(coefficient)) / np.abs(coefficient) ** 2, q))
    return out


def _resolve_curves(model, contour, p_name, q_name, p_grid, q_grid, tau_max: float,
                    tolerance: float = 0.03, rounds: int = 12) -> None:
    """Add line samples until every D-curve moves by less than ``tolerance`` of the window
    between neighbouring samples (inside the window), so crossing pairs are not skipped."""
    line = contour.line
    pw, qw = _window(p_grid), _window(q_grid, nonnegative=q_name == "delay")
    p_span, q_span = pw[1] - pw[0], qw[1] - qw[0]
    for _ in range(rounds):
        s, base, terms = line.s[1:], line.base[1:], line.terms[:, 1:]
        h = np.diff(s.imag)
        bad = np.zeros(h.size, bool)
        for p, q in _branches(model, s, base, terms, p_name, q_name, tau_max):
            inside = (p >= pw[0]) & (p <= pw[1]) & (q >= qw[0]) & (q <= qw[1])
            near = inside[1:] | inside[:-1]
            with np.errstate(invalid="ignore"):
                step = np.abs(np.diff(p)) / p_span + np.abs(np.diff(q)) / q_span
            bad |= near & ~(step <= tolerance)
        bad &= h > 1e-7 * contour.radius
        if not bad.any():
            return
        line.insert(np.concatenate([[False], bad]))


def _dcurves(model, contour, p_name, q_name, p_grid, q_grid, linear_x, tau_max: float) -> list[Boundary]:
    line = contour.line
    pw, qw = _window(p_grid), _window(q_grid, nonnegative=q_name == "delay")
    s, base, terms = line.s[1:], line.base[1:], line.terms[:, 1:]
    omega = s.imag
    curves: list[tuple[np.ndarray, np.ndarray, np.ndarray, str]] = []
    for p, q in _branches(model, s, base, terms, p_name, q_name, tau_max):
        pc, qc = _clip(p, pw), _clip(q, qw)
        keep = np.isfinite(pc) & np.isfinite(qc)
        if keep.any():
            curves.append((np.where(keep, pc, np.nan), np.where(keep, qc, np.nan), omega, "oscillatory"))
    s0, base0, terms0 = line.s[:1], line.base[:1], line.terms[:, :1]
    if q_name == "delay":
        d00 = _at(model, {p_name: 0.0, "delay": 0.0}, s0, base0, terms0)[0]
        d10 = _at(model, {p_name: 1.0, "delay": 0.0}, s0, base0, terms0)[0]
        if abs(d10 - d00) > 0:
            p0 = float(np.real(-d00 / (d10 - d00)))
            if pw[0] <= p0 <= pw[1]:
                curves.append((np.full(2, p0), np.array([q_grid.min(), q_grid.max()]), np.zeros(2),
                               "static"))
    else:
        tau = model.delay
        qs = np.linspace(q_grid.min(), q_grid.max(), 801)
        w0 = {(i, j): _at(model, {p_name: float(i), q_name: float(j), "delay": tau}, s0, base0, terms0)[0]
              for i in (0, 1) for j in (0, 1)}
        G0, Gp, Gq = w0[0, 0], w0[1, 0] - w0[0, 0], w0[0, 1] - w0[0, 0]
        Gpq = w0[1, 1] - w0[1, 0] - w0[0, 1] + w0[0, 0]
        with np.errstate(all="ignore"):
            p0 = np.real(-(G0 + qs * Gq) / (Gp + qs * Gpq))
        pc = _clip(p0, pw)
        if np.isfinite(pc).any():
            curves.append((pc, qs, np.zeros(qs.size), "static"))
    out = []
    for p, q, w, kind in curves:
        x_, y_ = (p, q) if linear_x else (q, p)
        out.append(Boundary(np.asarray(x_, float), np.asarray(y_, float), np.asarray(w, float), kind))
    return out


# --------------------------------------------------------------------------------------------
# spectral abscissa by level counting
# --------------------------------------------------------------------------------------------
def _abscissa_levels(model, k, tau, w, levels, im_max, progress=None) -> np.ndarray:
    from .progress import progress_bar

    counts = []
    bar = progress_bar(levels.size, "abscissa levels", enabled=progress, min_total=10)
    for sigma in levels:
        contour = build_contour(model, loop_weight_bound(k, w), float(tau.max()), sigma=float(sigma),
                           im_max=im_max)
        counts.append(count(contour, k, tau, w)[0])
        bar.update()
    bar.close()
    counts = np.array(counts)                       # (n_levels, n_points)
    right = counts != 0                             # roots right of (or on) the level
    first_clear = np.argmax(~right, axis=0)
    all_right = np.all(right, axis=0)
    mid = 0.5 * (levels[:-1] + levels[1:])
    value = np.where(first_clear == 0, levels[0], mid[np.clip(first_clear - 1, 0, mid.size - 1)])
    return np.where(all_right, levels[-1], value)


# --------------------------------------------------------------------------------------------
# charts of general functions make_system(x, y)
# --------------------------------------------------------------------------------------------
def _shared_loop(systems: list, loop: str | None):
    """The varying loop if all systems share plant and other loops (else None)."""
    first = systems[0]
    lp = find_loop(first, loop)
    index = first.loops.index(lp)
    for sys_ in systems[1:]:
        if sys_.plant is not first.plant or len(sys_.loops) != len(first.loops):
            return None
        other = sys_.loops[index]
        if (other.name, other.actuator, tuple(n for n, _ in other.terms)) != \
                (lp.name, lp.actuator, tuple(n for n, _ in lp.terms)):
            return None
        if other.is_lti or lp.is_lti:
            if other.gain is not lp.gain:
                return None
        for j, (a, b) in enumerate(zip(sys_.loops, first.loops)):
            if j != index and a != b:
                return None
    return lp


def _point_count(args) -> int:
    system, loop, im_max = args
    counts = unstable_root_count(system, loop=loop, im_max=im_max)
    return int(counts[0]), counts.certificate


def _function_chart(make_system, loop, xs, ys, im_max, levels, pool, progress) -> StabilityChart:
    (x_name, x_grid, x_label), (y_name, y_grid, y_label) = xs, ys
    systems = []
    for yv in y_grid:
        for xv in x_grid:
            sys_ = make_system(float(xv), float(yv))
            if not isinstance(sys_, ControlledChain):
                as_controlled(sys_, f"make_system({xv!r}, {yv!r})")
            systems.append(sys_)
    notes = ["boundaries interpolated from the counts on the grid"]
    shared = _shared_loop(systems, loop)
    if shared is not None:
        model = LoopCharacteristic(systems[0], shared.name)
        model.executor = pool
        k = np.array([1.0 if lp.is_lti else float(lp.gain) for lp in (sys_.loop(shared.name) for sys_ in systems)])
        tau = np.array([sys_.loop(shared.name).delay for sys_ in systems])
        w = np.array([[wt for _, wt in sys_.loop(shared.name).terms] for sys_ in systems])
        contour = build_contour(model, loop_weight_bound(k, w), float(tau.max()), im_max=im_max)
        counts, _ = count(contour, k, tau, w)
        radius, method, evaluations = contour.radius, "points (batched over one loop)", model.n_evaluations
        abscissa = None if levels is None else \
            _abscissa_levels(model, k, tau, w, levels, im_max, progress).reshape(y_grid.size, x_grid.size)
        notes += contour.notes
        certificate = contour.certificate
    else:
        if levels is not None:
            raise ModelError("abscissa_levels needs systems that differ only in one loop's parameters")
        results = parallel_map(_point_count, [(s_, loop, im_max) for s_ in systems],
                               executor=pool, progress=progress, description="stability chart")
        counts = np.array([c for c, _ in results])
        certificates = [cert for _, cert in results]
        certificate = next((cert for cert in certificates if not cert.certified), certificates[0])
        radius, method, evaluations, abscissa = float("nan") if im_max is None else im_max, \
            "points (one count per system)", 0, None
    counts = counts.reshape(y_grid.size, x_grid.size)
    boundaries = _grid_boundaries(x_grid, y_grid, counts)
    lp_name = shared.name if shared is not None else (loop or None)
    return StabilityChart(x_name, y_name, x_grid, y_grid, counts, tuple(boundaries),
                          {"row": np.zeros(0, int), "value": np.zeros(0), "omega": np.zeros(0),
                           "error": np.zeros(0), "static": np.zeros(0, bool)}, None,
                          x_label, y_label, systems[0].name, lp_name, radius, method, 0.0,
                          evaluations, abscissa, levels, None, notes, certificate)


def _grid_boundaries(x: np.ndarray, y: np.ndarray, counts: np.ndarray) -> list[Boundary]:
    import contourpy

    ox, oy = np.argsort(x), np.argsort(y)
    field_ = (counts == 0).astype(float)[np.ix_(oy, ox)]
    lines = contourpy.contour_generator(x[ox], y[oy], field_, line_type="Separate").lines(0.5)
    return [Boundary(line[:, 0].copy(), line[:, 1].copy(), np.full(len(line), np.nan), "grid")
            for line in lines]
