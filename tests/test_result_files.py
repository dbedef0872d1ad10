"""Results on disk: HDF5 round trips (bit for bit), provenance, partial results, bad files.

The reference for every stored array is the in-memory result itself (saving must not change a
bit), read back both through :func:`ctmm.results.load` and independently through plain h5py, as
a user's tool would.
"""
from __future__ import annotations

import os

import numpy as np
import pytest

import ctmm
from ctmm.control import ControlledChain, Feedback
from ctmm.elements import Fixed, Free, Mass, SpringDamper
from ctmm.errors import ModelError, SimulationError
from ctmm.result_files import FORMAT_VERSION, ResultFileError
from ctmm.results import FrequencyResponse, SimulationResult, StoredSystem, load

h5py = pytest.importorskip("h5py")


def plant() -> ctmm.Chain:
    return ctmm.Chain("two_mass", [Fixed("wall"), SpringDamper("k1", 100.0, 0.5), Mass("m1", 1.0),
                                   SpringDamper("k2", 50.0, 0.2), Mass("m2", 0.5), Free("tip")])


@pytest.fixture(scope="module")
def controlled_result() -> SimulationResult:
    system = ControlledChain(plant(), [Feedback("pd", "m2.v", "m1", 3.0, 0.01)])
    return ctmm.simulate(system, 0.5, 0.01, x0={"m2": 0.01})


def assert_same_simulation(a: SimulationResult, b: SimulationResult) -> None:
    for attribute in ("time", "states", "velocity", "acceleration"):
        x, y = getattr(a, attribute), getattr(b, attribute)
        assert x.dtype == y.dtype and x.shape == y.shape
        np.testing.assert_array_equal(x, y)       # bit for bit (equal_nan not needed: all finite)
    assert a.time_signals() == b.time_signals()
    for name in a.time_signals():
        np.testing.assert_array_equal(a[name], b[name])
    assert a.units() == b.units()
    assert a.scheme_name == b.scheme_name


def test_simulation_round_trip_is_exact_with_names_units_provenance(controlled_result, tmp_path):
    path = controlled_result.save(tmp_path / "run.h5")
    loaded = load(path)
    assert isinstance(loaded, SimulationResult) and isinstance(loaded.system, StoredSystem)
    assert_same_simulation(controlled_result, loaded)
    assert loaded.system.name == controlled_result.system.name
    assert loaded.system.point_names() == controlled_result.system.point_names()
    # units: the table of ctmm.signal_units, loop sensor in the unit of its sensed signal
    assert loaded.unit("m2.x") == "m" and loaded.unit("m2.v") == "m/s" and loaded.unit("m2.a") == "m/s^2"
    assert loaded.unit("k1.f") == "N" and loaded.unit("pd.u") == "N" and loaded.unit("pd.y") == "m/s"
    # provenance
    for key in ("dt", "n_steps", "wall_time_s", "path", "loops"):
        assert loaded.info[key] == controlled_result.info[key]
    assert loaded.info["ctmm_version"] == ctmm.__version__ and loaded.info["format_version"] == FORMAT_VERSION
    assert loaded.info["created_utc"].endswith("+00:00")
    # the loaded result is usable like the original one
    with pytest.raises(ModelError, match="unknown signal"):
        loaded["m9.x"]


def test_file_is_readable_with_plain_h5py(controlled_result, tmp_path):
    """What a user's tool sees: named datasets with unit attributes, provenance, parameters."""
    path = controlled_result.save(tmp_path / "run.hdf5")
    with h5py.File(path, "r") as f:
        assert f.attrs["format"] == "ctmm-result" and f.attrs["format_version"] == FORMAT_VERSION
        assert f.attrs["kind"] == "simulation" and f.attrs["scheme"] == "newmark"
        assert f.attrs["system_name"] == controlled_result.system.name
        np.testing.assert_array_equal(f["time"][()], controlled_result.time)
        assert f["time"].attrs["unit"] == "s"
        np.testing.assert_array_equal(f["signals/m2.x"][()], controlled_result["m2.x"])
        assert f["signals/m2.x"].attrs["unit"] == "m" and f["signals/pd.y"].attrs["unit"] == "m/s"
        elements = f["system"].attrs["elements"]
        assert '"mass": 1.0' in elements and '"stiffness": 100.0' in elements


def test_partial_result_of_failed_run_can_be_saved(tmp_path):
    system = ControlledChain(plant(), [Feedback("bad", "m2.x", "m1", -1.0e4, 0.0)])  # positive feedback
    with pytest.raises(SimulationError) as info:
        ctmm.simulate(system, 20.0, 0.01, x0={"m2": 0.01}, divergence_bound=1.0)
    partial = info.value.partial_result
    assert 1 < len(partial.time) < 2001
    loaded = load(partial.save(tmp_path / "partial.h5"))
    assert_same_simulation(partial, loaded)
    assert "bad.u" in loaded.time_signals() and len(loaded["bad.u"]) == len(partial.time)
    assert loaded.info["failed_at_s"] == info.value.time and loaded.info["dt"] == 0.01


