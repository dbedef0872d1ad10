"""``ctmm.control.tune``: gradient-based tuning of controlled chains on exact sensitivities.

The objective and the constraints are :class:`Quantity` objects -- the spectral abscissa, the
gain / phase / delay / stability margins of a loop, the sensitivity peak ``max |1/(1 + L)|`` or a
resonance peak ``max |H|`` -- evaluated with their exact gradients by :mod:`ctmm.sensitivity`
and handed to :func:`scipy.optimize.minimize` (SLSQP or trust-constr).  Parameters are
scaled to ``[0, 1]`` by their bounds, each point is evaluated once (value and gradient together),
and every iterate is recorded in :attr:`TuningResult.history`.

Example: maximise the closed-loop decay rate subject to a delay margin and a sensitivity peak::

    # fragment: needs a ControlledChain `system` with a PD loop "pd" on m6 (scenarios/pd_tuning.py)
    w = np.linspace(0.01, 30, 2000)
    result = tune(system, ["pd.m6.x", "pd.m6.v"], Quantity("spectral_abscissa"),
                  [Constraint(Quantity("delay_margin", loop="pd", omega=w), lower=0.1),
                   Constraint(Quantity("sensitivity_peak", loop="pd", omega=w), upper=2.5)],
                  bounds={"pd.m6.x": (-8, 12), "pd.m6.v": (-4, 6)})
"""
from __future__ import annotations

import math
import time
from dataclasses import dataclass, field
from typing import Any, Callable, Mapping, Sequence

import numpy as np

from ..errors import ModelError

__all__ = ["Quantity", "Constraint", "TuningStep", "TuningResult", "tune"]

_KINDS = {
    "spectral_abscissa": "1/s", "delay_margin": "s", "phase_margin": "deg", "gain_margin": "-",
    "stability_margin": "-", "sensitivity_peak": "-", "response_peak": "output unit per input unit",
}
_CLIP = 1e9     # an infinite margin (no crossover) is used as this value with a zero gradient


@dataclass(frozen=True)
class Quantity:
    """A differentiable scalar of a controlled chain or a planar or spatial model (controlled or not).

    Parameters
    ----------
    kind : str
        ``"spectral_abscissa"`` [1/s] (``re_min``, ``im_max`` with delays or LTI controllers),
        ``"delay_margin"`` [s], ``"phase_margin"`` [deg], ``"gain_margin"`` [-],
        ``"stability_margin"`` (``min |1 + L|``) [-], ``"sensitivity_peak"`` (``max |1/(1 + L)|``) [-]
        (these with ``loop`` and ``omega``), ``"response_peak"`` (``max |H|`` with ``input``,
        ``output``, ``omega``).
    loop, input, output : str, optional
    omega : array_like, optional
        Frequency grid [rad/s] resolving the crossovers / peaks.
    re_min, im_max : float, optional
        Root search region [1/s], [rad/s].
    """

    kind: str
    loop: str | None = None
    omega: Any = None
    input: str | None = None
    output: str | None = None
    re_min: float | None = None
    im_max: float | None = None

    def __post_init__(self) -> None:
        if self.kind not in _KINDS:
            raise ModelError(f"Quantity kind {self.kind!r} is unknown; allowed: {', '.join(_KINDS)}")
        needs = {"spectral_abscissa": (), "response_peak": ("input", "output", "omega")}.get(self.kind,
                                                                                        ("loop", "omega"))
        missing = [name for name in needs if getattr(self, name) is None]
        if missing:
            raise ModelError(f"Quantity {self.kind!r} needs {', '.join(missing)}; got {self!r:.200}")

    @property
    def unit(self) -> str:
        """Unit of the value."""
        return _KINDS[self.kind]

    @property
    def label(self) -> str:
        """Readable name, e.g. ``"delay_margin(pd)"``."""
        where = self.loop or (f"{self.input}->{self.output}" if self.input else "")
        return f"{self.kind}({where})" if where else self.kind

    def evaluate(self, system: Any, parameters: Sequence[str]) -> tuple[float, np.ndarray]:
        """Value and gradient (in the order of ``parameters``) at ``system``."""
        from .. import sensitivity as sens        # builds on the chain realisation, which imports this package

        names = list(parameters)
        if self.kind == "spectral_abscissa":
            found = sens.spectral_abscissa_sensitivity(system, names, re_min=self.re_min, im_max=self.im_max)
            return found.value, np.array([found.gradient[n] for n in names])
        if self.kind == "response_peak":
            peak = sens.peak_sensitivity(system, names, self.omega, input=self.input, output=self.output)
            return peak.value, np.array([peak.gradient[n] for n in names])
        if self.kind in ("stability_margin", "sensitivity_peak"):
            found = sens.stability_margin_sensitivity(system, self.loop, names, self.omega)
            gradient = np.array([found.gradient[n] for n in names])
            if self.kind == "stability_margin":
                return found.value, gradient
            return 1.0 / found.value, -gradient / found.value ** 2
        found = sens.margin_sensitivity(system, self.loop, names, self.omega)
        value = float(getattr(found.margins, self.kind))
        derivative = getattr(found, self.kind)
        if not math.isfinite(value):
            return math.copysign(_CLIP, value), np.zeros(len(names))
        return value, np.array([derivative[n] for n in names])


