"""Which spatial models the generated paths compile, time signals included (issue 13).

The loads and driven joints of a :class:`~ctmm.spatial.model.SpatialModel` carry time signals (forces and
moments; prescribed positions, rates and accelerations).  The terms
(:meth:`ctmm.spatial.body_forms.SpatialScene.terms`) evaluate them at a number ``t``; at a casadi time symbol
they take the symbolic form of the :mod:`ctmm.signals` classes (:func:`ctmm.signals.symbolic_signal`:
constants, sines, steps, square waves -- the same operations as the classes' ``__call__``), so the generated
RK4 (:class:`~ctmm.compiled_spatial.CompiledSpatialScene`) follows them at every stage time, and the generated
DT-TMM schemes (:class:`~ctmm.compiled_spatial_schemes.CompiledSpatialScheme`) at the step time, with feedback
loops too (:mod:`ctmm.compiled_spatial_loops`, :mod:`ctmm.compiled_spatial_scheme_loops`; their sensors at the
state only: one that moves with a driven joint's signal is refused there), the tree's loads of kinematic loop
models with their driven joints (:mod:`ctmm.compiled_spatial_kinematic_loops`,
:mod:`ctmm.compiled_spatial_loop_schemes`; not in the loop driver's generated run) and exported FMUs
(:mod:`ctmm.fmu_export_spatial`, at the FMU's time).  User callables have no symbolic form and are refused by name.

:func:`spatial_compile_refusal` says why a model cannot be compiled; with ``time_signals=False`` (the generated
paths that state the terms at one time: the frequency-domain sensitivities about an equilibrium) every load and
driven motion must be a :class:`~ctmm.signals.Constant`; the time-history sensitivities
(:mod:`ctmm.sensitivity_time_spatial`) take the signals on the time symbol of their RK4 step.
"""
from __future__ import annotations

from typing import Any, Sequence

from .signals import SYMBOLIC_FIELDS, Constant, signal_parameters
from .spatial.model import SpatialModel

__all__ = ["spatial_compile_refusal"]


def spatial_compile_refusal(model: Any, *, time_signals: bool = False) -> str:
    """Why ``model`` cannot be compiled by the generated spatial paths (empty string when it can).

    Parameters
    ----------
    model : object
        A :class:`~ctmm.spatial.model.SpatialModel` compiles when it has coordinates, joint laws with a casadi
        form and beams without time-dependent loads or modal force hooks.
    time_signals : bool
        ``True``: loads and driven joints may carry signals with a symbolic form
        (:data:`ctmm.signals.SYMBOLIC_FIELDS`; the generated RK4 and DT-TMM schemes, with or without feedback
        loops, state them on the time symbol); ``False``: they must be constants (paths that state the terms at
        one time).
    """
    if not isinstance(model, SpatialModel):
        return f"a ctmm.spatial.SpatialModel is compiled here, got {type(model).__name__}"
    if model.n_velocities == 0:
        return f"model {model.name!r} has no coordinates (every joint is welded or driven): nothing to integrate"
    laws = [f"{joint.name!r} ({joint.law!r})" for joint in model.joints
            if getattr(joint, "law", None) is not None and not joint.law.expressible]
    if laws:
        return (f"model {model.name!r} has nonlinear joint laws without a casadi form: {', '.join(laws)}; give "
                "CallableLaw a casadi-compatible force and no derivatives, or use ctmm.simulate without compiled=True")
    forces = [repr(body.name) for body in model.bodies if getattr(body, "nonlinear_force", None) is not None]
    if forces:
        return (f"model {model.name!r} has subsystems with a nonlinear_force: {', '.join(forces)} (Python code "
                "f(u, u_dot, t), which generated kernels cannot evaluate; use ctmm.simulate without compiled=True)")
    allowed = (lambda f: signal_parameters(f) is not None) if time_signals else (lambda f: isinstance(f, Constant))
    reasons = [f"driven joint {joint.name!r} ({_offending(joint, ('position', 'rate', 'acceleration'), allowed)})"
               for joint in model.joints if joint.driven and _offending(joint, ('position', 'rate', 'acceleration'),
                                                                        allowed)]
    reasons += [f"load {load.name!r} ({_offending(load, ('force', 'moment'), allowed)})" for load in model.loads
                if _offending(load, ('force', 'moment'), allowed)]
    reasons += [f"beam {body.name!r} (modal forces or distributed load)" for body in model.bodies
                if getattr(body, "time_dependent", False)]
    if not reasons:
        return ""
    if time_signals:
        return (f"model {model.name!r} has time signals without a symbolic form in " + ", ".join(reasons) + " (Python "
                "callables are not compiled; use ctmm.signals " + ", ".join(kind.__name__ for kind in SYMBOLIC_FIELDS)
                + ", or ctmm.simulate without compiled=True)")
    return (f"model {model.name!r} has signals that are not constants in " + ", ".join(reasons) + " (frequency-"
            "domain sensitivities linearise about one equilibrium, the terms at one time; time-history sensitivities "
            "(ctmm.sensitivity.simulation_sensitivity), the generated RK4 and DT-TMM schemes of a spatial model, "
            "with or without feedback loops, and exported FMUs follow ctmm.signals " + ", ".join(
                kind.__name__ for kind in SYMBOLIC_FIELDS) + "; or use ctmm.simulate without compiled=True)")


def _offending(element: Any, fields: Sequence[str], allowed: Any) -> str:
    """``"<field>[i] is a <class>"`` for the first signal of ``element``'s ``fields`` that is not ``allowed``
    (empty string when all are)."""
    return next((f"{field}[{i}] is a {type(f).__name__}" for field in fields
                 for i, f in enumerate(getattr(element, field)) if not allowed(f)), "")