def test_empty_partial_result_round_trip(tmp_path):
    empty = SimulationResult.empty(plant(), "newmark")
    loaded = load(empty.save(tmp_path / "empty.h5"))
    assert loaded.time.shape == (0,) and loaded.states.shape == empty.states.shape
    assert loaded["m2.x"].shape == (0,)
    controlled = ControlledChain(plant(), [Feedback("pd", "m2.v", "m1", 3.0, 0.01)])
    loaded = load(SimulationResult.empty(controlled, "newmark").save(tmp_path / "empty_loop.h5"))
    assert loaded["m2.v"].shape == (0,)
    with pytest.raises(ModelError, match="unknown signal"):    # the loop never ran: no loop signal
        loaded["pd.y"]


def test_frequency_response_round_trip(tmp_path):
    response = ctmm.frequency_response(plant(), np.linspace(1.0, 30.0, 40), input="m1.force",
                                       output=["m2.x", "m2.v"])
    response.info["solver"] = "riccati"
    loaded = load(response.save(tmp_path / "frf.h5"))
    assert isinstance(loaded, FrequencyResponse)
    assert loaded.response.dtype == np.complex128
    np.testing.assert_array_equal(loaded.response, response.response)
    np.testing.assert_array_equal(loaded.omega, response.omega)
    assert (loaded.inputs, loaded.outputs, loaded.system_name) == (response.inputs, response.outputs, "two_mass")
    assert loaded.response_unit("m2.x", "m1.force") == "m/N"
    assert loaded.response_unit("m2.v", "m1.force") == "(m/s)/N"
    assert loaded.info["solver"] == "riccati" and loaded.info["ctmm_version"] == ctmm.__version__


def test_save_is_atomic_and_replaces(controlled_result, tmp_path):
    path = tmp_path / "run.h5"
    path.write_bytes(b"old")
    controlled_result.save(path)
    assert load(path).time.shape == controlled_result.time.shape
    assert os.listdir(tmp_path) == ["run.h5"]                  # no temporary file left behind
    bad = SimulationResult(controlled_result.time, controlled_result.states, controlled_result.velocity,
                           controlled_result.acceleration, controlled_result.system,
                           extra={"x//y": controlled_result.time})
    with pytest.raises(ResultFileError, match="cannot be stored"):
        bad.save(path)
    assert os.listdir(tmp_path) == ["run.h5"]                  # failed save: old file intact
    assert load(path).time.shape == controlled_result.time.shape


def test_saved_file_has_ordinary_permissions_under_the_umask(controlled_result, tmp_path):
    """A saved result is an ordinary file (mode 0666 filtered by the umask, like ``open``), not the 0600
    of a temporary file; a colleague in the group can read it."""
    previous = os.umask(0o022)
    try:
        path = controlled_result.save(tmp_path / "shared.h5")
        written = tmp_path / "plain.txt"
        written.write_text("x")
    finally:
        os.umask(previous)
    assert oct(os.stat(path).st_mode & 0o777) == oct(os.stat(written).st_mode & 0o777) == oct(0o644)


@pytest.mark.parametrize("name, match", [
    ("missing_folder/run.h5", "does not exist"),
    ("run.csv", "must end with"),
])
def test_bad_save_path(controlled_result, tmp_path, name, match):
    with pytest.raises(ResultFileError, match=match):
        controlled_result.save(tmp_path / name)
    with pytest.raises(ResultFileError, match="is a folder"):
        (tmp_path / "folder.h5").mkdir(exist_ok=True)
        controlled_result.save(tmp_path / "folder.h5")


