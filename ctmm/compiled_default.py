"""When ``ctmm.simulate``'s default (``compiled=None``) runs the generated code (issue 13 item 2).

``compiled=True`` always takes the generated path (or refuses by name what it cannot compile) and
``compiled=False`` always the numpy path.  The default takes the generated path where it pays and is safe:

* a C compiler is present (:func:`ctmm.codegen.find_compiler`);
* the run is a fixed-step RK4 of a 1-D chain, a planar or a spatial model (plain, or with feedback loops,
  inputs and references), or a DT-TMM scheme of any of them (a chain's step is one data-driven kernel compiled
  once per variant);
* a DT-TMM scheme of a planar model whose generated step iterates with one implicit articulated sweep per
  iteration (:mod:`ctmm.compiled_sweep_newton`, O(n): linear hinge laws, no loops) and has no modal bodies at most
  :data:`SCHEME_SWEEP_MAXIMUM_COORDINATES` coordinates (measured up to there: at most 0.13 of the numpy step, first
  compile <= 3 s), another planar model at most :data:`SCHEME_MAXIMUM_COORDINATES` (with feedback loops
  :data:`SCHEME_LOOPS_MAXIMUM_COORDINATES`: the numpy path's loops cost more than the generated tangent there) and
  a spatial model at most :data:`SCHEME_MAXIMUM_VELOCITIES` velocities: their generated Newton step forms the
  ``n x n`` tangent of the sweep (``2 n`` directional derivatives, :mod:`ctmm.mapped_tangent`) and factors it,
  O(n^2 .. n^3) per iteration, where the numpy planar stepper iterates with one linearised articulated sweep
  (O(n)), so beyond these sizes the generated step is slower (planar) or its first compile too long (spatial);
* a chain is not larger than its kind allows: :data:`MAXIMUM_BANDED_CHAIN_POINTS` points for a *banded* chain (every
  moving point a mass, no inerter, no connector with a nonlinear law, supports that stand still: its generated
  set-up is ``O(n)``, :mod:`ctmm.chain_affine`) with feedback loops, :data:`MAXIMUM_CHAIN_POINTS` for the others:
  massless points and prescribed motions are condensed and inerters couple every node (a dense ``O(n^2)`` set-up,
  :func:`dense_chain_reason`), and a banded chain without loops runs cheaply on numpy (one sparse mat-vec per RK4
  stage, a banded solve per DT-TMM step) against a compile that grows with the chain (measured below);
* the call's options are ones the numpy path accepts for that chain and method (``store_every``, ``outputs``,
  ``inputs``, ``rtol``, ``atol``, ``max_step`` on a DT-TMM scheme of a chain; ``outputs``, ``progress``,
  ``stability_check`` on an RK4 run of a chain without loops, inputs or references): a call the numpy path refuses
  by name stays there and is refused, whatever its length, instead of running on the generated path only when it
  is long;
* it is long: at least :data:`MINIMUM_STEPS` steps, so that a first compile (about 1-2.5 s CPU for the
  planar, spatial and chain scenes measured below) costs a fraction of the numpy run it replaces, and a
  cached kernel (milliseconds to load) is far ahead;
* no co-simulated ``controllers`` (user objects with state, possibly FMUs: a run that the generated path
  refused after their first sample could not be repeated with them as they were), no numpy-only options
  (``fast``, ``force_hook``, another ``solver``, a ``solve_ivp`` method).

The generated path is then tried; what it refuses by name (a :class:`~ctmm.errors.ModelError`: user
callables of time, elements it does not state, ...) runs on the numpy path instead, with the reason in the
result's ``info["compiled"]``.  Warnings raised while the generated path was tried are shown only when it
ran (the numpy path shows its own).  A run that fails (:class:`~ctmm.errors.SimulationError`) fails as it
does on the numpy path (the contract of the generated paths: the numpy answer to round-off, failures at the
same step and time); it is not repeated.  One exception: the Newton iteration of a planar or spatial DT-TMM
scheme.  Both paths converge to the same step to round-off, but the generated one forms the exact tangent (or,
from 8 planar coordinates, iterates with the implicit sweep, :mod:`ctmm.compiled_sweep_newton`, linearly) and
the numpy one iterates with the transfer form, so where a state grows fast (an unstable closed loop, a chain
whipping at large steps) one may still converge where the other stops (``tests/test_loop_convergence_hint.py``:
75 steps apart, both naming the loops that may be unstable; a 24-link chain at ~2 rad/s and dt = 20 ms: the sweep
stopped at step 10, the mapped Newton tangent at step 11).  The choice depends on the call only, never on what the disk cache
holds, so the same call takes the same path on every machine with a compiler.

Measured (CPU time, cold cache, 200-step RK4 runs, load 13-15 on 2 cores, session 11): planar pendulum chain
N = 5: numpy 0.83 ms/step, first generated call 0.99 s (break-even 1 200 steps), cached call 14 ms; N = 20:
1.3 ms/step, 2.5 s (1 900 steps), 47 ms; spatial revolute chain N = 5: 17.8 ms/step, 1.2 s (70 steps);
1-D chain of 100 masses: 0.82 ms/step, 1.05 s (1 300 steps), 0.2 s.  At :data:`MINIMUM_STEPS` the first
compile is at most about half the numpy time of those runs.

DT-TMM schemes (``benchmarks/compiled_schemes_default.py``, Newmark, dt = 1 ms, CPU time, load 5-6 on 2 cores,
session 13; generated step on the loaded library / numpy step, first generated call), pendulum chains with the
implicit-sweep iteration (from 8 coordinates): N = 10: 7.4 / 648 us (0.011), 1.9 s; N = 15: 16 / 621 us (0.025),
2.9 s; N = 20: 39 / 1199 us (0.033), 1.9 s; N = 40: 78 / 1324 us (0.059), 2.4 s; N = 80: 144 / 1772 us (0.081),
2.6 s; N = 150: 235 / 1767 us (0.13), 2.6 s; N = 300: 330 / 2492 us (0.13), 2.8 s.  Session 12 (load 12-16), with the ``n x n`` tangent: planar
pendulum chains N = 5:
10.8 / 633 us, 2.4 s; N = 10: 151 / 895 us, 3.8 s; N = 15: 255 / 949 us (ratio 0.27), 5.0 s; N = 20 (sweep
folded): 1362 / 932 us (ratio 1.5); N = 40: 5.7 / 1.5 ms (3.9); N = 80: 20.3 / 2.0 ms (10).  With a PD loop on
every hinge: N = 15: 0.46 / 15.3 ms (0.030), 7.0 s; N = 30: 2.0 / 19.3 ms (0.10), 17 s.  Spatial revolute chains
(generated 15-280 us per step): N = 3: numpy 5.5 ms per step, first call 2.2 s; N = 5: 9.7 ms, 8.0 s; N = 10:
14.3 ms, 20 s; N = 20: gcc passed its 600 s wall-clock limit (load 15).

Chains of 20 001 points (10 000 masses, ``benchmarks/chain_default_limits.py``: a cold ``MINIMUM_STEPS``-step run,
CPU time with the compiler's, load 4-12 on 2 cores, session 12): with a real-time loop, RK4, generated 57.5 s
against numpy 230 s (4.0x, equal bit for bit), Newmark 39.2 s against 17 150 s (438x, 3.5e-16); without loops the
generated path is not faster (RK4 42.2 s against 29.1 s, Newmark 28.5 s against a numpy set-up of 21.6 s and a step
too cheap to resolve).
"""
from __future__ import annotations

