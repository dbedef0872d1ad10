"""The one simulation verb, :func:`ctmm.simulate`: every system is simulated with all it contains.

A plain :class:`~ctmm.system.Chain` goes to the DT-TMM stepper (:func:`ctmm.timestep.simulate`);
a :class:`~ctmm.control.loops.ControlledChain`, or a chain with co-simulated ``controllers`` or
loop ``references``, goes to the controlled stepper
(:func:`ctmm.control.simulate.simulate_controlled`), so that no loop is ever dropped.  Both
share the pre-run stability check of the scheme (:mod:`ctmm.step_limit`) and the divergence
guard (:mod:`ctmm.guard`).
"""
from __future__ import annotations

from typing import Any, Mapping, Sequence

from .control.loops import ControlledChain
from .control.protocol import Controller, check_controllers, check_references
from .capabilities import require_chain
from .control.simulate import simulate_controlled
from .errors import ModelError
from .results import SimulationResult
from .schemes import Scheme
from .system import Chain
from .timestep import ForceHook
from .timestep import simulate as simulate_chain

__all__ = ["simulate"]


def simulate(system: Chain | ControlledChain, t_final: float, dt: float, *, scheme: Scheme | str = "newmark",
             x0: Mapping[str, float] | None = None, v0: Mapping[str, float] | None = None, t0: float = 0.0,
             controllers: Sequence[Controller] = (), references: Mapping[str, Any] | None = None,
             coupling: str = "hold", solver: str = "riccati", fast: bool | None = None,
             force_hook: ForceHook | None = None, progress: bool | None = None,
             stability_check: str | None = None, divergence_bound: float | None = None) -> SimulationResult:
    """Simulate a chain or a controlled chain in the time domain (DT-TMM).

    Parameters
    ----------
    system : Chain or ControlledChain
        The model; every :class:`~ctmm.control.loops.Feedback` loop of a controlled chain is
        closed during the run.
    t_final, dt : float
        End time and step [s].
    scheme : Scheme or str
        Integrator (:mod:`ctmm.schemes`).
    x0, v0 : mapping, optional
        Initial positions [m] / velocities [m/s] by element name.
    t0 : float
        Start time [s].
    controllers : sequence of Controller
        Co-simulated controllers (Python objects, FMUs).
    references : mapping, optional
        ``{loop name: r(t)}`` loop references [sensed unit].
    coupling : {"hold", "previous"}
        Algebraic-loop policy of co-simulated controllers (see
        :func:`~ctmm.control.simulate.simulate_controlled`); ``"previous"`` without
        ``controllers`` is refused (it would be ignored).
    solver, fast, force_hook
        Options of the uncontrolled stepper (:func:`ctmm.timestep.simulate`); not available
        with loops or controllers.
    progress : bool, optional
        Show a progress bar.
    stability_check : {"warn", "error", "ignore"}, optional
        Pre-run check of ``dt`` against the scheme's stability limit (:mod:`ctmm.step_limit`).
    divergence_bound : float, optional
        Largest allowed distance [m] of a point from rest (:class:`ctmm.guard.DivergenceGuard`).

    Returns
    -------
    SimulationResult
        With ``"<loop>.y"`` / ``"<loop>.u"`` and controller outputs when the system is controlled.

    Raises
    ------
    ModelError
        Bad input; a system that is not a chain; options that do not apply to the run
        (``solver``/``fast``/``force_hook`` with loops or controllers, ``coupling`` without
        controllers).
    SimulationError
        A failed run (divergence, non-finite state, failing user code), with ``partial_result``.
    """
    require_chain(system, "ctmm.simulate")
    controllers = check_controllers(controllers)
    references = check_references(references)
    if coupling != "hold" and not controllers:
        raise ModelError(f"coupling={coupling!r} only applies to co-simulated controllers, but controllers is "
                         f"empty; leave coupling at 'hold' (embedded loops are always solved implicitly)")
    controlled = isinstance(system, ControlledChain) or bool(controllers) or bool(references)
    if not controlled:
        return simulate_chain(system, t_final, dt, scheme=scheme, x0=x0, v0=v0, t0=t0, solver=solver, fast=fast,
                              force_hook=force_hook, progress=progress, stability_check=stability_check,
                              divergence_bound=divergence_bound)
    unsupported = {"solver": (solver, "riccati"), "fast": (fast, None), "force_hook": (force_hook, None)}
    for name, (value, default) in unsupported.items():
        if value is not default and value != default:
            raise ModelError(f"{name}={value!r} applies to uncontrolled chains only; a controlled run uses the "
                             f"Riccati DT-TMM stepper (leave {name} at {default!r})")
    return simulate_controlled(system, t_final, dt, scheme=scheme, x0=x0, v0=v0, t0=t0, references=references,
                               controllers=controllers, coupling=coupling, progress=progress,
                               stability_check=stability_check, divergence_bound=divergence_bound)
