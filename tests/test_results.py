"""Result objects for the user's desk: data frames, units of signals, labelled plots."""
from __future__ import annotations

import sys

import numpy as np
import pytest

import ctmm
from ctmm.control import ControlledChain, Feedback
from ctmm.elements import Fixed, Free, Mass, Spring, SpringDamper
from ctmm.errors import ModelError
from ctmm.results import FrequencyResponse, SimulationResult
from ctmm.signal_units import QUANTITY_UNITS, label, signal_unit


def plant() -> ctmm.Chain:
    return ctmm.Chain("two_mass", [Fixed("wall"), SpringDamper("k1", 100.0, 0.5), Mass("m1", 1.0),
                                   SpringDamper("k2", 50.0, 0.2), Mass("m2", 0.5), Free("tip")])


@pytest.fixture(scope="module")
def result() -> SimulationResult:
    system = ControlledChain(plant(), [Feedback("pd", [("m2.x", 1.0), ("m1.x", -1.0)], "m1", 3.0, 0.01)])
    return ctmm.simulate(system, 0.3, 0.01, x0={"m2": 0.01})


# ------------------------------------------------------------------------------------- units
@pytest.mark.parametrize("name, unit", [
    ("m6.x", "m"), ("m6.v", "m/s"), ("m6.a", "m/s^2"), ("k3.f", "N"), ("m6.x_dot", "m/s"),
    ("m6.x_ddot", "m/s^2"), ("m1.force", "N"), ("base.displacement", "m"), ("beam.theta", "rad"),
    ("beam.theta_dot", "rad/s"), ("beam.moment", "N*m"), ("loop.L", "1"), ("loop.u", "N"),
    ("loop.y", ""), ("ctrl@samples", ""), ("m.xs", ""), ("tip.deflection", "m"), ("p1.voltage", "V"),
])
def test_units_from_names_alone(name, unit):
    """The 1-D kinds have fixed units; names whose unit depends on the system are not guessed."""
    assert signal_unit(name) == unit


def test_units_with_the_system(result):
    system = result.system
    assert signal_unit("pd.y", system) == "m"          # relative displacement sensor
    assert signal_unit("pd.reference", system) == "m"
    assert signal_unit("pd.u", system) == "N"
    assert signal_unit("k2.in.f", system) == "N" and signal_unit("wall.v", system) == "m/s"
    velocity_loop = ControlledChain(plant(), [Feedback("c", "m2.v", "m1.force", 1.0, 0.0)])
    assert signal_unit("c.y", velocity_loop) == "m/s"
    mixed = ControlledChain(plant(), [Feedback("c", [("m2.x", 1.0), ("m2.v", 0.1)], "m1", 1.0, 0.0)])
    assert signal_unit("c.y", mixed) == ""            # a sum of m and m/s has no single unit
    assert label("m6.x", "m") == "m6.x [m]" and label("ctrl", "") == "ctrl"
    assert set(QUANTITY_UNITS) >= {"x", "v", "a", "f"}


def test_units_of_one_name(result):
    """``result.units("m2.x")`` read the string as the names "m", "2", ".", "x" (a dict of four empty units)."""
    assert result.units("m2.x") == {"m2.x": "m"} and result.units(["m2.x", "pd.u"]) == {"m2.x": "m", "pd.u": "N"}
    with pytest.raises(ModelError, match="names must be a name"):
        result.units(3)


# ---------------------------------------------------------------------------------- data frame
def test_dataframe_equals_the_arrays(result):
    pd = pytest.importorskip("pandas")
    frame = result.to_dataframe()
    assert list(frame.columns) == result.time_signals()
    assert {"m2.x", "m2.v", "k1.f", "pd.y", "pd.u"} <= set(frame.columns)
    np.testing.assert_array_equal(frame.index.to_numpy(), result.time)
    assert frame.index.name == "time [s]"
    for name in frame.columns:
        assert frame[name].dtype == np.float64
        np.testing.assert_array_equal(frame[name].to_numpy(), result[name])
    # the sensed value is independently the weighted sum of the plant displacements
    np.testing.assert_array_equal(frame["pd.y"].to_numpy()[1:], (result["m2.x"] - result["m1.x"])[1:])
    assert frame.attrs["units"]["m2.v"] == "m/s" and frame.attrs["units"]["pd.u"] == "N"
    assert frame.attrs["provenance"]["dt"] == 0.01 and frame.attrs["provenance"]["scheme"] == "newmark"
    named = result.to_dataframe(["m2.x", "k1.f"], units_in_names=True)
    assert list(named.columns) == ["m2.x [m]", "k1.f [N]"]
    assert isinstance(named, pd.DataFrame)
    with pytest.raises(ModelError, match="unknown signal 'm9.x'"):
        result.to_dataframe(["m9.x"])


