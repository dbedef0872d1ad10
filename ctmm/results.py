"""Result objects: named data with units, ``.plot()``, converters, and saving/loading to HDF5.

Units of signals come from :mod:`ctmm.signal_units`; the file format is described in
:mod:`ctmm.result_files` and ``docs/results.md``.
"""
from __future__ import annotations

import datetime
import os
from dataclasses import dataclass, field
from pathlib import Path
from typing import Any, Sequence

import numpy as np

from . import result_files, validation
from .errors import ModelError, unknown_name
from .signal_units import label as unit_label, signal_unit
from .system import Signal
from .version import __version__


def _axes(ax=None, nrows: int = 1):
    import matplotlib.pyplot as plt

    if ax is not None:
        return _axes_figure(ax), ax
    fig, axes = plt.subplots(nrows, 1, sharex=True, figsize=(7, 2.6 * nrows + 0.8), squeeze=False)
    return fig, axes[:, 0] if nrows > 1 else axes[0, 0]


def _axes_figure(ax: Any):
    """The figure of a user-given matplotlib Axes, or a ModelError naming ``ax``."""
    if not callable(getattr(ax, "plot", None)) or getattr(ax, "figure", None) is None:
        raise ModelError(f"ax must be a matplotlib Axes (or None for a new figure), got {ax!r}")
    return ax.figure