@dataclass(frozen=True)
class Constraint:
    """``lower <= quantity <= upper`` (either bound may be omitted, not both)."""

    quantity: Quantity
    lower: float | None = None
    upper: float | None = None

    def __post_init__(self) -> None:
        if not isinstance(self.quantity, Quantity):
            raise ModelError(f"Constraint quantity must be a ctmm.control.tuning.Quantity, got {self.quantity!r}")
        if self.lower is None and self.upper is None:
            raise ModelError(f"Constraint on {self.quantity.label} needs lower= or upper=, got neither")
        for label, value in (("lower", self.lower), ("upper", self.upper)):
            if value is not None and not math.isfinite(value):
                raise ModelError(f"Constraint on {self.quantity.label}: {label} must be finite, got {value!r}")

    @property
    def label(self) -> str:
        """``"0.1 <= delay_margin(pd)"`` and the like."""
        low = f"{self.lower:g} <= " if self.lower is not None else ""
        high = f" <= {self.upper:g}" if self.upper is not None else ""
        return f"{low}{self.quantity.label}{high}"

    def violation(self, value: float) -> float:
        """How far ``value`` is outside the bounds (0 inside)."""
        low = 0.0 if self.lower is None else max(0.0, self.lower - value)
        return max(low, 0.0 if self.upper is None else max(0.0, value - self.upper))


@dataclass(frozen=True)
class TuningStep:
    """One evaluated point of the optimisation.

    Attributes
    ----------
    evaluation : int
        Running number of the evaluation.
    parameters : dict
        ``{name: value}``.
    objective : float
    constraints : tuple of float
        Constraint quantities, in the order given.
    elapsed : float
        Wall time since the start [s].
    """

    evaluation: int
    parameters: dict
    objective: float
    constraints: tuple
    elapsed: float


@dataclass
class TuningResult:
    """Result of :func:`tune`.

    Attributes
    ----------
    parameters : dict
        Optimal ``{name: value}``.
    system : Any
        The system with those parameters.
    objective : float
        Objective value there (as given, also when maximised).
    constraints : dict
        ``{constraint label: quantity value}`` there.
    feasible : bool
        Every constraint holds within ``1e-6`` (relative to its bound).
    success : bool
        The optimiser converged and the optimum is feasible.
    message : str
    history : list of TuningStep
        Every evaluated point (first = start).
    iterations : list of TuningStep
        The accepted iterates (one per optimiser iteration).
    evaluations : int
    wall_time : float
        [s].
    scipy_result : scipy.optimize.OptimizeResult
    """

    parameters: dict
    system: Any
    objective: float
    constraints: dict
    feasible: bool
    success: bool
    message: str
    history: list = field(default_factory=list)
    iterations: list = field(default_factory=list)
    evaluations: int = 0
    wall_time: float = 0.0
    scipy_result: Any = None