import math
import warnings
from typing import Any, Callable, Mapping

from .control.loops import ControlledChain
from .errors import ModelError
from .planar.model import PlanarModel
from .results import SimulationResult
from .schemes import SCHEMES, Scheme
from .spatial.model import SpatialModel
from .system import Chain

__all__ = ["MAXIMUM_BANDED_CHAIN_POINTS", "MAXIMUM_CHAIN_POINTS", "MINIMUM_STEPS",
           "SCHEME_LOOPS_MAXIMUM_COORDINATES", "SCHEME_MAXIMUM_COORDINATES", "SCHEME_MAXIMUM_VELOCITIES",
           "SCHEME_SWEEP_MAXIMUM_COORDINATES",
           "default_refusal", "dense_chain_reason", "is_size_refusal", "note_size_refusal", "run_default"]

MINIMUM_STEPS = 5000
"""Fewest fixed steps for which ``compiled=None`` tries the generated path (module docstring)."""
MAXIMUM_CHAIN_POINTS = 2002
"""Largest 1-D chain with massless points, inerters, connectors with a law or a prescribed motion (points: 2 per
mass between springs, plus the ends) the default generates: the set-up of such a chain's generated step (the
condensation, the coupled form read column by column) grows like ``n^2``; the set-up of every chain took 2-4 s at
1000 masses and passed 19 GB of memory at 10 000 before the banded form (session 11), so larger chains of these
kinds stay on the numpy path unless ``compiled=True``."""
MAXIMUM_BANDED_CHAIN_POINTS = 20002
"""Largest banded 1-D chain with feedback loops (:func:`dense_chain_reason` ``None``) the default generates: its
set-up is ``O(n)`` (``benchmarks/chain_setup_scaling.py``) and its cold generated run of ``MINIMUM_STEPS`` steps was
4x faster end to end than the numpy run at this size (``benchmarks/chain_default_limits.py``, module docstring);
larger chains were not measured."""


