"""What a system contains, and the refusals of verbs that cannot honour all of it.

Every public verb that is given a system either honours everything in it (loops, delays,
controllers, loads, prescribed motions) or refuses it with a :class:`~ctmm.errors.ModelError`
that says what is not supported and what to use instead.  The verbs call the helpers of this
module at their top; the table of what each verb honours is in ``docs/control.md`` (§4b).

A :class:`~ctmm.control.loops.ControlledChain` is recognised by its ``plant`` (a
:class:`~ctmm.system.Chain`) and ``loops`` attributes, so that this module does not import
:mod:`ctmm.control` (which imports the frequency-domain verbs that call it).
"""
from __future__ import annotations

from dataclasses import dataclass
from typing import Any

from .errors import ModelError
from .system import Chain

__all__ = ["SystemContents", "describe", "require_chain", "require_planar", "refuse_loops", "refuse_damping"]

_OTHER_PACKAGES = {
    "ctmm.planar.closed_loops": "the verbs ctmm.simulate, ctmm.linearize, ctmm.natural_frequencies, "
                                "ctmm.eigenvalue_count, ctmm.frequency_response (no feedback loops or stability tools "
                                "yet; docs/closed_loops.md)",
    "ctmm.planar": "the verbs that answer every model: ctmm.simulate, ctmm.linearize, ctmm.frequency_response, "
                   "ctmm.natural_frequencies, ctmm.mode_shapes (through the linearisation), ctmm.stability with "
                   "loops (ctmm.control.with_feedback)",
    "ctmm.flexible": "the verbs that answer every model (planar models with ctmm.flexible beams): ctmm.simulate, "
                     "ctmm.linearize, ctmm.frequency_response, ctmm.natural_frequencies, ctmm.mode_shapes, "
                     "ctmm.stability with loops",
    "ctmm.fem": "a ctmm.planar.PlanarModel holding it as a body (FiniteElementModel.subsystem(...) or a "
                "GlobalSubsystem in the element list), then every planar verb (docs/mixed.md); spatial: a "
                "ctmm.spatial.SpatialModel holding a SpatialSubsystem (SpatialFiniteElementModel.subsystem(...)), "
                "then every spatial verb (docs/mixed.md §7)",
    "ctmm.manipulator": "ctmm.manipulator.manipulator_scene (a ControlledModel for every verb; exact beam fields "
                        "with fields='exact'; the PZT voltage limit as loop saturation, on_limit='saturate')",
    "ctmm.spatial": "the verbs that answer every model: ctmm.simulate, ctmm.linearize, ctmm.frequency_response, "
                    "ctmm.natural_frequencies, ctmm.mode_shapes, ctmm.eigenvalue_count (through the linearisation), "
                    "ctmm.stability with loops (ctmm.control.with_feedback)",
    "ctmm.control.controlled_model": "the verbs that answer every model (planar and spatial plants with loops): "
                                     "ctmm.simulate, ctmm.linearize, ctmm.frequency_response, "
                                     "ctmm.control.loop_transfer_function / margins, ctmm.stability (delay_margin, "
                                     "stability_chart, characteristic_roots)",
}


@dataclass(frozen=True)
class SystemContents:
    """What a 1-D system holds that a verb must honour.

    Attributes
    ----------
    kind : str
        ``"chain"`` or ``"controlled chain"``.
    loops : tuple of str
        Names of the embedded feedback loops.
    delayed_loops : tuple of str
        Loops with a delay > 0 [s].
    lti_loops : tuple of str
        Loops whose gain is a python-control LTI controller ``C(s)``.
    damped : tuple of str
        Elements with nonzero damping [N s/m or N m s/rad] or otherwise not conservative
        (e.g. beams with a loss factor).
    """

    kind: str
    loops: tuple[str, ...]
    delayed_loops: tuple[str, ...]
    lti_loops: tuple[str, ...]
    damped: tuple[str, ...]


def _is_controlled(system: Any) -> bool:
    return isinstance(getattr(system, "plant", None), Chain) and hasattr(system, "loops")