@dataclass
class FrequencyResponse:
    """Frequency response between named inputs and outputs.

    Attributes
    ----------
    omega : ndarray
        Angular frequencies [rad/s], shape ``(n_omega,)``.
    response : ndarray
        Complex responses, shape ``(n_outputs, n_inputs, n_omega)`` [output unit / input unit].
    inputs, outputs : tuple of str
        Signal names.
    system_name : str
        Name of the system the response belongs to.
    info : dict
        Provenance (method, solver, wall time [s], error figures, ...), saved with :meth:`save`.
    units : dict
        Units of inputs/outputs by name; others get :func:`ctmm.signal_units.signal_unit` of the name.
    """

    omega: np.ndarray
    response: np.ndarray
    inputs: tuple[str, ...]
    outputs: tuple[str, ...]
    system_name: str = ""
    info: dict = field(default_factory=dict)
    units: dict = field(default_factory=dict)

    def unit(self, name: str) -> str:
        """Unit of an input or output signal (``""`` if unknown)."""
        return self.units[name] if name in self.units else signal_unit(name)

    def response_unit(self, output: str, input: str) -> str:  # noqa: A002
        """Unit of ``H[output, input]``: output unit per input unit (``""`` if either is unknown)."""
        out, inp = self.unit(output), self.unit(input)
        if out == "1" and output.endswith(".L"):
            return "1"                      # a loop transfer function is dimensionless
        if not out or not inp:
            return ""
        if inp == "1":
            return out
        numerator = f"({out})" if "/" in out else out
        return f"{numerator}/({inp})" if "/" in inp or "*" in inp else f"{numerator}/{inp}"

    def __call__(self, output: str | None = None, input: str | None = None) -> np.ndarray:  # noqa: A002
        """Response array ``(n_omega,)`` for one output/input pair (defaults: the only one)."""
        i_out = self._index(self.outputs, output, "output")
        i_in = self._index(self.inputs, input, "input")
        return self.response[i_out, i_in]

    @staticmethod
    def _index(names: Sequence[str], name: str | None, kind: str) -> int:
        if name is None:
            if len(names) != 1:
                raise ModelError(f"this response has {len(names)} {kind}s; name the {kind}: one of "
                                 f"{', '.join(names) or '(none)'}")
            return 0
        if name not in names:
            raise unknown_name(kind, name, list(names))
        return list(names).index(name)

    @property
    def magnitude(self) -> np.ndarray:
        """``|H|`` with shape ``(n_outputs, n_inputs, n_omega)``."""
        return np.abs(self.response)

    @property
    def phase(self) -> np.ndarray:
        """Unwrapped phase [rad]."""
        return np.unwrap(np.angle(self.response), axis=-1)

    def to_control(self):
        """Convert to :class:`control.FrequencyResponseData` (MIMO if several inputs/outputs).

        python-control does not allow ``.`` in signal names: ``"m1.force"`` becomes ``"m1_force"``.  Its FRD
        needs ascending, distinct frequencies [rad/s]: ``omega`` is sorted and a repeated one kept once.
        """
        import control

        omega, first = np.unique(self.omega, return_index=True)
        clean = lambda names: [n.replace(".", "_") for n in names]  # noqa: E731
        return control.frd(self.response[..., first], omega, inputs=clean(self.inputs), outputs=clean(self.outputs),
                           name=(self.system_name or "ctmm").replace(".", "_").replace("+", "_"))

    def plot(self, ax=None, *, output: str | None = None, input: str | None = None,  # noqa: A002
             phase: bool = True, label: str | None = None):
        """Bode plot (magnitude in dB and phase in degrees) of one or all pairs.

        The magnitude axis is labelled ``magnitude [dB re 1 <output unit>/<input unit>]`` when all
        plotted pairs share a unit (each legend entry carries its unit otherwise), the phase axis ``phase [deg]``,
        the frequency axis ``angular frequency [rad/s]``. Returns the figure.
        """
        pairs = [(o, i) for o in self.outputs for i in self.inputs]
        if output is not None or input is not None:
            pairs = [(self.outputs[self._index(self.outputs, output, "output")] if output is not None
                      else self.outputs[0],
                      self.inputs[self._index(self.inputs, input, "input")] if input is not None else self.inputs[0])]
        if ax is None:
            fig, axes = _axes(nrows=2 if phase else 1)
            axes = list(np.atleast_1d(axes))
        else:
            axes = list(np.atleast_1d(ax))
            fig = [_axes_figure(a) for a in axes][0]
        pair_units = {(o, i): self.response_unit(o, i) for o, i in pairs}
        common = set(pair_units.values())
        shared = common.pop() if len(common) == 1 else None
        for o, i in pairs:
            h = self(o, i)
            lab = label or f"{i} -> {o}" + ("" if shared is not None or not pair_units[o, i]
                                           else f" [{pair_units[o, i]}]")
            axes[0].semilogx(self.omega, 20 * np.log10(np.abs(h) + 1e-300), label=lab)
            if phase and len(axes) > 1:
                axes[1].semilogx(self.omega, np.degrees(np.unwrap(np.angle(h))), label=lab)
        if shared == "1":
            axes[0].set_ylabel("magnitude [dB] (dimensionless)")
        elif shared:
            axes[0].set_ylabel(f"magnitude [dB re 1 {shared}]")
        elif shared is None:
            axes[0].set_ylabel("magnitude [dB re 1 (unit in legend)]")
        else:
            axes[0].set_ylabel("magnitude [dB, unit unknown]")
        axes[0].grid(True, which="both", alpha=0.3)
        axes[0].legend(fontsize=8)
        if phase and len(axes) > 1:
            axes[1].set_ylabel("phase [deg]")
            axes[1].grid(True, which="both", alpha=0.3)
        axes[-1].set_xlabel("angular frequency [rad/s]")
        return fig

    def save(self, path: str | os.PathLike) -> Path:
        """Save to an HDF5 result file, atomically (format in ``docs/results.md``, read back with :func:`load`).

        Stored: omega [rad/s], the complex response with input/output names and units, the system
        name and the provenance (ctmm version, creation time (UTC), :attr:`info`). Errors as for
        :meth:`SimulationResult.save`; a response whose shape does not match the names raises
        :class:`~ctmm.errors.ModelError`.
        """
        n_out, n_in = len(self.outputs), len(self.inputs)
        response = np.asarray(self.response)
        if response.shape != (n_out, n_in, len(self.omega)):
            raise ModelError(f"response has shape {response.shape}; expected (n_outputs, n_inputs, n_omega) = "
                             f"{(n_out, n_in, len(self.omega))}")
        datasets = {
            "omega": (np.asarray(self.omega), {"unit": "rad/s"}),
            "response": (response, {"axes": ["output", "input", "omega"], "inputs": list(self.inputs),
                                    "outputs": list(self.outputs),
                                    "input_units": [self.unit(n) for n in self.inputs],
                                    "output_units": [self.unit(n) for n in self.outputs]}),
        }
        attributes = _provenance(self.system_name, self.info)
        attributes["stored_units"] = {n: self.unit(n) for n in (*self.inputs, *self.outputs)}
        return result_files.write(path, "frequency_response", attributes, datasets)


