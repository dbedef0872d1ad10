"""Run guards shared by every simulator: divergence, step-size stability limits and user code.

Every time integrator in ctmm (the 1-D DT-TMM, the controlled stepper, the planar, flexible and
manipulator simulators) uses these three pieces, so that a run that goes wrong stops the same way
everywhere: with a :class:`~ctmm.errors.SimulationError` that names the time and the element or
coordinate, and that the caller completes with the result computed so far (``partial_result``).

Divergence
----------
:class:`DivergenceGuard` watches a vector of coordinates (displacements [m], angles [rad], modal
coordinates [-]) and stops the run when one is non-finite or when its distance from a reference
(the rest or initial configuration) exceeds ``bound``.  The default bound is
``growth * max(1, largest initial excursion)`` with ``growth = 1e6``: a physical model that moves
a million times further than it started (or a million metres / radians from rest) has diverged;
a run that should go further sets ``divergence_bound`` explicitly (``math.inf`` switches the
bound off, non-finite values are still caught).

Step-size stability limits
--------------------------
Known limits, checked before a run starts against the model's highest natural frequency
``omega_max`` [rad/s] (undamped, the worst case for these schemes):

* Newmark-beta with ``gamma >= 1/2``: unconditionally stable for ``2 beta >= gamma``; otherwise
  stable for ``omega_max h <= 1 / sqrt(gamma / 2 - beta)`` (Hughes, *The Finite Element Method*,
  §9.1, eq. 9.1.30 with zero damping).  ``gamma < 1/2`` amplifies every mode at any step
  (numerical negative damping).
* Wilson-theta: unconditionally stable for ``theta >= 1.37`` (Bathe & Wilson 1973); for
  ``1 <= theta < 1.37`` the spectral radius exceeds one at large ``omega h``: the limit is found
  from the amplification matrix (:func:`wilson_amplification`).
* Classical RK4 on an undamped mode: stable for ``omega_max h <= 2 sqrt 2`` (the stability
  region meets the imaginary axis at ``+-2 sqrt 2 i``).

:func:`check_step` turns a limit into a :class:`StabilityLimitWarning` (silence it with the
``warnings`` module or the simulator's option) or a :class:`~ctmm.errors.ModelError`.

User code
---------
:func:`call_user` runs a callback or controller and turns any exception into a
:class:`~ctmm.errors.SimulationError` naming the callback and the time; :func:`user_output`
checks what it returned (shape and finiteness).
"""
from __future__ import annotations

import math
import warnings
from dataclasses import dataclass
from typing import Any, Callable, Sequence

import numpy as np

from . import validation
from .errors import ModelError, SimulationError

__all__ = ["StabilityLimitWarning", "DivergenceGuard", "newmark_limit", "wilson_limit", "wilson_amplification", "RK4_LIMIT",
           "check_step", "call_user", "user_output", "UserFunction", "DEFAULT_GROWTH", "unstable_loops_hint"]

#: Largest ``omega h`` of classical RK4 on an undamped mode (imaginary-axis stability boundary).
RK4_LIMIT = 2.0 * math.sqrt(2.0)
#: Default growth factor of :class:`DivergenceGuard` over the initial excursion (or 1).
DEFAULT_GROWTH = 1e6


class StabilityLimitWarning(UserWarning):
    """A step size exceeds the known stability limit of the chosen scheme for this model."""


def newmark_limit(beta: float, gamma: float) -> float:
    """Largest stable ``omega h`` of Newmark-beta on an undamped mode.

    Parameters
    ----------
    beta, gamma : float
        Newmark parameters [-].

    Returns
    -------
    float
        ``inf`` when unconditionally stable (``2 beta >= gamma >= 1/2``), ``0`` when no step is
        stable (``gamma < 1/2``: every mode is amplified), else ``1 / sqrt(gamma/2 - beta)``.
    """
    beta, gamma = validation.finite("beta", beta), validation.finite("gamma", gamma)
    if beta < 0.0:
        raise ModelError(f"beta must be >= 0, got {beta!r}")
    if gamma < 0.5:
        return 0.0
    if 2.0 * beta >= gamma:
        return math.inf
    return 1.0 / math.sqrt(gamma / 2.0 - beta)