def dense_chain_reason(chain: Any) -> str | None:
    """Why the generated set-up of a plain 1-D chain is dense (``O(n^2)``), or ``None`` for a banded chain.

    Parameters
    ----------
    chain : Chain
        The plant of the call.

    Returns
    -------
    str or None
        The parts that make it dense, named (massless points, inerters, connectors with a nonlinear law, a prescribed
        start or end motion, a chain that is not of lumped 1-D elements), or ``None``: every moving point has a mass
        and the supports stand still, so the chain's rates are the certified tridiagonal form of
        :mod:`ctmm.chain_affine` (three probes of the sweep).
    """
    from .elements.inerter import Inerter
    from .lumped_forms import lumped_tree, massless_nodes

    try:
        tree = lumped_tree(chain)
    except ModelError:
        return "elements that are not lumped 1-D elements"
    parts = []
    mask = massless_nodes(tree)
    massless = [tree.bodies[j].name for j in range(len(tree.bodies)) if mask[tree.node[j]]]
    if massless:
        parts.append(f"points without mass ({_names(massless)})")
    inerters = [element.name for element in chain.body if isinstance(element, Inerter)]
    if inerters:
        parts.append(f"inerters ({_names(inerters)})")
    laws = [element.name for element in chain.body if hasattr(element, "law") and not element.is_point]
    if laws:
        parts.append(f"connectors with a law ({_names(laws)})")
    moving = [boundary.name for boundary in (chain.start, chain.end) if hasattr(boundary, "displacement")]
    if moving:
        parts.append(f"a prescribed motion ({_names(moving)})")
    return ", ".join(parts) or None


def _names(names: list) -> str:
    return ", ".join(names[:3]) + (f", ... {len(names)} in all" if len(names) > 3 else "")


SCHEME_MAXIMUM_COORDINATES = 15
"""Largest planar model (coordinates) without loops whose DT-TMM schemes the default generates where its generated
step forms the ``n x n`` tangent (nonlinear hinge laws, modal bodies: not :data:`SCHEME_SWEEP_MAXIMUM_COORDINATES`):
that step was 0.27 of the numpy step at 15 coordinates and 1.5 times it at 20 (module docstring); larger ones stay
on numpy unless ``compiled=True``."""
SCHEME_SWEEP_MAXIMUM_COORDINATES = 300
"""Largest planar model (coordinates) without loops whose DT-TMM schemes the default generates where the generated
step iterates with the implicit sweep (:mod:`ctmm.compiled_sweep_newton`: linear hinge laws, no modal bodies; one
articulated sweep per iteration, O(n)): measured generated / numpy step 0.011 at 10 coordinates, 0.081 at 80 and 0.13 at 300, first compile 1.9-2.9 s
CPU (pendulum chains, folded from 20 bodies; module docstring); not measured beyond, nor for modal bodies (which the
sweep covers, tangent="sweep", but whose default limit stays :data:`SCHEME_MAXIMUM_COORDINATES`)."""
SCHEME_LOOPS_MAXIMUM_COORDINATES = 30
"""Largest planar model (coordinates) with feedback loops (a ``ControlledModel``) whose DT-TMM schemes the default
generates: the numpy path closes the loops around its stepper (about 0.7 ms per body and step), the generated step
inside its Newton iteration; measured with a PD on every hinge of pendulum chains, generated / numpy step 0.030 at
15 coordinates and 0.10 at 30 (first call 7.0 s and 17 s CPU; module docstring); not measured beyond."""
SCHEME_MAXIMUM_VELOCITIES = 10
"""Largest spatial model (velocities) whose DT-TMM schemes the default generates: the generated step is far ahead
(0.28 ms against 14 ms at 10), but the first compile grows steeply (20 s CPU at 10 velocities with the symbolic
tangent, 15.5 s with the directional-derivative tangent used from 3 velocities (``benchmarks/spatial_scheme_tangent.py``,
one run at load 9-10), over 600 s at 20; module docstring), a fraction of the numpy time of :data:`MINIMUM_STEPS`
steps only up to about this size."""