@dataclass
class ModalResult:
    """Natural frequencies and mode shapes.

    Attributes
    ----------
    natural_frequencies : ndarray
        Undamped natural frequencies [rad/s], ascending (rigid-body modes as 0).
    shapes : ndarray or None
        Mode shapes at the connection points, shape ``(n_modes, n_points, n_components)``,
        normalised to unit largest displacement.
    components : tuple of str
        Layout component names of ``shapes``' last axis.
    """

    natural_frequencies: np.ndarray
    shapes: np.ndarray | None = None
    components: tuple[str, ...] = ()
    point_names: tuple[str, ...] = ()

    @property
    def frequencies_hz(self) -> np.ndarray:
        """Natural frequencies [Hz]."""
        return self.natural_frequencies / (2 * np.pi)

    def plot(self, ax=None, *, component: str | None = None, modes: Sequence[int] | None = None):
        """Plot mode shapes (displacement component) against the point index.

        Shapes are dimensionless (normalised to unit largest displacement): the y axis says so, the
        legend gives each mode's natural frequency [rad/s]. Returns the figure.
        """
        fig, ax = _axes(ax)
        if self.shapes is None:
            raise ValueError("no mode shapes stored; call mode_shapes()")
        if component is not None and component not in self.components:
            raise unknown_name("component", component, list(self.components))
        c = self.components.index(component) if component is not None else 0
        n_modes = len(self.natural_frequencies)
        modes = range(n_modes) if modes is None else validation.indices("modes", modes, n_modes)
        for k in modes:
            ax.plot(np.real(self.shapes[k, :, c]), marker="o",
                    label=f"mode {k + 1}: {self.natural_frequencies[k]:.4g} rad/s")
        ax.set_xlabel("connection point (index)")
        name = self.components[c] if self.components else "displacement"
        ax.set_ylabel(f"mode shape, {name} [1] (largest displacement = 1)")
        ax.legend(fontsize=8)
        ax.grid(True, alpha=0.3)
        return fig