def wilson_amplification(theta: float, omega_h: float) -> np.ndarray:
    """Amplification matrix of Wilson-theta on ``x'' + omega^2 x = 0`` for the state ``(x, h v, h^2 a)``.

    One step: ``a_tau (1 + (omega tau)^2 / 6) = -omega^2 (x + tau v + tau^2 a / 3)`` at
    ``tau = theta h``, then ``a_{n+1} = a_n + (a_tau - a_n) / theta``,
    ``v_{n+1} = v_n + h (a_n + a_{n+1}) / 2``, ``x_{n+1} = x_n + h v_n + h^2 (2 a_n + a_{n+1}) / 6``.
    """
    theta = validation.positive("theta", theta)
    omega_h = validation.nonnegative("omega_h", omega_h)
    w2 = omega_h * omega_h
    columns = []
    for state in np.eye(3):
        x, hv, h2a = state
        a_tau = -w2 * (x + theta * hv + theta ** 2 * h2a / 3.0) / (1.0 + w2 * theta ** 2 / 6.0)
        a_new = h2a + (a_tau - h2a) / theta
        columns.append([x + hv + (2.0 * h2a + a_new) / 6.0, hv + 0.5 * (h2a + a_new), a_new])
    return np.array(columns).T


def wilson_limit(theta: float) -> float:
    """Largest stable ``omega h`` of Wilson-theta on an undamped mode.

    ``inf`` for ``theta >= 1.37`` (Bathe & Wilson 1973).  Below, the spectral radius of
    :func:`wilson_amplification` is scanned on a logarithmic grid of ``omega h`` up to ``1e8``
    and the first crossing of 1 is bisected to 1e-10 relative (``theta = 1``, the linear
    acceleration method, gives ``2 sqrt 3``).
    """
    theta = validation.positive("theta", theta)
    if theta >= 1.37:
        return math.inf

    def unstable(omega_h: float) -> bool:
        return float(np.max(np.abs(np.linalg.eigvals(wilson_amplification(theta, omega_h))))) > 1.0 + 1e-12

    grid = np.logspace(-2, 8, 401)
    crossing = next((k for k, value in enumerate(grid) if unstable(value)), None)
    if crossing is None:
        return math.inf
    low, high = (grid[crossing - 1] if crossing else 0.0), grid[crossing]
    while high - low > 1e-10 * high:
        middle = 0.5 * (low + high)
        low, high = (low, middle) if unstable(middle) else (middle, high)
    return float(low)


def _nonnegative_or_infinite(name: str, value: Any) -> float:
    if isinstance(value, (float, np.floating)) and value == math.inf:
        return math.inf
    return validation.nonnegative(name, value)


def check_step(what: str, omega_max: float, dt: float, limit: float, *, policy: str = "warn") -> str | None:
    """Compare ``omega_max * dt`` with a scheme's stability limit before a run.

    Parameters
    ----------
    what : str
        The scheme and its parameters, for the message (e.g. ``"Newmark(beta=0.01, gamma=0.5)"``).
    omega_max : float
        Highest natural frequency of the model [rad/s] (``inf`` if unbounded).
    dt : float
        Step size [s].
    limit : float
        Largest stable ``omega h`` of the scheme [-] (``inf``: unconditionally stable).
    policy : {"warn", "error", "ignore"}
        What to do when the limit is exceeded.

    Returns
    -------
    str or None
        The message, or ``None`` when the step is within the limit.
    """
    if policy not in ("warn", "error", "ignore"):
        raise ModelError(f"stability_check must be 'warn', 'error' or 'ignore', got {policy!r}")
    omega_max = _nonnegative_or_infinite("omega_max", omega_max)
    dt = validation.positive("dt", dt)
    limit = _nonnegative_or_infinite("limit", limit)
    if math.isinf(limit) or omega_max * dt <= limit:
        return None
    if limit == 0.0:
        message = (f"{what} is not stable at any step size for an undamped mode (highest natural "
                   f"frequency {omega_max:.6g} rad/s): the response will grow without bound")
    else:
        message = (f"{what} is only conditionally stable: omega_max * dt = {omega_max * dt:.4g} exceeds its "
                   f"limit {limit:.4g} (highest natural frequency {omega_max:.6g} rad/s); use dt <= "
                   f"{limit / omega_max:.4g} s or an unconditionally stable scheme")
    if policy == "error":
        raise ModelError(message)
    if policy == "warn":
        warnings.warn(message, StabilityLimitWarning, stacklevel=3)
    return message


