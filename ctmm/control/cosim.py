"""Co-simulation master: sampled controllers with zero-order hold (controller objects and FMUs).

One class, :class:`CoSimulation`, drives the :class:`~ctmm.control.protocol.Controller` objects
of every time stepper of the package (the controlled chains of :mod:`ctmm.control.simulate` and
the planar models of :mod:`ctmm.control.planar_time`).  The stepper owns the physics -- which
signal a name reads and where an output acts -- and the master owns the timing:

* a controller is sampled at the steps ``n`` that are multiples of ``sample_time / dt`` (a whole
  number; ``sample_time=None``: every step), at most once per step, and its outputs are held
  until its next sample (zero-order hold);
* a controller with direct feedthrough that reads a signal depending on its own output at the
  same instant (an acceleration or an internal force of a chain) forms an algebraic loop: it is
  refused (:class:`~ctmm.errors.ModelError`) unless ``coupling="previous"`` accepts the
  one-sample lag;
* controller code that raises, returns something else than ``(outputs, state)``, the wrong
  number of outputs or a non-finite value stops the run with a
  :class:`~ctmm.errors.SimulationError` naming the controller and the time (:mod:`ctmm.guard`);
* every sample is recorded (``"<output>@samples"``: sample time [s], value).

Every stepper gets one wiring rule, :func:`check_wiring`, run by :class:`CoSimulation` itself: unknown
signal or actuator names (when the stepper passes its ``signals`` / ``actuators``), an actuator
written by two controllers (refused on every path -- chains, planar, spatial, numpy and generated --
never added) and sample times off the step grid are refused together, one per line.  The held outputs
are read by actuator name with :meth:`CoSimulation.held_values`.
"""
from __future__ import annotations

from typing import Any, Callable, Collection, Sequence, Union

import numpy as np

from ..errors import ModelError, SimulationError, unknown_name
from ..guard import call_user, user_output

__all__ = ["COUPLINGS", "CoSimulation", "sample_ratio", "check_wiring"]

COUPLINGS = ("hold", "previous")


def sample_ratio(sample_time: float | None, dt: float) -> int:
    """Steps per sample of a controller: ``sample_time / dt`` as a whole number >= 1.

    Parameters
    ----------
    sample_time : float or None
        The controller's sample time [s]; ``None``: every step.
    dt : float
        Time step [s].

    Raises
    ------
    ModelError
        ``sample_time`` is not a whole multiple of ``dt``.
    """
    if sample_time is None:
        return 1
    ratio = float(sample_time) / dt
    if abs(ratio - round(ratio)) > 1e-9 * ratio or round(ratio) < 1:
        raise ModelError(f"sample_time {sample_time!r} must be a whole multiple of dt = {dt!r} (both in s)")
    return int(round(ratio))


NameCheck = Union[Sequence[str], Callable[[str], Any], None]
"""The names a stepper accepts: a sequence of names, a look-up ``check(name)`` that raises
:class:`~ctmm.errors.ModelError` for a name it refuses (e.g. ``Chain.signal``), or ``None`` (the stepper
checks the names itself)."""


def _name_problem(check: NameCheck, name: str, what: str) -> str | None:
    """Why ``name`` is refused by ``check`` (:data:`NameCheck`), or ``None``."""
    if check is None:
        return None
    if callable(check):
        try:
            check(name)
        except ModelError as exc:
            return f"{what}: {exc}"
        return None
    return None if name in check else str(unknown_name(what, name, list(check)))


