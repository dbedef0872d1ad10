"""Result objects: named data, ``.plot()`` and converters."""
from __future__ import annotations

from dataclasses import dataclass, field
from typing import Any, Sequence

import numpy as np

from .errors import unknown_name


def _axes(ax=None, nrows: int = 1):
    import matplotlib.pyplot as plt

    if ax is not None:
        return ax.figure, ax
    fig, axes = plt.subplots(nrows, 1, sharex=True, figsize=(7, 2.6 * nrows + 0.8), squeeze=False)
    return fig, axes[:, 0] if nrows > 1 else axes[0, 0]


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
    """

    omega: np.ndarray
    response: np.ndarray
    inputs: tuple[str, ...]
    outputs: tuple[str, ...]
    system_name: str = ""

    def __call__(self, output: str | None = None, input: str | None = None) -> np.ndarray:  # noqa: A002
        """Response array ``(n_omega,)`` for one output/input pair (defaults: the only one)."""
        i_out = self._index(self.outputs, output, "output")
        i_in = self._index(self.inputs, input, "input")
        return self.response[i_out, i_in]

    @staticmethod
    def _index(names: Sequence[str], name: str | None, kind: str) -> int:
        if name is None:
            if len(names) != 1:
                raise unknown_name(kind, "<none given>", list(names))
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

        python-control does not allow ``.`` in signal names: ``"m1.force"`` becomes ``"m1_force"``.
        """
        import control

        data = self.response if self.response.shape[:2] != (1, 1) else self.response[0, 0]
        clean = lambda names: [n.replace(".", "_") for n in names]  # noqa: E731
        return control.frd(data, self.omega, inputs=clean(self.inputs), outputs=clean(self.outputs),
                           name=(self.system_name or "ctmm").replace(".", "_").replace("+", "_"))

    def plot(self, ax=None, *, output: str | None = None, input: str | None = None,  # noqa: A002
             phase: bool = True, label: str | None = None):
        """Bode plot (magnitude in dB and phase in degrees) of one or all pairs.

        Returns the figure.
        """
        pairs = [(o, i) for o in self.outputs for i in self.inputs]
        if output is not None or input is not None:
            pairs = [(output or self.outputs[0], input or self.inputs[0])]
        if ax is None:
            fig, axes = _axes(nrows=2 if phase else 1)
            axes = list(np.atleast_1d(axes))
        else:
            axes = list(np.atleast_1d(ax))
            fig = axes[0].figure
        for o, i in pairs:
            h = self(o, i)
            lab = label or f"{i} -> {o}"
            axes[0].semilogx(self.omega, 20 * np.log10(np.abs(h) + 1e-300), label=lab)
            if phase and len(axes) > 1:
                axes[1].semilogx(self.omega, np.degrees(np.unwrap(np.angle(h))), label=lab)
        axes[0].set_ylabel("magnitude [dB]")
        axes[0].grid(True, which="both", alpha=0.3)
        axes[0].legend(fontsize=8)
        if phase and len(axes) > 1:
            axes[1].set_ylabel("phase [deg]")
            axes[1].grid(True, which="both", alpha=0.3)
        axes[-1].set_xlabel("omega [rad/s]")
        return fig


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
        """Plot mode shapes (displacement component) against the point index."""
        fig, ax = _axes(ax)
        if self.shapes is None:
            raise ValueError("no mode shapes stored; call mode_shapes()")
        c = self.components.index(component) if component else 0
        for k in (modes if modes is not None else range(len(self.natural_frequencies))):
            ax.plot(np.real(self.shapes[k, :, c]), marker="o",
                    label=f"mode {k + 1}: {self.natural_frequencies[k]:.4g} rad/s")
        ax.set_xlabel("connection point")
        ax.set_ylabel(self.components[c] if self.components else "shape")
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

    def to_dataframe(self, names: Sequence[str]):
        """A pandas DataFrame of the named signals indexed by time (pandas optional)."""
        import pandas as pd  # optional dependency

        return pd.DataFrame({n: self[n] for n in names}, index=pd.Index(self.time, name="t [s]"))

    def plot(self, *names: str, ax=None):
        """Plot the named signals against time; returns the figure."""
        fig, ax = _axes(ax)
        for n in names:
            ax.plot(self.time, self[n], label=n)
        ax.set_xlabel("t [s]")
        ax.grid(True, alpha=0.3)
        ax.legend(fontsize=8)
        return fig