@dataclass
class SimulationResult:
    """Time history of a DT-TMM simulation.

    Attributes
    ----------
    time : ndarray
        Times [s], shape ``(n_steps + 1,)``.
    states : ndarray
        States at all connection points, shape ``(n_steps + 1, n_points, n_components)``.
    velocity, acceleration : ndarray
        Time derivatives of the displacement components, shape ``(n_steps + 1, n_points, d)``.
    """

    time: np.ndarray
    states: np.ndarray
    velocity: np.ndarray
    acceleration: np.ndarray
    system: Any
    scheme_name: str = ""
    info: dict = field(default_factory=dict)
    extra: dict = field(default_factory=dict)

    @classmethod
    def empty(cls, system: Any, scheme_name: str = "") -> "SimulationResult":
        """A result with no time row (the partial result of a run that failed before ``t0``)."""
        layout = getattr(system, "plant", system).layout   # a controlled chain stores its plant's states
        n_points = system.n_points
        return cls(np.zeros(0), np.zeros((0, n_points, layout.size)), np.zeros((0, n_points, layout.half)),
                   np.zeros((0, n_points, layout.half)), system, scheme_name)

    def __getitem__(self, name: str) -> np.ndarray:
        """History of one signal by name, e.g. ``result["m1.x"]`` or ``result["loop.u"]``."""
        if not isinstance(name, str):
            raise unknown_name("signal", repr(name), self.signals())
        if name in self.extra:
            return self.extra[name]
        sig = self.system.signal(name)
        if sig.derivative == 0:
            return self.states[:, sig.point, sig.component]
        store = self.velocity if sig.derivative == 1 else self.acceleration
        return store[:, sig.point, sig.component]

    def signals(self) -> list[str]:
        """Available signal names."""
        return sorted(set(self.system.signal_names()) | set(self.extra))

    def unit(self, name: str) -> str:
        """Unit of a signal (``"m"`` for ``"m6.x"``, ``"N"`` for ``"loop.u"``; ``""`` if unknown)."""
        return signal_unit(name, self.system)

    def units(self, names: str | Sequence[str] | None = None) -> dict[str, str]:
        """Units of the named signals (a name or names; default: all time-grid signals), ``{name: unit}``."""
        return {n: self.unit(n) for n in (self.time_signals() if names is None else validation.names("names", names))}

    def time_signals(self) -> list[str]:
        """Signals sampled on :attr:`time` (one value per time row); the default of exports.

        Controller outputs sampled at their own rate (``"<output>@samples"``, rows ``(t, value)``)
        are not on the grid; read them with ``result[name]``.
        """
        n = len(self.time)
        names = []
        for name in self.signals():
            try:
                values = self[name]
            except (ModelError, IndexError):   # e.g. a loop signal of a run that failed before t0
                continue
            if np.ndim(values) == 1 and len(values) == n:
                names.append(name)
        return names

    def to_dataframe(self, names: Sequence[str] | None = None, *, units_in_names: bool = False):
        """A pandas DataFrame of signals indexed by time [s].

        Parameters
        ----------
        names : sequence of str, optional
            Signals to include (default: every signal on the time grid, :meth:`time_signals`).
        units_in_names : bool
            Name columns ``"m6.x [m]"`` instead of ``"m6.x"``.

        Returns
        -------
        pandas.DataFrame
            One float64 column per signal, values identical to ``result[name]``; index ``"time [s]"``;
            ``df.attrs["units"]`` maps column names to units, ``df.attrs["provenance"]`` holds
            system name, scheme and :attr:`info`.

        Raises
        ------
        ImportError
            pandas is not installed (``pip install 'ctmm[data]'``).
        UnknownNameError
            A name is not a signal of the result.
        """
        try:
            import pandas as pd
        except ImportError as exc:
            raise ImportError("SimulationResult.to_dataframe needs pandas, an optional dependency of ctmm: "
                              "pip install 'ctmm[data]' (or pip install pandas)") from exc
        units_in_names = validation.flag("units_in_names", units_in_names)
        if names is not None and (isinstance(names, (str, bytes, dict)) or not hasattr(names, "__iter__")):
            raise ModelError(f"names must be a sequence of signal names or None, got {names!r}")
        names = self.time_signals() if names is None else list(names)
        n = len(self.time)
        columns, units = {}, {}
        for name in names:
            values = self[name]
            if np.ndim(values) != 1 or len(values) != n:
                raise ModelError(f"signal {name!r} has shape {np.shape(values)}, not one value per time row "
                                 f"({n}); read it with result[{name!r}]")
            column = unit_label(name, self.unit(name)) if units_in_names else name
            columns[column] = values
            units[column] = self.unit(name)
        frame = pd.DataFrame(columns, index=pd.Index(self.time, name="time [s]"))
        frame.attrs["units"] = units
        frame.attrs["provenance"] = {"system": getattr(self.system, "name", ""), "scheme": self.scheme_name,
                                     **self.info}
        return frame

    def plot(self, *names: str, ax=None):
        """Plot the named signals against time; returns the figure.

        Axes are labelled with units: ``"time [s]"`` and ``"m6.x [m]"`` (several signals: their
        names joined, with one unit if they share it, otherwise the unit of each in the label and
        the legend).
        """
        if not names:
            raise ModelError(f"names: give at least one signal name to plot, got {names!r}; e.g. "
                             f"result.plot({(self.signals() or ['m.x'])[0]!r})")
        for n in names:
            self[n]                          # UnknownNameError listing the signals, before a figure opens
        fig, ax = _axes(ax)
        units = [self.unit(n) for n in names]
        shared = len(set(units)) == 1
        for n, unit in zip(names, units):
            ax.plot(self.time, self[n], label=n if shared else unit_label(n, unit))
        ax.set_ylabel(unit_label(", ".join(names), units[0]) if shared
                      else ", ".join(unit_label(n, u) for n, u in zip(names, units)))
        ax.set_xlabel("time [s]")
        ax.grid(True, alpha=0.3)
        ax.legend(fontsize=8)
        return fig

    def animate(self, path: str | os.PathLike, **options: Any) -> Path:
        """Animate a planar or spatial run into a GIF or MP4 file (:func:`ctmm.animation.animate`, its options)."""
        from .animation import animate
        return animate(self, path, **options)

    def save(self, path: str | os.PathLike, signals: Sequence[str] | None = None) -> Path:
        """Save the whole result to an HDF5 file, written atomically (temporary file + ``os.replace``).

        Stored: time [s], the raw ``states``/``velocity``/``acceleration`` arrays with the map from every signal name
        to them, signals by name with their unit (``/signals/<name>``), the system's element parameters, and the
        provenance (ctmm version, creation time (UTC), system name, scheme, :attr:`info`: dt, wall time, error
        figures, failure time of a partial result). Format: ``docs/results.md``; :func:`load` reads it back.

        Parameters
        ----------
        path : str or os.PathLike
            File name ending with ``.h5`` (or ``.hdf5``, ``.hdf``) in an existing folder.
        signals : sequence of str or str, optional
            Signals written as named datasets (default: all; a string is one name). Signals not listed stay readable
            after :func:`load` (from the raw arrays); loop signals and controller outputs, which are
            not in the raw arrays, are always written. Give a short list for large chains.

        Returns
        -------
        Path
            The written file.

        Raises
        ------
        ResultFileError
            Bad path (missing folder, a folder, another suffix).
        UnknownNameError
            A name in ``signals`` is not a signal of the result.
        ImportError
            h5py is not installed (``pip install 'ctmm[data]'``).
        """
        signal_map = _signal_map(self)
        available = [n for n in self.signals() if _available(self, n)]
        if signals is None:
            stored = available
        else:
            signals = [signals] if isinstance(signals, str) else list(signals)   # one name as a string: that name
            [self[name] for name in signals]    # raises UnknownNameError naming the available signals
            stored = list(dict.fromkeys([*signals, *(n for n in available if n not in signal_map)]))
        units = {n: self.unit(n) for n in dict.fromkeys([*signal_map, *available])}
        datasets: dict[str, tuple[np.ndarray, dict]] = {
            "time": (np.asarray(self.time), {"unit": "s"}),
            "states": (np.asarray(self.states), {"axes": ["time", "point", "component"]}),
            "velocity": (np.asarray(self.velocity), {"axes": ["time", "point", "displacement component"]}),
            "acceleration": (np.asarray(self.acceleration), {"axes": ["time", "point", "displacement component"]}),
        }
        for name in stored:
            values = np.asarray(self[name])
            meta: dict[str, Any] = {"unit": units[name]}
            if values.ndim == 2 and values.shape[1:] == (2,):
                meta["columns"] = ["time [s]", unit_label("value", units[name])]
            datasets[f"signals/{name}"] = (values, meta)
        groups = {"signals": {"names": stored}, "system": {**_system_description(self.system),
                                                           "signal_map": signal_map}}
        attributes = _provenance(getattr(self.system, "name", ""), self.info)
        attributes["scheme"] = self.scheme_name
        attributes["stored_units"] = units
        return result_files.write(path, "simulation", attributes, datasets, groups)