def check_wiring(controllers: Sequence[Any], signals: NameCheck, actuators: NameCheck, dt: float, *,
                 what: str = "controllers") -> set[str]:
    """Check that controllers fit a stepper with named signals and actuators; all problems at once.

    The one wiring rule of every co-simulation path (:class:`CoSimulation` runs it): each input a
    signal of the stepper, each output an actuator of the stepper written by **one** controller only
    (two controllers on one actuator are refused, not added), each sample time a whole multiple of ``dt``.

    Parameters
    ----------
    controllers : sequence of Controller
        Controllers with ``inputs``, ``outputs`` and ``sample_time`` (protocol members already
        validated, e.g. by :func:`~ctmm.control.protocol.check_controllers`).
    signals : sequence of str, callable or None
        The signal names a controller may read (:data:`NameCheck`; ``None``: not checked here).
    actuators : sequence of str, callable or None
        The actuator names a controller may write (:data:`NameCheck`; ``None``: not checked here).
    dt : float
        Time step [s] of the stepper (sample times must be whole multiples of it).
    what : str
        How the controllers are named in the message (e.g. ``"manipulator controllers"``).

    Returns
    -------
    set of str
        The actuator names written by the controllers.

    Raises
    ------
    ModelError
        Unknown input or output names (listing the available ones), an actuator written by two
        controllers, or a sample time that is not a whole multiple of ``dt``: every problem, one per line.
    """
    written: dict[str, int] = {}
    problems = []
    for i, c in enumerate(controllers):
        for name in c.inputs:
            problem = _name_problem(signals, name, f"input of controller {i}")
            if problem:
                problems.append(problem)
        for name in c.outputs:
            problem = _name_problem(actuators, name, f"output of controller {i}")
            if problem:
                problems.append(problem)
            if name in written:
                problems.append(f"{name!r} is written by controllers {written[name]} and {i} (each actuator by one "
                                "controller: combine their outputs in one controller)")
            written[name] = i
        try:
            sample_ratio(getattr(c, "sample_time", None), dt)
        except ModelError as exc:
            problems.append(f"controller {i}: {exc}")
    if problems:
        raise ModelError(f"{what} are invalid:\n  - " + "\n  - ".join(problems))
    return set(written)


def default_label(controller: Any) -> str:
    """``"controller '<name>' (outputs [...])"``: how a controller is named in messages."""
    name = getattr(controller, "name", None) or type(controller).__name__
    return f"controller {name!r} (outputs {list(controller.outputs)})"