def test_bad_files_are_refused_clearly(controlled_result, tmp_path):
    with pytest.raises(ResultFileError, match="no such result file"):
        load(tmp_path / "absent.h5")
    text = tmp_path / "text.h5"
    text.write_text("not hdf5")
    with pytest.raises(ResultFileError, match="not a readable HDF5 file"):
        load(text)
    foreign = tmp_path / "foreign.h5"
    with h5py.File(foreign, "w") as f:
        f["x"] = np.ones(3)
    with pytest.raises(ResultFileError, match="not a ctmm result file"):
        load(foreign)
    path = controlled_result.save(tmp_path / "run.h5")
    truncated = tmp_path / "truncated.h5"
    truncated.write_bytes(path.read_bytes()[: path.stat().st_size // 2])
    with pytest.raises(ResultFileError, match="not a readable HDF5|corrupted"):
        load(truncated)
    newer = controlled_result.save(tmp_path / "newer.h5")
    with h5py.File(newer, "a") as f:
        f.attrs["format_version"] = FORMAT_VERSION + 1
    with pytest.raises(ResultFileError, match=f"format version {FORMAT_VERSION + 1}.*upgrade ctmm"):
        load(newer)
    damaged = controlled_result.save(tmp_path / "damaged.h5")
    with h5py.File(damaged, "a") as f:
        del f["velocity"]
    with pytest.raises(ResultFileError, match="no dataset 'velocity'"):
        load(damaged)


def test_flipped_data_bytes_are_detected_by_the_checksum(controlled_result, tmp_path):
    """A bit flipped inside a stored array raises instead of returning a wrong number."""
    path = controlled_result.save(tmp_path / "run.h5")
    with h5py.File(path, "r") as f:
        offset = f["signals/m2.x"].id.get_chunk_info(0).byte_offset
    raw = bytearray(path.read_bytes())
    raw[offset + 8] ^= 0xFF
    path.write_bytes(bytes(raw))
    with pytest.raises(ResultFileError, match="corrupted"):
        load(path)


def test_docs_examples_run(tmp_path, monkeypatch):
    """Every ``python`` block of docs/results.md runs, in order, in one namespace."""
    import re
    from pathlib import Path

    import matplotlib
    matplotlib.use("Agg")
    text = (Path(__file__).resolve().parents[1] / "docs" / "results.md").read_text()
    blocks = re.findall(r"```python\n(.*?)```", text, flags=re.S)
    assert len(blocks) == 4
    monkeypatch.chdir(tmp_path)
    namespace: dict = {}
    for block in blocks:
        exec(compile(block, "docs/results.md", "exec"), namespace)  # noqa: S102
    assert namespace["unit"] == "m" and namespace["info"]["dt"] == 0.01
    assert namespace["elements"][2]["parameters"]["mass"] == 1.0


def test_short_signal_list_keeps_every_signal_readable(controlled_result, tmp_path):
    """With ``signals=[...]`` only those datasets are written; the rest comes from the raw arrays."""
    path = controlled_result.save(tmp_path / "short.h5", signals=["m2.x"])
    with h5py.File(path, "r") as f:
        assert sorted(f["signals"]) == ["m2.x", "pd.u", "pd.y"]   # loop signals are not in the raw arrays
    loaded = load(path)
    assert_same_simulation(controlled_result, loaded)
    for name in ("k2.in.f", "k2.out.x", "tip.in.v", "wall.out.x_ddot"):
        np.testing.assert_array_equal(loaded[name], controlled_result[name])
    again = load(loaded.save(tmp_path / "again.h5"))              # a loaded result saves with its model
    assert_same_simulation(controlled_result, again)
    assert again.system.description["elements"] == loaded.system.description["elements"]
    assert again.system.description["elements"][2]["parameters"]["mass"] == 1.0
    with pytest.raises(ModelError, match="unknown signal 'm9.x'"):
        controlled_result.save(tmp_path / "bad.h5", signals=["m9.x"])
    one = controlled_result.save(tmp_path / "one.h5", signals="m2.x")     # one name as a string, not its letters
    with h5py.File(one, "r") as f:
        assert sorted(f["signals"]) == ["m2.x", "pd.u", "pd.y"]


def test_special_floats_round_trip_bit_for_bit(controlled_result, tmp_path):
    """NaN, infinities, signed zero and subnormals (a diverged partial run) come back bit for bit."""
    special = np.array([np.nan, np.inf, -np.inf, -0.0, 5e-324, np.finfo(float).max, 1.0 / 3.0])
    states = controlled_result.states.copy()
    states[: len(special), 0, 0] = special
    odd = SimulationResult(controlled_result.time, states, controlled_result.velocity,
                           controlled_result.acceleration, controlled_result.system, "newmark",
                           {"error_estimate_m": 1.0 / 3.0, "tolerance": 5e-324, "note": "json:not json"},
                           dict(controlled_result.extra))
    loaded = load(odd.save(tmp_path / "odd.h5"))
    np.testing.assert_array_equal(loaded.states.view(np.uint64), states.view(np.uint64))
    assert loaded.info["error_estimate_m"] == 1.0 / 3.0 and loaded.info["tolerance"] == 5e-324
    assert loaded.info["note"] == "json:not json"


def test_damaged_provenance_text_is_refused(controlled_result, tmp_path):
    path = controlled_result.save(tmp_path / "run.h5")
    with h5py.File(path, "a") as f:
        f.attrs["info"] = "json:{broken"
    with pytest.raises(ResultFileError, match="not valid JSON"):
        load(path)


def test_frequency_response_carries_units_of_loop_signals():
    """frequency_response fills the units (loop sensor unit from its sensor, actuator force) and info."""
    import ctmm
    from ctmm.control import ControlledChain, Feedback
    from ctmm.elements import Fixed, Free, Mass, Spring

    chain = ctmm.Chain("s", [Fixed("w"), Spring("k", 100.0), Mass("m", 1.0), Free("e")])
    system = ControlledChain(chain, [Feedback("L", sensor="m.v", actuator="m", gain=1.0)])
    frf = ctmm.frequency_response(system, [1.0, 2.0], input="m.force", output=["L.y", "L.u", "k.f"])
    assert frf.units == {"m.force": "N", "L.y": "m/s", "L.u": "N", "k.f": "N"}
    assert frf.info["solver"] == "riccati" and frf.info["n_frequencies"] == 2