def unstable_loops_hint(loop_names: Sequence[str]) -> str:
    """The hint a diverging run with feedback loops appends to its message (the numpy and the generated DT-TMM paths
    of chains say the same)."""
    names = list(loop_names)
    chosen = "" if len(names) == 1 else f", loop={names[0]!r}"       # several loops: the analysis names the one swept
    return (f"the closed loop(s) {names} may be unstable: check ctmm.stability.unstable_root_count(system{chosen}) "
            f"and ctmm.stability.delay_margin(system{chosen})")


@dataclass(frozen=True)
class DivergenceGuard:
    """Stops a run whose monitored coordinates go non-finite or leave a bound.

    Parameters
    ----------
    names : sequence of str
        Name of each monitored coordinate (element, point or coordinate name), for messages.
    reference : ndarray
        Values the distance is measured from (rest or initial configuration), same length.
    bound : float
        Largest allowed ``|value - reference|`` (in the coordinates' own units); ``inf`` checks
        only finiteness.
    hint : str
        Appended to the message when the bound is exceeded (e.g. which loops may be unstable).
    """

    names: tuple[str, ...]
    reference: np.ndarray
    bound: float
    hint: str = ""

    @classmethod
    def from_start(cls, names: Sequence[str], reference: Any, initial: Any, *, bound: float | None = None,
                   growth: float = DEFAULT_GROWTH, hint: str = "") -> "DivergenceGuard":
        """A guard whose default bound is ``growth * max(1, largest initial excursion)``.

        Parameters
        ----------
        names : sequence of str
            Coordinate names.
        reference : array_like
            Rest / reference values.
        initial : array_like
            Initial values (their excursion from ``reference`` sets the default scale).
        bound : float, optional
            Explicit bound (``> 0``, may be ``inf``); overrides the default.
        growth : float
            Growth factor of the default bound.
        hint : str
            Appended to divergence messages.
        """
        reference = np.asarray(reference, dtype=float).reshape(-1)
        initial = np.asarray(initial, dtype=float).reshape(-1)
        if bound is None:
            excursion = float(np.max(np.abs(initial - reference), initial=0.0))
            bound = growth * max(1.0, excursion)
        else:
            if isinstance(bound, bool) or not isinstance(bound, (int, float, np.floating, np.integer)) \
                    or math.isnan(bound) or bound <= 0:
                raise ModelError(f"divergence_bound must be a number > 0 (or math.inf), got {bound!r}")
            bound = float(bound)
        return cls(tuple(names), reference, bound, hint)

    def passes(self, values: Any) -> np.ndarray:
        """Whether :meth:`check` accepts each row of ``values`` (rows, coordinates): all finite and within the bound
        of the reference; for a block of stored rows at once (a ``False`` row is then given to :meth:`check`,
        which raises with its message)."""
        values = np.asarray(values, dtype=float)
        with np.errstate(invalid="ignore", over="ignore"):
            largest = np.max(np.abs(values - self.reference), axis=-1, initial=0.0)
            return np.all(np.isfinite(values), axis=-1) & (largest <= self.bound)

    def check(self, time: float, values: Any) -> None:
        """Raise :class:`SimulationError` if ``values`` are non-finite or out of bound at ``time`` [s]."""
        values = np.asarray(values, dtype=float).reshape(-1)
        # the usual case, one pass (NaN fails both); the ndarray method skips numpy's Python-level dispatch of np.max
        largest = float(np.abs(values - self.reference).max(initial=0.0))
        if largest < math.inf and largest <= self.bound:
            return
        bad = ~np.isfinite(values)
        if np.any(bad):
            i = int(np.flatnonzero(bad)[0])
            raise SimulationError(f"non-finite state at t = {time:.6g} s in {self.names[i]!r}"
                                  + (f"; {self.hint}" if self.hint else ""),
                                  time=float(time), element=self.names[i])
        if math.isinf(self.bound):
            return
        excursion = np.abs(values - self.reference)
        i = int(np.argmax(excursion))
        if excursion[i] > self.bound:
            raise SimulationError(f"the run diverged at t = {time:.6g} s: {self.names[i]!r} is "
                                  f"{excursion[i]:.4g} from its reference, beyond the bound {self.bound:.4g} "
                                  "(set divergence_bound to change it)" + (f"; {self.hint}" if self.hint else ""),
                                  time=float(time), element=self.names[i])