def _plant(system: Any) -> Any:
    return getattr(system, "plant", system)


_SIZE_REFUSAL = "a chain of"
_SCHEME_SIZE_REFUSAL = "a DT-TMM scheme of"


def _scheme_size_refusal(system: Any, plant: PlanarModel | SpatialModel) -> str | None:
    """Why a DT-TMM scheme of ``system`` (on ``plant``) stays on numpy by its size
    (:data:`SCHEME_MAXIMUM_COORDINATES`, :data:`SCHEME_SWEEP_MAXIMUM_COORDINATES` where the generated step iterates
    with the implicit sweep, with feedback loops :data:`SCHEME_LOOPS_MAXIMUM_COORDINATES`,
    :data:`SCHEME_MAXIMUM_VELOCITIES`), or ``None``."""
    if isinstance(plant, PlanarModel):
        from .compiled_sweep_newton import sweep_refusal

        loops = system is not plant and bool(getattr(system, "loops", ()))
        sweep = not loops and not sweep_refusal(plant) and not any(len(index) for index in plant.modal_index)
        limit = SCHEME_LOOPS_MAXIMUM_COORDINATES if loops else \
            SCHEME_SWEEP_MAXIMUM_COORDINATES if sweep else SCHEME_MAXIMUM_COORDINATES
        size, what = plant.n_coordinates, "coordinates" + (" with loops" if loops else "")
        if sweep and size > limit:
            return (f"{_SCHEME_SIZE_REFUSAL} {size} {what} (> {limit}: the generated step (one implicit sweep per "
                    "iteration) was not measured beyond; give compiled=True)")
    else:
        size, limit, what = plant.n_velocities, SCHEME_MAXIMUM_VELOCITIES, "velocities"
    if size > limit:
        return (f"{_SCHEME_SIZE_REFUSAL} {size} {what} (> {limit}: the generated Newton step forms and factors an "
                f"{size} x {size} tangent, slower than the numpy stepper there or too long to compile; give "
                "compiled=True)")
    return None


def is_size_refusal(refusal: str | None) -> bool:
    """Whether :func:`default_refusal` kept the call on the numpy path for the system's size: a chain (and its
    kind) or a planar or spatial model under a DT-TMM scheme."""
    return bool(refusal) and str(refusal).startswith((_SIZE_REFUSAL, _SCHEME_SIZE_REFUSAL))


def note_size_refusal(result: SimulationResult, refusal: str) -> SimulationResult:
    """``result`` of the numpy path with the size refusal in ``info["compiled"]`` (kept if the path set it)."""
    result.info.setdefault("compiled", f"numpy (the default for this run: {refusal})")
    return result


def _numpy_refused_options(system: Any, is_scheme: bool, options: Mapping[str, Any]) -> str:
    """The call's options the numpy path refuses on this chain and method (:func:`ctmm.simulation.simulate`), named."""
    checked = ("store_every", "outputs", "inputs", "references", "progress", "stability_check", "rtol", "atol",
               "max_step")
    given = {name: options[name] for name in checked if options.get(name) is not None}
    if is_scheme:
        defaults = {"store_every": 1, "outputs": (), "rtol": 1e-8, "atol": 1e-10}
        refused = [name for name in ("inputs", "max_step") if name in given]
    else:
        controlled = bool(getattr(system, "loops", ())) or bool(given.get("inputs")) or bool(given.get("references"))
        if controlled:
            return ""
        defaults = {"outputs": ()}
        refused = [name for name in ("progress", "stability_check") if name in given]
    refused += [name for name, default in defaults.items()
                if name in given and _differs(given[name], default)]
    return ", ".join(refused)


def _differs(value: Any, default: Any) -> bool:
    try:
        return bool(tuple(value) != default) if isinstance(default, tuple) else bool(value != default)
    except (TypeError, ValueError):
        return True