def _signal_map(result: SimulationResult) -> dict[str, list[int]]:
    """``{name: [point, component, derivative order]}`` of every signal read from the raw arrays."""
    mapping = {}
    for name in result.system.signal_names():
        if name in result.extra:
            continue
        try:
            signal = result.system.signal(name)
        except ModelError:
            continue
        width = (result.states if signal.derivative == 0 else result.velocity).shape[-1]
        if signal.derivative in (0, 1, 2) and 0 <= signal.component < width:
            mapping[name] = [int(signal.point), int(signal.component), int(signal.derivative)]
    return mapping


def _system_description(system: Any) -> dict[str, Any]:
    """Name, type, points, components, element parameters and loops of the simulated system."""
    stored = getattr(system, "description", None)
    if isinstance(system, StoredSystem) and stored:     # re-saving a loaded result keeps its model
        return {k: v for k, v in stored.items() if k != "signal_map"}
    layout = getattr(getattr(system, "plant", system), "layout", None)
    return {"name": getattr(system, "name", ""), "type": getattr(system, "model_type", type(system).__name__),
            "point_names": list(system.point_names()) if hasattr(system, "point_names") else [],
            "components": list(getattr(layout, "components", ())),
            "elements": _element_parameters(system),
            "loops": [repr(lp) for lp in getattr(system, "loops", ()) or ()]}


def _available(result: SimulationResult, name: str) -> bool:
    try:
        result[name]
    except (ModelError, IndexError):
        return False
    return True


def _element_parameters(system: Any) -> list[dict]:
    """Type, repr and numeric parameters of every element (the model as it was simulated)."""
    described = []
    for element in getattr(system, "elements", ()):
        numbers = {k: v for k, v in vars(element).items()
                   if not k.startswith("_") and isinstance(v, (int, float, np.floating, np.integer))
                   and not isinstance(v, bool)}
        described.append({"name": getattr(element, "name", ""), "type": type(element).__name__,
                          "repr": repr(element), "parameters": numbers})
    return described


def _provenance(system_name: str, info: dict) -> dict[str, Any]:
    return {"ctmm_version": __version__, "created_utc": datetime.datetime.now(datetime.timezone.utc).isoformat(),
            "system_name": system_name, "info": dict(info)}