class CoSimulation:
    """Sampled co-simulation master for controller objects and FMUs (zero-order hold).

    Parameters
    ----------
    controllers : sequence of Controller
        Controllers with ``inputs``, ``outputs``, ``sample_time``, ``init`` and ``step``
        (validated by the caller, e.g. :func:`~ctmm.control.protocol.check_controllers`).
    dt : float
        Time step [s] of the stepper.
    t0 : float
        Start time [s]: every controller's ``init(t0)`` is called here.
    coupling : {"hold", "previous"}
        ``"hold"``: algebraic loops are errors; ``"previous"``: accept their one-sample lag.
    instantaneous : collection of str
        Signal names that depend on the controllers' outputs at the same instant (accelerations,
        internal forces); read by a controller with direct feedthrough they form an algebraic loop.
    labels : sequence of str, optional
        How each controller is named in messages (default :func:`default_label`).
    measurement_delays : bool
        Whether the stepper reads the inputs of a controller with a ``measurement_delay``
        (:class:`~ctmm.control.measurement_delay.DelayedController`) late; if not, such a
        controller is refused (it would read on time).
    signals, actuators : sequence of str, callable or None
        The stepper's signal and actuator names for :func:`check_wiring` (:data:`NameCheck`;
        ``None``: the stepper checks the names itself).

    Raises
    ------
    ModelError
        The wiring (:func:`check_wiring`: unknown names, an actuator written by two controllers, a
        sample time that is not a whole multiple of ``dt``), an algebraic loop, a bad ``coupling``,
        a measurement delay the stepper does not apply.
    SimulationError
        A controller's ``init`` failed (controllers already started are closed).
    """

    def __init__(self, controllers: Sequence[Any], dt: float, t0: float, *, coupling: str = "hold",
                 instantaneous: Collection[str] = (), labels: Sequence[str] | None = None,
                 measurement_delays: bool = False, signals: NameCheck = None,
                 actuators: NameCheck = None) -> None:
        if coupling not in COUPLINGS:
            raise ModelError(f"coupling must be 'hold' or 'previous', got {coupling!r}")
        check_wiring(controllers, signals, actuators, dt)
        delayed = [c for c in controllers if getattr(c, "measurement_delay", 0.0)]
        if delayed and not measurement_delays:
            raise ModelError(f"{delayed[0]!r} declares a measurement delay, which this stepper does not apply (it "
                             "would be dropped); close a delayed measurement as a Feedback loop with delay=..., or "
                             "simulate a planar model with ctmm.simulate")
        self.controllers = list(controllers)
        self.dt = dt
        self.t0 = t0
        self.coupling = coupling
        self.labels = list(labels) if labels is not None else [default_label(c) for c in self.controllers]
        self.ratios = [sample_ratio(getattr(c, "sample_time", None), dt) for c in self.controllers]
        for c in self.controllers:
            algebraic = [n for n in c.inputs if n in instantaneous]
            if getattr(c, "direct_feedthrough", False) and algebraic and coupling != "previous":
                raise ModelError(
                    f"algebraic loop: controller with outputs {list(c.outputs)} has direct feedthrough and "
                    f"reads {algebraic}, which depend on its own output at the same instant; pass "
                    "coupling='previous' to accept a one-sample lag, or measure displacement/velocity")
        self.states: list[Any] = []
        try:
            for c, label in zip(self.controllers, self.labels):
                self.states.append(call_user(label, c.init, t0, time=t0))
        except SimulationError:
            self.close()
            raise
        self.held = [np.zeros(len(c.outputs)) for c in self.controllers]
        self._last_step = [None] * len(self.controllers)
        self._log_t: list[list[float]] = [[] for _ in self.controllers]
        self._log_u: list[list[np.ndarray]] = [[] for _ in self.controllers]

    def __len__(self) -> int:
        return len(self.controllers)

    def sample(self, step: int, t: float, measure: Callable[[int], np.ndarray]) -> list[int]:
        """Sample the controllers due at step ``step`` (time ``t`` [s]); returns their indices.

        Parameters
        ----------
        step : int
            Step number from the start (0 at ``t0``); a controller is due when it is a multiple
            of its sample ratio and it was not sampled at this step yet.
        t : float
            Time of the step [s].
        measure : callable
            ``measure(i) -> y``: the inputs of controller ``i`` at ``t`` (called only when due).

        Raises
        ------
        SimulationError
            Failing controller code, named with the time (:mod:`ctmm.guard`).
        """
        sampled = []
        for i, c in enumerate(self.controllers):
            if step % self.ratios[i] or self._last_step[i] == step:
                continue
            self._last_step[i] = step
            what = self.labels[i]
            result = call_user(what, c.step, t, measure(i), self.states[i], time=t)
            if not isinstance(result, (tuple, list)) or len(result) != 2:
                raise SimulationError(f"{what} returned {result!r} at t = {t:.6g} s; expected "
                                      "(outputs, state), e.g. a ControllerStep", time=float(t), element=what)
            u = user_output(what, result[0], len(c.outputs), time=t)
            self.states[i] = result[1]
            self.held[i] = u
            self._log_t[i].append(t)
            self._log_u[i].append(u.copy())
            sampled.append(i)
        return sampled

    def held_values(self, names: Sequence[str]) -> np.ndarray:
        """The held output for each actuator in ``names``: the last sample of the controller that
        writes it, ``0.0`` where no controller writes it (each name written once: :func:`check_wiring`).
        """
        held = {name: value for c, u in zip(self.controllers, self.held) for name, value in zip(c.outputs, u)}
        return np.array([held.get(name, 0.0) for name in names], dtype=float)

    def outputs(self, until: float | None = None) -> dict[str, np.ndarray]:
        """Recorded samples ``{"<output>@samples": (n, 2) array of (time [s], value)}``.

        ``until``: keep the samples at times <= ``until`` (a partial result's last time).
        """
        records = {}
        for i, c in enumerate(self.controllers):
            if not self._log_t[i]:
                continue
            u = np.array(self._log_u[i])
            for k, name in enumerate(c.outputs):
                samples = np.column_stack([self._log_t[i], u[:, k]])
                records[f"{name}@samples"] = samples if until is None else samples[samples[:, 0] <= until]
        return records

    def close(self) -> None:
        """Release controller resources (e.g. FMU instances) deterministically; never raises."""
        for c, state in zip(self.controllers, self.states):
            closer = getattr(c, "close", None)
            if callable(closer):
                try:
                    closer(state)
                except Exception:  # noqa: BLE001 - a failed cleanup must not hide the result
                    pass

    def describe(self) -> list[dict]:
        """``[{"outputs", "inputs", "sample_time" [s]}]`` per controller (for ``result.info``)."""
        return [{"outputs": list(c.outputs), "inputs": list(c.inputs), "sample_time": ratio * self.dt}
                for c, ratio in zip(self.controllers, self.ratios)]