def _bounds(parameters: Sequence[str], bounds: Any, x0: np.ndarray) -> tuple[np.ndarray, np.ndarray]:
    if bounds is None:
        bounds = {}
    if not isinstance(bounds, Mapping):
        if len(bounds) != len(parameters):
            raise ModelError(f"bounds must be a mapping {{parameter: (low, high)}} or one (low, high) per "
                             f"parameter ({len(parameters)}), got {bounds!r}")
        bounds = dict(zip(parameters, bounds))
    unknown = [k for k in bounds if k not in parameters]
    if unknown:
        raise ModelError(f"bounds name parameters that are not tuned: {unknown}; tuned: {list(parameters)}")
    low, high = np.empty(len(parameters)), np.empty(len(parameters))
    for k, name in enumerate(parameters):
        pair = bounds.get(name)
        if pair is None:
            low[k], high[k] = -math.inf, math.inf
            continue
        lo, hi = (float(v) for v in pair)
        if not (math.isfinite(lo) and math.isfinite(hi) and lo < hi):
            raise ModelError(f"bounds of {name!r} must be finite with low < high, got {pair!r}")
        if not lo <= x0[k] <= hi:
            raise ModelError(f"the start value {x0[k]!r} of {name!r} is outside its bounds {pair!r}")
        low[k], high[k] = lo, hi
    return low, high


