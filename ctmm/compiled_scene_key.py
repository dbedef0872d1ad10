"""The cache key of a planar generated scene, computed before anything is built (issue 13), and the check of a
hit.

:class:`~ctmm.compiled_scene.CompiledScene` keys its library (:func:`ctmm.generated_loop.compiled_time_loop` with
``description=``) on :func:`scene_description`: with the numbers as inputs ``p``, the model's description without
its numbers (:func:`ctmm.model_description.describe` with ``numbers=False``) and its
:func:`~ctmm.compiled_parameters.structure_key` (the numbers the code keeps as constants), so models that differ
only in entries of ``p`` share one library; a hit is then certified (:func:`certified_hit`) against the numpy
sweep of the model, independent of the generated code, else the scene is built and keyed on its functions.
With loops whose numbers are inputs, the loops' other numbers are keyed exactly (:func:`loop_constants`) and the
hit is also certified on the loop sensors (:func:`sensor_check`, :func:`certified_sensors`: their code keeps the
plant's numbers).  :class:`~ctmm.compiled_scene_schemes.CompiledSceneScheme` (a planar DT-TMM scheme without
loops) keys its library the same way on :func:`scheme_description`: the model without its numbers, and the
scheme's options with theirs.
"""
from __future__ import annotations

from typing import Any, Callable, Sequence

import numpy as np

from .compiled_parameters import structure_key
from .control.controlled_model import ControlledModel
from .errors import ModelError, SimulationError
from .generated_loop import TimeLoop, compiled_time_loop
from .planar.body_forms import PlanarScene
from .planar.model import PlanarModel

__all__ = ["certified_hit", "certified_sensors", "described_time_loop", "loop_constants", "scene_description",
           "scheme_description", "sensor_check"]


def scene_description(system: PlanarModel | ControlledModel, numbers: str, period: int,
                      loop_options: tuple, stations: Sequence[str] = (), loops: Any = None
                      ) -> list[tuple[str, bytes]] | None:
    """The labelled description a :class:`~ctmm.compiled_scene.CompiledScene`'s library is keyed on before
    anything is built (:func:`ctmm.generated_loop.compiled_time_loop`), or ``None`` (key on the built functions).

    Parameters
    ----------
    system : PlanarModel or ControlledModel
    numbers : {"inputs", "constants"}
        Of the scene.
    period : int
        Bodies per folded segment (0: straight-line code).
    loop_options : tuple
        ``(dt, references, signals)`` of the loops.
    stations : sequence of str
        The beam station loads that are inputs of the scene (:func:`~ctmm.compiled_parameters.compiled_actuators`).
    loops : ClosedLoops, optional
        The scene's :class:`~ctmm.compiled_loops.ClosedLoops` (with a ControlledModel).

    With ``numbers="inputs"``: the plant's description without its numbers (every float by
    its zero pattern, ``describe(..., numbers=False)``) and its :func:`structure_key` (the numbers the code
    keeps as constants), so models differing only in numbers of
    :func:`~ctmm.compiled_parameters.parameter_vector` (entries of ``p``) share a library (as
    :meth:`ctmm.compiled_scene.CompiledScene.with_model`); a hit is certified against the numpy sweep
    (:func:`certified_hit`).  With loops also :func:`loop_constants` (every number of the loops that is not an entry
    of ``p``: sensor and actuator weights, delays, saturations, open-loop inputs), and a hit is certified on the
    loop sensors too (:func:`certified_sensors`: their code keeps the plant's numbers).  Numbers as constants (with
    or without loops): the description of the whole system and the loops' options, so any changed number gives
    another library."""
    from .model_description import describe

    extra = (tuple(stations),) if stations else ()
    if numbers == "inputs" and isinstance(system, ControlledModel) and loops is None:
        return None
    if numbers == "inputs":
        constants = b"" if loops is None else loop_constants(loops)
        plant = system.plant if isinstance(system, ControlledModel) else system
        text = None if constants is None else describe((plant, numbers, period, *extra), numbers=False)
        parts = [("planar structure", structure_key(plant).encode())] + ([("planar loops", constants)]
                                                                         if loops is not None else [])
    else:
        text = describe((system, numbers, period, loop_options, *extra))
        parts = []
    return None if text is None else [*parts, ("planar", text)]


def loop_constants(loops: Any) -> bytes | None:
    """The description (every number) of what the generated step of :class:`~ctmm.compiled_loops.ClosedLoops` with
    ``numbers="inputs"`` keeps as constants: per law its name, sensor and actuator terms, controller order, delay and
    steps, saturation and reference class (its gains, realisation and reference numbers are entries of ``p``:
    :func:`~ctmm.compiled_parameters.loop_parameter_layout`), the open-loop inputs, the channels' signals, the
    actuators; ``None`` when a reference has no symbolic form of a :mod:`ctmm.signals` class (a user's
    :class:`~ctmm.compiled_references.SymbolicReference`: its code is not described)."""
    from .model_description import describe
    from .signals import signal_parameters

    if any(signal_parameters(law.reference) is None for law in loops.laws):
        return None
    laws = [(law.name, law.sensors, law.actuators, law.A.shape, law.delay, law.steps, law.saturation,
             type(law.reference)) for law in loops.laws]
    return describe(("closed loops", laws, loops.inputs, [index for index, _ in loops.channels], loops.actuators,
                     loops.ring_columns))


