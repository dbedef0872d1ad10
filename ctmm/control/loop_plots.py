"""Bode and Nyquist plots of frequency responses and loop transfer functions (matplotlib).

:func:`bode_plot` draws every input/output pair of one or more :class:`~ctmm.results.FrequencyResponse` through
:meth:`FrequencyResponse.plot <ctmm.results.FrequencyResponse.plot>` (the one Bode drawing of ctmm), optionally with
the crossovers and margins of :func:`ctmm.control.analysis.margins`; :func:`nyquist_plot` draws loop transfer
functions (:func:`ctmm.control.analysis.loop_transfer_function`) around the critical point ``-1``.  Both return the
figure; ``ctmm.control`` exports them.
"""
from __future__ import annotations

from typing import Any

import numpy as np

from ..errors import ModelError
from ..results import FrequencyResponse
from .analysis import Margins

__all__ = ["bode_plot", "nyquist_plot"]


def _responses(frfs: Any) -> list[tuple[str, np.ndarray, np.ndarray]]:
    """``(label, omega, response)`` of every input/output pair of ``frfs``, labelled ``"<system>: <input> ->
    <output>"``; anything but a :class:`FrequencyResponse` is refused (:class:`~ctmm.errors.ModelError`)."""
    items = frfs if isinstance(frfs, (list, tuple)) else [frfs]
    curves = []
    for item in items:
        if not isinstance(item, FrequencyResponse):
            raise ModelError(f"expected FrequencyResponse objects, got {item!r}")
        for o in item.outputs:
            for i in item.inputs:
                label = f"{item.system_name}: {i} -> {o}" if item.system_name else f"{i} -> {o}"
                curves.append((label, item.omega, item(o, i)))
    return curves


def bode_plot(responses: Any, *, margins: Margins | None = None, title: str | None = None,
              hz: bool = False, axes: Any = None):
    """Bode plot (magnitude [dB], phase [deg]) of one or more :class:`FrequencyResponse`.

    Every curve is drawn by :meth:`FrequencyResponse.plot <ctmm.results.FrequencyResponse.plot>`
    (the one Bode drawing of ctmm), so the axes carry the same labels and units: the magnitude
    axis reads ``magnitude [dB re 1 <output unit>/<input unit>]`` when every curve has the same
    unit (``(dimensionless)`` for loop transfer functions); with mixed units each legend entry
    carries its unit.  Legend entries are ``"<system>: <input> -> <output>"``.

    Parameters
    ----------
    responses : FrequencyResponse or sequence of them
        Every input/output pair is drawn.
    margins : Margins, optional
        Mark the gain and phase crossovers of a loop transfer function.
    title : str, optional
        Figure title.
    hz : bool
        Frequency axis in Hz instead of rad/s.
    axes : pair of matplotlib axes, optional
        Draw into these (magnitude, phase) axes.

    Returns
    -------
    matplotlib.figure.Figure
    """
    import matplotlib.pyplot as plt

    items = list(responses) if isinstance(responses, (list, tuple)) else [responses]
    curves = _responses(items)  # checks the items; labels "system: input -> output"
    pairs = [(item, o, i) for item in items for o in item.outputs for i in item.inputs]
    if axes is None:
        fig, axes = plt.subplots(2, 1, sharex=True, figsize=(7.5, 5.5))
    else:
        fig = axes[0].figure
    axes = list(axes)
    drawn_before = [len(ax.get_lines()) for ax in axes]
    mixed = len({item.response_unit(o, i) for item, o, i in pairs}) > 1
    for (label, _, _), (item, o, i) in zip(curves, pairs):
        unit = item.response_unit(o, i)
        item.plot(axes, output=o, input=i, label=label + (f" [{unit}]" if mixed and unit else ""))
    if mixed:
        axes[0].set_ylabel("magnitude [dB re 1 (unit in legend)]")
    scale = 1.0 / (2 * np.pi) if hz else 1.0
    if hz:  # FrequencyResponse.plot draws against omega [rad/s]: rescale the curves drawn here
        for ax, before in zip(axes, drawn_before):
            for line in ax.get_lines()[before:]:
                line.set_xdata(np.asarray(line.get_xdata()) * scale)
            ax.relim()
            ax.autoscale_view()
        axes[-1].set_xlabel("frequency [Hz]")
    if margins is not None:
        for wc in margins.gain_crossovers:
            axes[0].axvline(wc * scale, color="k", lw=0.6, ls=":")
            axes[1].axvline(wc * scale, color="k", lw=0.6, ls=":")
        for wp in margins.phase_crossovers:
            axes[1].axvline(wp * scale, color="r", lw=0.6, ls=":")
        axes[0].axhline(0.0, color="k", lw=0.6)
        text = (f"GM = {20 * np.log10(margins.gain_margin):.2f} dB, PM = {margins.phase_margin:.1f} deg, "
                f"DM = {margins.delay_margin * 1e3:.2f} ms" if np.isfinite(margins.gain_margin)
                else f"GM = inf, PM = {margins.phase_margin:.1f} deg, DM = {margins.delay_margin * 1e3:.2f} ms")
        axes[0].set_title(text, fontsize=9)
    axes[0].legend(fontsize=7)
    if title:
        fig.suptitle(title)
    fig.tight_layout()
    return fig


def nyquist_plot(responses: Any, *, margins: Margins | None = None, title: str | None = None, ax: Any = None,
                 mirror: bool = True):
    """Nyquist plot of loop transfer functions with the critical point ``-1``.

    Parameters
    ----------
    responses : FrequencyResponse or sequence of them
        SISO loop transfer functions (e.g. from :func:`ctmm.control.analysis.loop_transfer_function`).
    margins : Margins, optional
        Mark the gain-crossover points on the unit circle and the phase crossovers.
    title : str, optional
        Axes title.
    ax : matplotlib axes, optional
        Draw into these axes.
    mirror : bool
        Also draw the negative-frequency branch (complex conjugate, dashed).

    Returns
    -------
    matplotlib.figure.Figure
    """
    import matplotlib.pyplot as plt

    if ax is None:
        fig, ax = plt.subplots(figsize=(6, 6))
    else:
        fig = ax.figure
    theta = np.linspace(0, 2 * np.pi, 361)
    ax.plot(np.cos(theta), np.sin(theta), color="0.7", lw=0.8)
    for label, w, h in _responses(responses):
        line, = ax.plot(h.real, h.imag, label=label)
        if mirror:
            ax.plot(h.real, -h.imag, ls="--", color=line.get_color(), lw=0.8)
        k = max(1, h.size // 3)
        if h.size > k + 1:
            ax.annotate("", xy=(h[k + 1].real, h[k + 1].imag), xytext=(h[k].real, h[k].imag),
                        arrowprops=dict(arrowstyle="->", color=line.get_color()))
    ax.plot([-1.0], [0.0], "r+", ms=12, mew=2, label="-1")
    if margins is not None:
        for pm in margins.phase_margins:
            ang = np.radians(pm - 180.0)
            ax.plot(np.cos(ang), np.sin(ang), "ko", ms=4)
        for gm in margins.gain_margins:
            ax.plot(-1.0 / gm, 0.0, "rs", ms=4)
    ax.axhline(0, color="k", lw=0.5)
    ax.axvline(0, color="k", lw=0.5)
    ax.set_xlabel("Re L")
    ax.set_ylabel("Im L")
    ax.set_aspect("equal", adjustable="datalim")
    ax.grid(True, alpha=0.3)
    ax.legend(fontsize=7)
    if title:
        ax.set_title(title)
    return fig