def test_dataframe_without_pandas_names_the_extra(result, monkeypatch):
    monkeypatch.setitem(sys.modules, "pandas", None)
    with pytest.raises(ImportError, match=r"pip install 'ctmm\[data\]'"):
        result.to_dataframe()


def test_save_without_h5py_names_the_extra(result, monkeypatch, tmp_path):
    monkeypatch.setitem(sys.modules, "h5py", None)
    with pytest.raises(ImportError, match=r"h5py.*pip install 'ctmm\[data\]'"):
        result.save(tmp_path / "run.h5")


# ---------------------------------------------------------------------------------- plots
def test_simulation_plot_labels_carry_units(result):
    import matplotlib.pyplot as plt

    fig = result.plot("m2.x")
    ax = fig.axes[0]
    assert ax.get_xlabel() == "time [s]" and ax.get_ylabel() == "m2.x [m]"
    fig2 = result.plot("m2.x", "m1.x")
    assert fig2.axes[0].get_ylabel() == "m2.x, m1.x [m]"
    fig3 = result.plot("m2.x", "pd.u")
    assert fig3.axes[0].get_ylabel() == "m2.x [m], pd.u [N]"
    assert fig3.axes[0].get_legend_handles_labels()[1] == ["m2.x [m]", "pd.u [N]"]
    plt.close("all")


def test_frequency_response_plot_labels_carry_units():
    import matplotlib.pyplot as plt

    response = ctmm.frequency_response(plant(), np.linspace(1.0, 30.0, 20), input="m1.force", output=["m2.x", "m2.a"])
    fig = response.plot(output="m2.x")
    assert [a.get_ylabel() for a in fig.axes] == ["magnitude [dB re 1 m/N]", "phase [deg]"]
    assert fig.axes[-1].get_xlabel() == "angular frequency [rad/s]"
    fig = response.plot()
    assert fig.axes[0].get_ylabel() == "magnitude [dB re 1 (unit in legend)]"
    assert fig.axes[0].get_legend_handles_labels()[1] == ["m1.force -> m2.x [m/N]", "m1.force -> m2.a [(m/s^2)/N]"]
    loop = FrequencyResponse(response.omega, response.response[:1], ("pd.u",), ("pd.L",))
    assert loop.plot().axes[0].get_ylabel() == "magnitude [dB] (dimensionless)"
    unknown = FrequencyResponse(response.omega, response.response[:1], ("m1.force",), ("pd.y",))
    assert unknown.plot().axes[0].get_ylabel() == "magnitude [dB, unit unknown]"
    given = FrequencyResponse(response.omega, response.response[:1], ("m1.force",), ("pd.y",), units={"pd.y": "m"})
    assert given.plot().axes[0].get_ylabel() == "magnitude [dB re 1 m/N]"
    plt.close("all")


def test_modal_plot_labels():
    import matplotlib.pyplot as plt

    chain = ctmm.Chain("undamped", [Fixed("wall"), Spring("k1", 100.0), Mass("m1", 1.0), Spring("k2", 50.0),
                                    Mass("m2", 0.5), Free("tip")])
    fig = ctmm.mode_shapes(chain, n_modes=2).plot()
    ax = fig.axes[0]
    assert ax.get_xlabel() == "connection point (index)"
    assert ax.get_ylabel() == "mode shape, x [1] (largest displacement = 1)"
    assert all("rad/s" in text for text in ax.get_legend_handles_labels()[1])
    plt.close("all")


def test_frequency_response_call_without_a_name_needs_a_single_pair():
    import ctmm
    from ctmm.elements import Fixed, Free, Mass, Spring

    chain = ctmm.Chain("s", [Fixed("w"), Spring("k", 100.0), Mass("m", 1.0), Spring("k2", 50.0), Mass("m2", 1.0),
                             Free("e")])
    frf = ctmm.frequency_response(chain, [1.0, 2.0], input=["m.force", "m2.force"], output="m.x")
    assert frf("m.x", "m2.force").shape == (2,)
    with pytest.raises(ctmm.ModelError, match="2 inputs; name the input: one of m.force, m2.force"):
        frf("m.x")