def sensor_check(loops: Any) -> Any:
    """``loop_sensor_check(q, v, a, t) -> (y, y')``: the loops' signals and their rates on symbols (a function of the
    library, for :func:`certified_sensors`)."""
    import casadi as ca

    q, v, a, t = ca.SX.sym("q", loops.nq), ca.SX.sym("v", loops.nv), ca.SX.sym("a", loops.nv), ca.SX.sym("t")
    return ca.Function("loop_sensor_check", [q, v, a, t],
                       [loops.sensors_at(q, v, t), loops.sensor_rates_at(q, v, a, t)])


def certified_sensors(loops: Any, check: Any) -> bool:
    """Whether a cached ``loop_sensor_check`` (:func:`sensor_check`) gives the loop signals and rates of ``loops``
    (built now from the plant's own numbers, independent of the library) at one fixed state, to 1e-9 (relative)."""
    rng = np.random.default_rng(20261126)
    q, v, a, t = (rng.uniform(-0.3, 0.3, size) for size in (loops.nq, loops.nv, loops.nv, 1))
    expected = [np.asarray(loops.sensors_at(q, v, t[0])), np.asarray(loops.sensor_rates_at(q, v, a, t[0]))]
    got = [np.asarray(value) for value in check(q, v, a, t[0])]
    return all(mine.shape == theirs.shape and bool(np.all(np.abs(mine - theirs) <= 1e-9 * (
        1.0 + np.max(np.abs(theirs), initial=0.0)))) for mine, theirs in zip(got, expected))


def scheme_description(model: PlanarModel, options: tuple) -> list[tuple[str, bytes]] | None:
    """The labelled description a planar scheme's library (numbers as inputs ``p``, no loops) is keyed on before
    anything is built, or ``None`` (key on the built functions).

    Parameters
    ----------
    model : PlanarModel
        Described without its numbers (``describe(..., numbers=False)``: every float by its zero pattern), with its
        :func:`structure_key` (the numbers the code keeps as constants); its other numbers are entries of ``p``,
        and a hit is certified against the numpy sweep (:func:`certified_hit`).
    options : tuple
        Everything else the builder reads (scheme, Newton tangent and fold, tolerance, iterations, actuators),
        described with every number (a scheme's coefficients and the tolerance are constants of the code).

    Returns
    -------
    list of (str, bytes) or None
    """
    from .model_description import describe

    structure, settings = describe(model, numbers=False), describe(("planar scheme", *options))
    if structure is None or settings is None:
        return None
    return [("planar structure", structure_key(model).encode()), ("planar scheme model", structure),
            ("planar scheme options", settings)]


def described_time_loop(description: list[tuple[str, bytes]] | None, build: Callable[[], tuple[Any, list]],
                        certify: Callable[[tuple], bool] | None, store_every: int, rows: int, name: str,
                        **options: Any) -> TimeLoop:
    """The compiled time loop (:func:`ctmm.generated_loop.compiled_time_loop`) keyed on ``description`` before
    anything is built, or on the built functions: when ``description`` is ``None``, or when a library found by it
    fails ``certify`` (a description without numbers does not determine them: the hit is checked, never trusted).

    Parameters
    ----------
    description : list of (str, bytes) or None
        :func:`scene_description`, :func:`scheme_description`.
    build : callable
        ``build() -> (step, extra)`` on symbols; called only when no library is found (or the found one fails).
    certify : callable or None
        ``certify(extra) -> bool`` on the loaded ``extra`` functions of a library found by ``description`` (not on
        one just built from it); ``None``: ``description`` is complete, a hit is taken.
    store_every, rows, name, **options
        Of :func:`ctmm.generated_loop.compiled_time_loop`.

    Returns
    -------
    TimeLoop
    """
    built: list = []
    if description is not None:
        def recorded() -> tuple[Any, list]:
            built.append(True)
            return build()

        loop = compiled_time_loop(recorded, store_every, rows, name, description=description, **options)
        if built or certify is None or certify(loop.extra):
            return loop
    step, extra = build()
    return compiled_time_loop(step, store_every, rows, name, extra=extra, **options)


def certified_hit(model: PlanarModel, acceleration: Any, parameters: np.ndarray) -> bool:
    """Whether a cached ``acceleration(q, v, u, p, t)`` gives the numpy sweep's accelerations of ``model``
    (:class:`~ctmm.planar.body_forms.PlanarScene`, independent of the generated code) with its
    ``parameters`` at one fixed state, without inputs, to 1e-9 (relative): the check that a library found
    by the description without numbers (:func:`scene_description`) computes this model.

    Parameters
    ----------
    model : PlanarModel
    acceleration : casadi.Function
        The library's ``acceleration(q, v, u, p, t)`` [rad/s^2, m/s^2].
    parameters : ndarray
        The model's :func:`~ctmm.compiled_parameters.parameter_vector` (SI).

    Returns
    -------
    bool
        ``False`` also when the numpy sweep fails at that state (then the scene is built).
    """
    rng = np.random.default_rng(20261125)
    n = model.n_coordinates
    q, v, t = rng.uniform(-0.3, 0.3, n), rng.uniform(-0.3, 0.3, n), 0.37
    try:
        expected = PlanarScene(model).accelerations(q[None, :], v[None, :], t)[0]
    except (ModelError, SimulationError, np.linalg.LinAlgError):
        return False
    got = np.asarray(acceleration(q, v, np.zeros(acceleration.size1_in(2)), parameters, t)).reshape(-1)
    return bool(np.all(np.isfinite(expected)) and np.max(np.abs(got - expected), initial=0.0)
                <= 1e-9 * (1.0 + np.max(np.abs(expected), initial=0.0)))