def tune(system: Any, parameters: Sequence[str], objective: Quantity, constraints: Sequence[Constraint] = (),
         bounds: Any = None, *, maximize: bool = False, method: str = "SLSQP", max_iterations: int = 100,
         tolerance: float = 1e-8, progress: bool | Callable[[TuningStep], None] = False) -> TuningResult:
    """Tune named parameters of a controlled chain, planar or spatial model by gradient-based constrained optimisation.

    Parameters
    ----------
    system : Chain, ControlledChain, PlanarModel, SpatialModel or ControlledModel (planar or spatial plant)
        Start point (its current parameter values).
    parameters : sequence of str
        Names as in :mod:`ctmm.sensitivity` (``"pd.m6.x"``, ``"pd.delay"``, ``"K3.stiffness"``,
        ``"upper.mass"``, ``"pd.motor.rate"``, ...).
    objective : Quantity
        Minimised (maximised with ``maximize=True``).
    constraints : sequence of Constraint
    bounds : mapping or sequence, optional
        ``{name: (low, high)}`` or one pair per parameter; parameters with bounds are scaled to
        ``[0, 1]``, the others by ``max(1, |start|)``.
    maximize : bool
    method : {"SLSQP", "trust-constr"}
    max_iterations : int
    tolerance : float
        Optimiser tolerance on the scaled problem.
    progress : bool or callable
        ``True`` prints one line per iteration; a callable receives every accepted
        :class:`TuningStep`.

    Returns
    -------
    TuningResult

    Raises
    ------
    ModelError
        Unknown parameters or kinds, inconsistent bounds, an unknown method, a quantity that cannot
        be differentiated at an iterate (named with the parameter values).
    """
    from scipy.optimize import Bounds, NonlinearConstraint, minimize

    from .. import sensitivity as sens        # builds on the chain realisation, which imports this package

    if method not in ("SLSQP", "trust-constr"):
        raise ModelError(f"tune: method must be 'SLSQP' or 'trust-constr', got {method!r}")
    if not isinstance(objective, Quantity):
        raise ModelError(f"tune: objective must be a ctmm.control.tuning.Quantity, got {objective!r}")
    constraints = tuple(constraints)
    for c in constraints:
        if not isinstance(c, Constraint):
            raise ModelError(f"tune: constraints must be ctmm.control.tuning.Constraint objects, got {c!r}")
    start_values = sens.parameter_values(system, parameters)
    names = list(start_values)
    x0 = np.array([start_values[n] for n in names])
    low, high = _bounds(names, bounds, x0)
    bounded = np.isfinite(low)
    scale = np.where(bounded, high - low, np.maximum(1.0, np.abs(x0)))
    offset = np.where(bounded, low, 0.0)
    sign = -1.0 if maximize else 1.0
    cache: dict[bytes, tuple] = {}
    history: list[TuningStep] = []
    iterations: list[TuningStep] = []
    started = time.perf_counter()

    def evaluate(z: np.ndarray) -> tuple:
        key = np.asarray(z, dtype=float).tobytes()
        if key not in cache:
            x = offset + scale * np.asarray(z, dtype=float)
            values = dict(zip(names, x.tolist()))
            try:
                candidate = sens.with_parameters(system, values)
                f, df = objective.evaluate(candidate, names)
                cs = [c.quantity.evaluate(candidate, names) for c in constraints]
            except ModelError as exc:
                raise ModelError(f"tune: at {values}: {exc}") from exc
            step = TuningStep(len(history), values, float(f), tuple(float(v) for v, _ in cs),
                              time.perf_counter() - started)
            history.append(step)
            cache[key] = (f, df * scale, [(v, g * scale) for v, g in cs], step)
        return cache[key]

    def fun(z):
        return sign * evaluate(z)[0]

    def jac(z):
        return sign * evaluate(z)[1]

    scipy_constraints: list = []
    for k, c in enumerate(constraints):
        if method == "trust-constr":
            scipy_constraints.append(NonlinearConstraint(
                lambda z, k=k: evaluate(z)[2][k][0], -np.inf if c.lower is None else c.lower,
                np.inf if c.upper is None else c.upper, jac=lambda z, k=k: evaluate(z)[2][k][1][None]))
            continue
        for bound, factor in ((c.lower, 1.0), (c.upper, -1.0)):
            if bound is not None:
                scipy_constraints.append({
                    "type": "ineq",
                    "fun": lambda z, k=k, b=bound, f=factor: f * (evaluate(z)[2][k][0] - b),
                    "jac": lambda z, k=k, f=factor: f * evaluate(z)[2][k][1]})

    def report(step: TuningStep) -> None:
        iterations.append(step)
        if callable(progress):
            progress(step)
        elif progress:
            shown = ", ".join(f"{n} = {v:.6g}" for n, v in step.parameters.items())
            cons = ", ".join(f"{c.quantity.label} = {v:.4g}" for c, v in zip(constraints, step.constraints))
            print(f"tune: iteration {len(iterations) - 1:3d}: {objective.label} = {step.objective:.6g}; "
                  f"{cons}; {shown}", flush=True)

    def callback(z, *args):
        report(evaluate(z)[3])

    z0 = (x0 - offset) / scale
    report(evaluate(z0)[3])
    z_bounds = Bounds(np.where(bounded, 0.0, -np.inf), np.where(bounded, 1.0, np.inf))
    options = {"maxiter": int(max_iterations)}
    if method == "SLSQP":
        options["ftol"] = tolerance
    else:
        options.update(gtol=tolerance, xtol=tolerance, barrier_tol=tolerance)
    found = minimize(fun, z0, jac=jac, method=method, bounds=z_bounds, constraints=scipy_constraints,
                     callback=callback, options=options)
    f, _, cs, step = evaluate(found.x)
    tuned = sens.with_parameters(system, step.parameters)
    values = {c.label: float(v) for c, (v, _) in zip(constraints, cs)}
    feasible = all(c.violation(v) <= 1e-6 * max(1.0, abs(c.lower if c.lower is not None else c.upper))
                   for c, (v, _) in zip(constraints, cs))
    message = str(found.message) + ("" if feasible else "; the optimum violates a constraint")
    return TuningResult(step.parameters, tuned, float(f), values, feasible, bool(found.success) and feasible,
                        message, history, iterations, len(history), time.perf_counter() - started, found)