def default_refusal(system: Any, method: Any, t_final: Any, t0: Any, dt: Any, *, controllers: Any, fast: Any,
                    force_hook: Any, solver: Any, options: Mapping[str, Any] | None = None) -> str | None:
    """``None`` when the default tries the generated path for this call, else why it stays on numpy.

    Parameters
    ----------
    system : Chain, ControlledChain, PlanarModel, SpatialModel or a ControlledModel on one
        The system of the call (other kinds stay on numpy).
    method : str or Scheme
        The integrator after the verb's default (``"rk4"`` planar / spatial, ``"newmark"`` chains).
    t_final, t0, dt : float
        The run's end, start and fixed step [s].
    controllers, fast, force_hook, solver
        The call's options (any co-simulated controller, ``fast``, a force hook or another solver keep numpy).
    options : mapping, optional
        The call's other options by name (read: ``store_every``, ``outputs``, ``inputs``, ``references``,
        ``progress``, ``stability_check``, ``rtol``, ``atol``, ``max_step``; others are ignored): those the numpy
        path refuses for a chain and its method keep numpy, which refuses them by name.
    """
    plant = _plant(system)
    is_scheme = isinstance(method, Scheme) or (isinstance(method, str) and method in SCHEMES)
    if isinstance(system, (Chain, ControlledChain)):
        if method != "rk4" and not is_scheme:
            return f"method {method!r} has no generated form"
        points = getattr(plant, "n_points", 0)
        if points > MAXIMUM_BANDED_CHAIN_POINTS:
            return (f"{_SIZE_REFUSAL} {points} points (> {MAXIMUM_BANDED_CHAIN_POINTS}, the largest banded chain "
                    "the default generates; give compiled=True)")
        if points > MAXIMUM_CHAIN_POINTS:
            dense = dense_chain_reason(plant)
            if dense is not None:
                return (f"{_SIZE_REFUSAL} {points} points with {dense} (> {MAXIMUM_CHAIN_POINTS}: its generated "
                        "set-up is dense; give compiled=True)")
            if not getattr(system, "loops", ()):
                return (f"{_SIZE_REFUSAL} {points} points without feedback loops (> {MAXIMUM_CHAIN_POINTS}: the numpy "
                        "run of a plain banded chain is cheaper than the generated path's compile; give compiled=True)")
        refused = _numpy_refused_options(system, is_scheme, options or {})
        if refused:
            return f"options the numpy path refuses for this chain and method ({refused}: it names them)"
    elif isinstance(plant, (PlanarModel, SpatialModel)):
        if method != "rk4" and not is_scheme:
            return f"method {method!r} has no generated form"
        if is_scheme:
            reason = _scheme_size_refusal(system, plant)
            if reason:
                return reason
    else:
        return "only chains, planar and spatial models (with or without loops) take the generated path by default"
    if controllers:
        return "co-simulated controllers (give compiled=True)"
    if fast is not None or force_hook is not None or solver != "riccati":
        return "numpy-path options (fast, force_hook, solver)"
    try:
        span = (float(t_final) - float(t0)) / float(dt)
        steps = math.ceil(span - 1e-9) if math.isfinite(span) else 0
    except (TypeError, ValueError, ZeroDivisionError, OverflowError):
        return "no fixed step"          # the verb's own checks refuse bad numbers by name
    if not steps > 0:
        return "no fixed step"
    if not steps >= MINIMUM_STEPS:
        return f"short run ({steps} steps < {MINIMUM_STEPS})"
    from .codegen import find_compiler

    try:
        find_compiler()
    except ModelError:
        return "no C compiler"
    return None


def run_default(generated: Callable[[], SimulationResult], numpy_path: Callable[[], SimulationResult]
                ) -> SimulationResult:
    """The default's run of a call :func:`default_refusal` accepts: ``generated()``, or ``numpy_path()`` when the
    generated path refuses the call (a :class:`~ctmm.errors.ModelError`); ``info["compiled"]`` says which ran and
    why."""
    refusal = None
    with warnings.catch_warnings(record=True) as caught:
        warnings.simplefilter("always")
        try:
            result = generated()
        except ModelError as exc:
            refusal = str(exc)
        shown = list(caught)
    if refusal is None:
        for entry in shown:
            warnings.warn_explicit(entry.message, entry.category, entry.filename, entry.lineno)
        result.info["compiled"] = "generated (the default for this run)"
        return result
    result = numpy_path()
    result.info["compiled"] = f"numpy (the default for this run; the generated path refused it: {refusal})"
    return result
