"""One Bode drawing: ``control.loop_plots.bode_plot`` draws through ``FrequencyResponse.plot``.

The curves are checked against the closed-form receptance of a spring-mass oscillator
``x / F = 1 / (k - m omega^2)`` (independent of the TMM), the axis labels against the units.
"""
from __future__ import annotations

import matplotlib
import numpy as np
import pytest

import ctmm
from ctmm.control.loop_plots import bode_plot
from ctmm.elements import Fixed, Free, Mass, Spring
from ctmm.errors import ModelError

matplotlib.use("Agg")
import matplotlib.pyplot as plt  # noqa: E402

STIFFNESS, MASS = 100.0, 2.0        # [N/m], [kg]
OMEGA = np.logspace(0.0, 2.0, 40)   # [rad/s], resonance at sqrt(50) = 7.07 rad/s inside


@pytest.fixture(autouse=True)
def _close_figures():
    yield
    plt.close("all")


def _oscillator(output):
    chain = ctmm.Chain("sdof", [Fixed("wall"), Spring("k", STIFFNESS), Mass("m", MASS), Free("end")])
    return ctmm.frequency_response(chain, OMEGA, input="m.force", output=output)


def test_curves_are_the_closed_form_receptance_and_mobility():
    receptance = 1.0 / (STIFFNESS - MASS * OMEGA ** 2)               # x/F [m/N]
    expected = {"m.x": receptance, "m.v": 1j * OMEGA * receptance}  # v/F [(m/s)/N]
    fig = bode_plot(_oscillator(["m.x", "m.v"]))
    magnitude, phase = fig.axes
    for name, h in expected.items():
        [line] = [line for line in magnitude.get_lines() if f"-> {name}" in line.get_label()]
        np.testing.assert_allclose(line.get_xdata(), OMEGA)
        np.testing.assert_allclose(line.get_ydata(), 20 * np.log10(np.abs(h)), rtol=1e-9, atol=1e-9)
        [line] = [line for line in phase.get_lines() if f"-> {name}" in line.get_label()]
        wrapped = np.angle(np.exp(1j * np.radians(line.get_ydata())))
        np.testing.assert_allclose(np.exp(1j * wrapped), h / np.abs(h), atol=1e-9)


def test_labels_carry_units_as_frequency_response_plot():
    single = _oscillator("m.x")
    own = single.plot()
    fig = bode_plot(single)
    assert [ax.get_ylabel() for ax in fig.axes] == [ax.get_ylabel() for ax in own.axes] \
        == ["magnitude [dB re 1 m/N]", "phase [deg]"]
    assert fig.axes[1].get_xlabel() == own.axes[1].get_xlabel() == "angular frequency [rad/s]"
    assert [line.get_label() for line in fig.axes[0].get_lines()] == ["sdof: m.force -> m.x"]
    mixed = bode_plot(_oscillator(["m.x", "m.v"]))
    assert mixed.axes[0].get_ylabel() == "magnitude [dB re 1 (unit in legend)]"
    assert [line.get_label() for line in mixed.axes[0].get_lines()] == [
        "sdof: m.force -> m.x [m/N]", "sdof: m.force -> m.v [(m/s)/N]"]


def test_hz_axis_rescales_only_the_curves_drawn():
    fig, axes = plt.subplots(2, 1)
    axes[0].plot([1.0, 2.0], [0.0, 0.0], label="already there")
    bode_plot(_oscillator("m.x"), hz=True, axes=axes)
    existing, curve = axes[0].get_lines()
    np.testing.assert_array_equal(existing.get_xdata(), [1.0, 2.0])
    np.testing.assert_allclose(curve.get_xdata(), OMEGA / (2 * np.pi))
    np.testing.assert_allclose(axes[1].get_lines()[0].get_xdata(), OMEGA / (2 * np.pi))
    assert axes[1].get_xlabel() == "frequency [Hz]"


def test_refuses_what_is_not_a_frequency_response():
    with pytest.raises(ModelError, match="expected FrequencyResponse"):
        bode_plot([_oscillator("m.x"), np.ones(3)])
