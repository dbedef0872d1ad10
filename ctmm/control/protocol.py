"""The controller protocol used by the time stepper and the co-simulation master.

A controller reads named measured signals (ctmm signal names such as ``"m6.x"`` or
``"m6.v"``) and writes named actuator signals (such as ``"m2.force"``).  Controllers are
*descriptions*: all mutable data (internal states, an FMU instance, the last held output)
lives in the state object returned by :meth:`Controller.init` and threaded through
:meth:`Controller.step`.

Semantics of one call ``u, state = controller.step(t, y, state)``:

* ``y`` is a 1-D float array ordered like ``controller.inputs``: the measurements at time ``t``
  [units of each signal, SI].
* ``u`` is a 1-D float array ordered like ``controller.outputs``: the actuator values valid
  from ``t`` on.  With ``sample_time = h`` the stepper holds ``u`` (zero-order hold) on
  ``[t, t + h)``; with ``sample_time = None`` it calls ``step`` at every integrator step.
* If ``direct_feedthrough`` is True, ``u`` depends on ``y(t)`` at the same instant (e.g. a PD
  law).  The co-simulation master uses this flag to detect algebraic loops.
* The returned state is the controller state advanced to ``t + h`` (or to the next call).
"""
from __future__ import annotations

from typing import Any, Mapping, NamedTuple, Protocol, runtime_checkable

import numpy as np

from .. import validation
from ..errors import ModelError


class ControllerStep(NamedTuple):
    """Output of one controller call: actuator values and the advanced controller state."""

    outputs: np.ndarray
    state: Any


@runtime_checkable
class Controller(Protocol):
    """Protocol of a controller usable by :func:`ctmm.simulate`.

    Attributes
    ----------
    inputs : tuple of str
        Measured ctmm signal names read by the controller, in order.
    outputs : tuple of str
        Actuator signal names written by the controller, in order.
    sample_time : float or None
        Sample time [s] of a sampled controller (zero-order hold), or ``None`` for a
        controller evaluated at every integrator step.
    direct_feedthrough : bool
        Whether the outputs depend on the inputs at the same instant.
    """

    inputs: tuple[str, ...]
    outputs: tuple[str, ...]
    sample_time: float | None
    direct_feedthrough: bool

    def init(self, t0: float) -> Any:
        """Return the controller state at the start time ``t0`` [s]."""
        ...

    def step(self, t: float, y: np.ndarray, state: Any) -> ControllerStep:
        """Return the outputs valid from time ``t`` [s] and the advanced state."""
        ...


def check_controllers(controllers: Any) -> list:
    """Validate controller objects before a run (attributes only; outputs are checked per call).

    Parameters
    ----------
    controllers : sequence of Controller
        The controllers given to :func:`ctmm.control.simulate_controlled`.

    Returns
    -------
    list
        The controllers.

    Raises
    ------
    ModelError
        ``controllers`` is not a list/tuple, or a controller lacks a protocol member or has one
        of the wrong type (names the controller index, the member and the value).
    """
    if isinstance(controllers, Controller) and not isinstance(controllers, (list, tuple)):
        raise ModelError(f"controllers must be a list or tuple of controllers, got the controller "
                         f"{controllers!r}; pass [controller]")
    if not isinstance(controllers, (list, tuple)):
        raise ModelError(f"controllers must be a list or tuple of controllers, got {controllers!r}")
    for i, c in enumerate(controllers):
        where = f"controllers[{i}] = {c!r}"
        for member in ("init", "step"):
            if not callable(getattr(c, member, None)):
                raise ModelError(f"{where} must have a callable {member}() (the Controller protocol), "
                                 f"got {getattr(c, member, None)!r}")
        for member, minimum in (("inputs", 0), ("outputs", 1)):
            value = getattr(c, member, None)
            if not isinstance(value, (list, tuple)) or len(value) < minimum \
                    or not all(isinstance(n, str) for n in value):
                raise ModelError(f"{where}.{member} must be a tuple of signal names (str)"
                                 f"{', at least one' if minimum else ''}, got {value!r}")
        sample_time = getattr(c, "sample_time", None)
        if sample_time is not None:
            validation.positive(f"{where}.sample_time", sample_time)
        validation.flag(f"{where}.direct_feedthrough", getattr(c, "direct_feedthrough", None))
    return list(controllers)


def check_references(references: Any) -> dict:
    """Validate the ``references`` option of a controlled run (the loop names are checked later).

    Parameters
    ----------
    references : mapping or None
        ``{loop name: r(t)}`` reference signals [sensed unit].

    Returns
    -------
    dict
        The references (empty for ``None``).

    Raises
    ------
    ModelError
        ``references`` is not a mapping or ``None``, or a key is not a loop name (str).
    """
    if references is None:
        return {}
    if not isinstance(references, Mapping):
        raise ModelError(f"references must be a mapping {{loop name: reference signal}} or None, "
                         f"got {references!r}")
    for name in references:
        if not isinstance(name, str):
            raise ModelError(f"references must be keyed by loop names (str), got the key {name!r}")
    return dict(references)


def split_loop_references(loops: Any, inputs: Mapping[str, Any] | None, references: dict) -> tuple[dict, dict]:
    """Move ``"<loop>.reference"`` entries of ``inputs`` (the loop's input name in the frequency
    domain) to ``references``; the same loop in both is an error.

    Parameters
    ----------
    loops : sequence of Feedback
        The system's loops.
    inputs : mapping or None
        The run's ``inputs`` (actuator values and ``"<loop>.reference"`` entries).
    references : dict
        The run's checked ``references`` (:func:`check_references`).

    Returns
    -------
    tuple of dict
        ``(actuator inputs, references)``.
    """
    if not inputs:
        return {}, references
    names = {f"{loop.name}.reference": loop.name for loop in loops}
    actuators, references = {}, dict(references)
    for key, value in inputs.items():
        if key in names:
            if names[key] in references:
                raise ModelError(f"loop {names[key]!r} has a reference in both inputs[{key!r}] and references; "
                                 "give it once")
            references[names[key]] = value
        else:
            actuators[key] = value
    return actuators, references
