"""Results whose every signal is stored by name: planar and flexible models in :func:`ctmm.simulate`.

A 1-D chain's :class:`~ctmm.results.SimulationResult` reads most signals from its raw point
arrays; a planar model has no 1-D connection points, so its result keeps every signal
(coordinates, rates, requested sensors, loop signals, controller samples) by name in
``result.extra`` and its system is a :class:`SignalSystem` that knows the model and the units.
Plots, data frames and saving/loading work unchanged.
"""
from __future__ import annotations

from typing import Any, Sequence

import numpy as np

from .errors import ModelError, unknown_name
from .results import SimulationResult
from .system import Signal

__all__ = ["SignalSystem", "signal_result", "coordinate_histories", "energy_history"]


class SignalSystem:
    """The system of a result whose every signal is stored by name.

    Parameters
    ----------
    model : object
        The simulated model (e.g. a :class:`~ctmm.planar.model.PlanarModel`), kept as :attr:`model`.
    units : dict
        ``{signal name: unit}`` of every signal of the result (``""``: unknown).
    loops : sequence, optional
        The closed feedback loops (listed in the saved description).
    """

    def __init__(self, model: Any, units: dict[str, str], loops: Sequence[Any] = ()) -> None:
        self.model = model
        self.name = getattr(model, "name", "")
        self.stored_units = dict(units)
        self.loops = tuple(loops)
        self.model_type = type(model).__name__

    @property
    def elements(self) -> tuple:
        """The model's elements (their numeric parameters are saved with the result)."""
        return tuple(getattr(self.model, "elements", ()))

    @property
    def n_points(self) -> int:
        """0: the model has no 1-D connection points."""
        return 0

    def point_names(self) -> list[str]:
        """No 1-D connection points (an empty list)."""
        return []

    def signal_names(self) -> list[str]:
        """Names of the signals of the result."""
        return list(self.stored_units)

    def signal(self, name: str) -> Signal:
        """Every signal is stored by name, so a name not in the result is unknown (raises)."""
        raise unknown_name("signal", name, list(self.stored_units))

    def __repr__(self) -> str:
        return f"SignalSystem({self.name!r}, {len(self.stored_units)} signals)"


def signal_result(system: SignalSystem, time: np.ndarray, signals: dict[str, np.ndarray], method: str = "",
                  info: dict | None = None) -> SimulationResult:
    """A :class:`~ctmm.results.SimulationResult` holding ``signals`` by name.

    Parameters
    ----------
    system : SignalSystem
        The simulated model and the units of the signals.
    time : ndarray
        Times [s], shape ``(n_rows,)``.
    signals : dict
        ``{name: values}``: one value per time row, or ``(n, 2)`` rows of (time [s], value) for
        ``"<output>@samples"`` records of sampled controllers.
    method : str
        Integrator used (the result's ``scheme_name``).
    info : dict, optional
        Provenance (dt [s], wall time [s], evaluations, ...), saved with the result.

    Returns
    -------
    SimulationResult
        With empty raw point arrays (shape ``(n_rows, 0, 0)``) and every signal in ``extra``.
    """
    time = np.asarray(time, dtype=float)
    empty = np.zeros((len(time), 0, 0))
    return SimulationResult(time, empty, empty.copy(), empty.copy(), system, method, dict(info or {}),
                            dict(signals))


def _planar_model(result: SimulationResult, what: str) -> Any:
    """The planar model of a result of :func:`ctmm.simulate` on a planar model, else :class:`ModelError`."""
    model = getattr(result.system, "model", None)
    if not isinstance(result, SimulationResult) or not hasattr(model, "coordinates"):
        raise ModelError(f"{what} needs the SimulationResult of ctmm.simulate on a planar or flexible model, "
                         f"got {type(result).__name__} of {type(getattr(result, 'system', None)).__name__}")
    return model


def coordinate_histories(result: SimulationResult) -> tuple[np.ndarray, np.ndarray]:
    """Coordinates and rates of a planar run as two arrays.

    Parameters
    ----------
    result : SimulationResult
        Of :func:`ctmm.simulate` on a planar or flexible model.

    Returns
    -------
    q, qdot : ndarray, shape (n_rows, n_coordinates)
        Columns ordered as ``model.coordinates`` [m, rad, modal] and their rates [m/s, rad/s]:
        the signals ``"<coordinate>"`` and ``"<coordinate>_dot"``.

    Raises
    ------
    ModelError
        ``result`` is not the result of a planar run.
    """
    model = _planar_model(result, "coordinate_histories")
    n_rows = len(result.time)
    q = np.array([result[name] for name in model.coordinates], dtype=float).reshape(-1, n_rows).T
    qdot = np.array([result[name + "_dot"] for name in model.coordinates], dtype=float).reshape(-1, n_rows).T
    return q, qdot


def energy_history(result: SimulationResult) -> np.ndarray:
    """Total mechanical energy [J] of a planar run at every stored time
    (:meth:`~ctmm.planar.model.PlanarModel.energy`).

    Raises
    ------
    ModelError
        ``result`` is not the result of a planar run.
    """
    model = _planar_model(result, "energy_history")
    q, qdot = coordinate_histories(result)
    return np.array([model.energy(qk, vk, float(tk)) for tk, qk, vk in zip(result.time, q, qdot)])