class StoredSystem:
    """The system of a loaded result: its name, points and signal names with units (no model).

    A loaded :class:`SimulationResult` has every signal dataset of the file in ``extra``; the
    other signals are read from the raw arrays through ``signal_map``. This object answers the
    name and unit questions (``signal_names()``, :func:`~ctmm.signal_units.signal_unit`) and
    refuses names that were not stored.

    Parameters
    ----------
    name : str
        System name.
    point_names : sequence of str
        Connection point names.
    stored_units : dict
        ``{signal name: unit}`` of every signal of the result.
    description : dict, optional
        The file's ``/system`` attributes (element parameters, loops, ``signal_map``).
    """

    def __init__(self, name: str, point_names: Sequence[str], stored_units: dict[str, str],
                 description: dict | None = None) -> None:
        self.name = name
        self._point_names = list(point_names)
        self.stored_units = dict(stored_units)
        self.description = dict(description or {})
        self.signal_map = {k: tuple(v) for k, v in self.description.get("signal_map", {}).items()}

    @property
    def n_points(self) -> int:
        """Number of connection points."""
        return len(self._point_names)

    def point_names(self) -> list[str]:
        """Names of the connection points as stored."""
        return list(self._point_names)

    def signal_names(self) -> list[str]:
        """Names of the stored signals."""
        return list(self.stored_units)

    def signal(self, name: str) -> Signal:
        """The place of a signal in the raw arrays (signals in ``extra`` are found there first)."""
        if name in self.signal_map:
            return Signal(name, *self.signal_map[name])
        parts = name.split(".") if isinstance(name, str) else []
        if len(parts) == 3 and parts[1] in ("in", "out") and self._point_names:
            # "<element>.in.<q>" / ".out.<q>": the element's inboard/outboard point (as in Chain.signal)
            elements = [p.split("|")[0] for p in self._point_names] + [self._point_names[-1].split("|")[-1]]
            places = {tuple(v[1:]) for k, v in self.signal_map.items() if k.rsplit(".", 1)[-1] == parts[2]}
            if parts[0] in elements and len(places) == 1:
                position = elements.index(parts[0])
                point = min(max(position - 1 if parts[1] == "in" else position, 0), self.n_points - 1)
                return Signal(name, point, *places.pop())
        raise unknown_name("signal (of a loaded result)", name, list(self.stored_units))

    def __repr__(self) -> str:
        return f"StoredSystem({self.name!r}, {len(self.stored_units)} signals)"


def load(path: str | os.PathLike) -> SimulationResult | FrequencyResponse:
    """Load a result saved by :meth:`SimulationResult.save` or :meth:`FrequencyResponse.save`.

    Arrays come back bit for bit; the provenance is in ``result.info`` (with ``ctmm_version``,
    ``created_utc``, ``format_version`` added); a simulation's system is a :class:`StoredSystem`.

    Raises
    ------
    ResultFileError
        No such file, not a ctmm result file, corrupted data, or a newer format version.
    ImportError
        h5py is not installed (``pip install 'ctmm[data]'``).
    """
    contents = result_files.read(path, ("simulation", "frequency_response"))
    attrs = contents.attributes
    info = dict(attrs.get("info", {}))
    stored_units = dict(attrs.get("stored_units", {}))
    info.update(ctmm_version=attrs.get("ctmm_version", ""), created_utc=attrs.get("created_utc", ""),
                format_version=contents.version)
    if contents.kind == "frequency_response":
        meta = contents.dataset_attributes.get("response", {})
        result_files.check_response_shape(contents, len(meta.get("outputs", ())), len(meta.get("inputs", ())))
        return FrequencyResponse(contents.dataset("omega"), contents.dataset("response"),
                                 tuple(meta.get("inputs", ())), tuple(meta.get("outputs", ())),
                                 attrs.get("system_name", ""), info, stored_units)
    system_attrs = contents.group_attributes.get("system", {})
    names = contents.group_attributes.get("signals", {}).get("names", [])
    extra = {name: contents.dataset(f"signals/{name}") for name in names}
    units = {n: stored_units.get(n, "") for n in dict.fromkeys([*system_attrs.get("signal_map", {}), *names])}
    system = StoredSystem(attrs.get("system_name", ""), system_attrs.get("point_names", []), units, system_attrs)
    result_files.check_time_grid(contents, extra)
    return SimulationResult(contents.dataset("time"), contents.dataset("states"), contents.dataset("velocity"),
                            contents.dataset("acceleration"), system, attrs.get("scheme", ""), info, extra)