def call_user(what: str, function: Callable[..., Any], *args: Any, time: float) -> Any:
    """Call user code; any exception becomes a :class:`SimulationError` naming ``what`` and ``time``.

    Parameters
    ----------
    what : str
        The callback or controller, e.g. ``"force of element 'm2'"`` or ``"controller 'pid'"``.
    function : callable
        The user's function.
    *args
        Its arguments.
    time : float
        Simulation time [s] of the call.
    """
    try:
        return function(*args)
    except SimulationError:
        raise
    except Exception as exc:  # noqa: BLE001 - user code may raise anything; it is named and chained
        raise SimulationError(f"{what} raised {type(exc).__name__} at t = {time:.6g} s: {exc}",
                              time=float(time), element=what) from exc


def user_output(what: str, value: Any, size: int, *, time: float) -> np.ndarray:
    """Check a user function's return value: ``size`` finite real numbers, else :class:`SimulationError`.

    Parameters
    ----------
    what : str
        The callback or controller, for the message.
    value : array_like
        What it returned.
    size : int
        Number of values expected.
    time : float
        Simulation time [s].
    """
    def not_numbers() -> SimulationError:          # built only on failure (the repr costs a step's time)
        return SimulationError(f"{what} returned {value!r:.80} at t = {time:.6g} s; expected {size} real "
                               f"number(s)", time=float(time), element=what)

    if value is None:                               # np.asarray(None, float) is nan: say what it was
        raise not_numbers()
    try:
        array = np.asarray(value, dtype=float).reshape(-1)
    except (TypeError, ValueError, OverflowError) as exc:   # 10**400: no float holds it
        raise not_numbers() from exc
    if array.size != size:
        raise SimulationError(f"{what} returned {array.size} value(s) at t = {time:.6g} s; expected {size}",
                              time=float(time), element=what)
    if not np.all(np.isfinite(array)):
        raise SimulationError(f"{what} returned a non-finite value {array.tolist()!r} at t = {time:.6g} s",
                              time=float(time), element=what)
    return array


@dataclass(frozen=True)
class UserFunction:
    """A user's function of time ``f(t) -> float`` whose failures name it and the time.

    :func:`ctmm.signals.as_signal` wraps every user callable in one, so that a force or
    reference callback that raises, returns a non-finite value or more than one value stops the
    run with a :class:`~ctmm.errors.SimulationError` instead of a raw exception or a silently
    truncated value.

    Parameters
    ----------
    what : str
        The parameter the function was given for, e.g. ``"m2: force"``.
    function : callable
        The user's ``f(t)``.
    """

    what: str
    function: Callable[[float], Any]

    def __call__(self, t: float) -> float:
        label = f"user function {self.what!r}"
        return float(user_output(label, call_user(label, self.function, t, time=t), 1, time=t)[0])