def require_chain(system: Any, verb: str) -> None:
    """Refuse anything that is not a 1-D :class:`~ctmm.system.Chain` or ``ControlledChain``.

    Parameters
    ----------
    system : object
        What the user passed as ``system``.
    verb : str
        Public name of the calling verb, e.g. ``"ctmm.frequency_response"``.

    Raises
    ------
    ModelError
        Naming the type received and, for planar / flexible / manipulator models, their own verbs.
    """
    if isinstance(system, Chain) or _is_controlled(system):
        return
    module = type(system).__module__ or ""
    instead = next((hint for prefix, hint in _OTHER_PACKAGES.items() if module.startswith(prefix)), None)
    message = (f"{verb}: system must be a ctmm.Chain or a ctmm.control.ControlledChain, got "
               f"{type(system).__name__} ({system!r:.80})")
    if instead is not None:
        message += f"; a {type(system).__name__} is simulated or analysed with {instead}"
    raise ModelError(message)


def require_planar(model: Any, verb: str) -> None:
    """Refuse anything that is not a :class:`~ctmm.planar.model.PlanarModel` in a planar verb.

    Parameters
    ----------
    model : object
        What the user passed as ``model``.
    verb : str
        Public name of the calling verb(s), e.g. ``"ctmm.planar simulation"``.

    Raises
    ------
    ModelError
        Naming the type received; for a 1-D chain, the chain verbs.
    """
    from .planar.model import PlanarModel  # here, not at the top: ctmm.planar imports the chain verbs

    if isinstance(model, PlanarModel):
        return
    message = f"{verb}: model must be a ctmm.planar.PlanarModel, got {type(model).__name__} ({model!r:.80})"
    if isinstance(model, Chain) or _is_controlled(model):
        message += ("; a 1-D Chain or ControlledChain (loops included) is simulated with ctmm.simulate and "
                    "analysed with ctmm.frequency_response / ctmm.natural_frequencies / ctmm.stability")
    raise ModelError(message)


def describe(system: Any) -> SystemContents:
    """Loops, delays, LTI controllers and damping of a chain or controlled chain.

    Parameters
    ----------
    system : Chain or ControlledChain

    Returns
    -------
    SystemContents
    """
    require_chain(system, "ctmm.capabilities.describe")
    loops = tuple(getattr(system, "loops", ()))
    plant = system.plant if _is_controlled(system) else system
    return SystemContents(
        kind="controlled chain" if _is_controlled(system) else "chain",
        loops=tuple(lp.name for lp in loops),
        delayed_loops=tuple(lp.name for lp in loops if lp.delay > 0),
        lti_loops=tuple(lp.name for lp in loops if lp.is_lti),
        damped=tuple(e.name for e in plant.elements
                     if getattr(e, "damping", 0.0) or getattr(e, "is_conservative", True) is False))


def refuse_loops(system: Any, verb: str, instead: str) -> Chain:
    """The plain chain behind ``system``, or a refusal if it closes feedback loops.

    A controlled chain without loops is its plant (answered as such); with loops the verb
    would answer for the open loop, so it refuses.

    Parameters
    ----------
    system : Chain or ControlledChain
    verb : str
        Public name of the calling verb.
    instead : str
        What to use for the closed loop.

    Returns
    -------
    Chain

    Raises
    ------
    ModelError
        ``system`` closes loops; the message names them and says what to use.
    """
    require_chain(system, verb)
    if not _is_controlled(system):
        return system
    names = [lp.name for lp in system.loops]
    if names:
        raise ModelError(f"{verb} cannot honour the feedback loops {names} of {system.name!r}: it describes "
                         f"an uncontrolled chain; for the closed loop use {instead}; for the plant pass "
                         f"system.plant")
    return system.plant


def refuse_damping(system: Chain, verb: str, instead: str) -> None:
    """Refuse a chain with damping or non-conservative elements for an undamped-only verb.

    Parameters
    ----------
    system : Chain
    verb : str
        Public name of the calling verb.
    instead : str
        What to use for damped chains.

    Raises
    ------
    ModelError
        Naming the first damped element and its damping.
    """
    for element in system.elements:
        damping = getattr(element, "damping", 0.0)
        if damping:
            raise ModelError(f"{verb} needs an undamped system, but {element.name!r} has damping={damping!r}; "
                             f"use {instead}")
        if getattr(element, "is_conservative", True) is False:
            raise ModelError(f"{verb} needs a conservative system; {element.name!r} is not; use {instead}")
