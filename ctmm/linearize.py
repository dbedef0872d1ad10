"""``ctmm.linearize``: one linear state-space model of every ctmm model, delays beside it.

:func:`linearize` returns a :class:`LinearizedSystem`: a :class:`control.StateSpace` of the
delay-free part with named states, inputs and outputs, the delayed loops left open beside it
(:class:`DelayedLoop`), and the operating point.

* 1-D :class:`~ctmm.system.Chain` / :class:`~ctmm.control.loops.ControlledChain`: the exact
  lumped realisation of :func:`ctmm.lumped_realisation.chain_state_space` (the chain is linear; no operating
  point).
* :class:`~ctmm.planar.model.PlanarModel` (rigid or with :mod:`ctmm.flexible` beams) and
  ``ctmm.control.ControlledModel``: the tangent of ``qddot = f(q, qdot, u)`` at an operating
  point (:class:`OperatingPoint`), states ``[q, qdot]`` named by the coordinates
  (``"arm.q1"``, ``"arm.q1_dot"``), deviations from the operating point.
* :class:`~ctmm.spatial.model.SpatialModel` and a ``ControlledModel`` on one: the same tangent in
  tangent coordinates (rotation vectors for quaternion joints) and velocities, sensor and actuator ports of
  :mod:`ctmm.spatial.ports`, :mod:`ctmm.spatial_linearization`; the loops closed as for planar models
  (:mod:`ctmm.controlled_linearization`).

On the package, ``ctmm.linearize`` is the function; the result types are importable as
``from ctmm.linearize import LinearizedSystem, DelayedLoop, OperatingPoint`` (defined in
:mod:`ctmm.linearized`).

Planar Jacobians (accuracy)
---------------------------
``df/dq`` and ``df/dqdot`` are taken by complex step through the batched terms of the one
articulated sweep (:mod:`ctmm.articulated`; exact to round-off), cross-checked along one direction
against a Richardson difference of :func:`ctmm.planar.accelerations`: the disagreement (plus that
difference's error estimate), divided by ``max |A|``, is ``OperatingPoint.jacobian_error``.  When
they disagree by more than ``1e-6``, and for models not on the element protocol yet
(translational-spring hinges, user state laws on beams), every column is a central difference with
Richardson extrapolation over the steps ``h, h/2, h/4`` (``h = 1e-3 max(1, min(|x|, 2 pi), |x| / 1e4)``; the difference
between the two extrapolated estimates as a conservative truncation error, plus the slope jump where
a kink sits exactly at the operating point, detected by the second differences), and the
linearisation is refused (:class:`~ctmm.errors.ModelError`) if that estimate exceeds ``1e-6``.
``f`` is affine in the actuator inputs, so the columns of ``B`` are exact differences of unit
inputs.  ``C`` comes from the sensor Jacobians of :mod:`ctmm.planar.ports` (outputs are deviations of the sensed
values from their values at the operating point); ``D = 0`` (no planar sensor depends on an
input).

Loops
-----
A loop ``u = -C(s) e^{-s tau} y`` without delay is closed inside ``A`` (a static gain, or the
states of its LTI controller appended as ``"<loop>.controller<k>"``).  A loop with
``tau > 0`` is left open: the state space gets an input ``"<loop>_u"`` (the loop force, entering
through the loop's actuator terms and weights) and an output ``"<loop>_y"`` (the weighted sensor
sum), and :attr:`LinearizedSystem.delays` lists it as ``DelayedLoop(name, gain, delay)`` meaning
``u_j(t) = -gain_j * y_j(t - delay_j)``.  python-control reserves ``'.'`` in signal names, so every
ctmm name is labelled through :func:`ctmm.interop.control_name` (``"motor.torque"`` ->
``"motor_torque"``).
"""
from __future__ import annotations

from typing import Any, Sequence

import numpy as np

from . import validation
from .errors import ModelError
from .lumped_realisation import chain_state_space, default_signal_names
from .linearized import DelayedLoop, LinearizedSystem, OperatingPoint, control_name
from .system import Chain

__all__ = ["linearize", "LinearizedSystem", "DelayedLoop", "OperatingPoint"]


def _is_planar(system: Any) -> bool:
    from .planar.model import PlanarModel

    return isinstance(system, PlanarModel)


def linearize(system: Any, operating_point: Any = None, *, inputs: str | Sequence[str] | None = None,
              outputs: str | Sequence[str] | None = None, allow_nonequilibrium: bool = False
              ) -> LinearizedSystem:
    """Linear state-space model of any ctmm model (module docstring).

    Parameters
    ----------
    system : Chain, ControlledChain, PlanarModel, SpatialModel or ControlledModel (planar or spatial plant)
        The model; loops with a delay are returned open beside the state space.
    operating_point : OperatingPoint, (q, qdot), mapping or None
        Spatial models: ``(q, v)``, ``{"q", "v", "t"}`` or ``None`` (the static equilibrium by
        pseudo-transient Newton on the sweep, :func:`ctmm.spatial_linearization.static_equilibrium`,
        ``stable=True``: a statically stable one, or refused naming the directions of negative stiffness).
        Planar models: ``(q, qdot)`` or ``{"q": ..., "qdot": ..., "t": ...}`` or a
        mapping from coordinate names to values (rates zero); ``None``: the static equilibrium
        found by :func:`ctmm.planar.equilibrium.static_equilibrium` from
        :func:`ctmm.planar.equilibrium.hanging_configuration` (every centre of mass straight below
        its hinge; refine-by-root-search, so hinge springs and loads are honoured; ``stable=True``: a statically stable one).  Must be ``None`` for chains.
    inputs : str or sequence of str, optional
        Exogenous inputs: chain force inputs / loop references; planar actuator names of
        :func:`ctmm.planar.ports.actuator_names` (default: every actuator not used by a loop);
        spatial input components of :func:`ctmm.spatial_linearization.input_names` and actuator ports
        (default: the input components not driven by a loop);
        ``[]``: no exogenous input (e.g. for the eigenvalues of ``A``; refused with a single
        output and no delayed loop, a shape python-control cannot hold).
    outputs : str or sequence of str, optional
        Chain signal names; planar sensor names of :mod:`ctmm.planar.ports` (default: every
        coordinate); ``"<loop>.y"`` (sensed value) and ``"<loop>.u"`` (loop force) of a loop
        without delay; spatial sensor ports, tangent coordinates and velocities (default: the tangent
        coordinates).
    allow_nonequilibrium : bool
        Planar and spatial models: accept an operating point that is not an equilibrium (nonzero rates or
        accelerations, now or a little later: a driven hinge in motion, a time-varying load).  The result is then the tangent at that instant only (the constant
        term ``f(x0)`` is dropped); by default such a point is refused.

    Returns
    -------
    LinearizedSystem

    Raises
    ------
    ModelError
        Unknown model type or names, an operating point given for a chain, a non-equilibrium
        point (unless allowed), inaccurate Jacobians, an algebraic loop.

    Examples
    --------
    >>> import ctmm
    >>> from ctmm.elements import Fixed, Spring, Mass, Free
    >>> chain = ctmm.Chain("sdof", [Fixed("wall"), Spring("k", 100.0), Mass("m", 1.0), Free("end")])
    >>> lin = ctmm.linearize(chain)
    >>> lin.state_space.input_labels, lin.state_space.output_labels, lin.delays
    (['m_force'], ['m_x'], ())
    """
    validation.flag("allow_nonequilibrium", allow_nonequilibrium)
    from .planar.closed_loops import KinematicLoopModel

    plant = getattr(system, "plant", None)
    if isinstance(system, KinematicLoopModel) or isinstance(plant, KinematicLoopModel):   # docs/closed_loops.md §3a, 3c
        from .planar.loop_verbs import linearize_loops

        return linearize_loops(system, operating_point, inputs=inputs, outputs=outputs,
                               allow_nonequilibrium=allow_nonequilibrium)
    from .spatial.closed_loops import SpatialKinematicLoopModel

    if isinstance(system, SpatialKinematicLoopModel) or isinstance(plant, SpatialKinematicLoopModel):  # closed_loops §8
        from .spatial.closed_loop_verbs import linearize_spatial_loops

        return linearize_spatial_loops(system, operating_point, inputs=inputs, outputs=outputs,
                                       allow_nonequilibrium=allow_nonequilibrium)
    loops = tuple(getattr(system, "loops", ()))
    if isinstance(system, Chain) or (isinstance(plant, Chain) and hasattr(system, "loops")):
        if operating_point is not None:
            raise ModelError(f"linearize: a 1-D chain is linear and has no operating point; got "
                             f"operating_point={operating_point!r} (pass None)")
        return _linearize_chain(system, inputs, outputs)
    if _is_planar(system) or (_is_planar(plant) and hasattr(system, "loops")):
        from .planar_linearization import linearize_planar

        model = system if _is_planar(system) else plant
        return linearize_planar(model, loops if not _is_planar(system) else (), operating_point,
                                inputs=inputs, outputs=outputs, allow_nonequilibrium=allow_nonequilibrium)
    if _is_spatial(system) or (_is_spatial(plant) and hasattr(system, "loops")):
        from .spatial_linearization import linearize_spatial

        model = system if _is_spatial(system) else plant
        return linearize_spatial(model, operating_point, inputs=inputs, outputs=outputs,
                                 allow_nonequilibrium=allow_nonequilibrium,
                                 loops=loops if not _is_spatial(system) else ())
    raise ModelError(f"linearize: system must be a ctmm.Chain, ctmm.control.ControlledChain, "
                     f"ctmm.planar.PlanarModel, ctmm.control.ControlledModel or ctmm.spatial.SpatialModel, got "
                     f"{type(system).__name__} ({system!r:.80})")


def _is_spatial(system: Any) -> bool:
    from .spatial.model import SpatialModel

    return isinstance(system, SpatialModel)


# ------------------------------------------------------------------------------- chains
def _linearize_chain(system: Any, inputs, outputs) -> LinearizedSystem:
    import control

    from .control.loops import actuator_inputs
    from .controlled_linearization import requested_outputs

    controlled = not isinstance(system, Chain)
    loops = tuple(system.loops) if controlled else ()
    delayed = [lp for lp in loops if lp.delay > 0.0]
    base = system.with_loops([lp for lp in loops if lp.delay == 0.0]) if controlled else system
    d_in, d_out = default_signal_names(base)
    delayed_names = {lp.name for lp in delayed}
    exo = d_in if inputs is None else list(validation.names("inputs", inputs))
    req = d_out if outputs is None else list(validation.names("outputs", outputs))
    for name in exo:
        if name.partition(".")[0] in delayed_names:
            raise ModelError(f"linearize: input {name!r} belongs to the delayed loop "
                             f"{name.partition('.')[0]!r}, whose force is the input '<loop>_u' already")
    requested_outputs(delayed, req, ())    # refuses a delayed loop's '.y', '.u' (its ports), as planar models do
    forces = {lp.name: actuator_inputs(system, lp.name) for lp in delayed}
    sensors = {lp.name: lp.terms for lp in delayed}
    all_in = list(dict.fromkeys(exo + [n for lp in delayed for n, _ in forces[lp.name]]))
    all_out = list(dict.fromkeys(req + [n for lp in delayed for n, _ in sensors[lp.name]]))
    ss = chain_state_space(base, inputs=all_in, outputs=all_out)
    A, B, C, D = (np.asarray(m, dtype=float) for m in (ss.A, ss.B, ss.C, ss.D))
    col = {n: k for k, n in enumerate(all_in)}
    row = {n: k for k, n in enumerate(all_out)}
    S_in = np.zeros((len(all_in), len(exo) + len(delayed)))
    for k, name in enumerate(exo):
        S_in[col[name], k] = 1.0
    S_out = np.zeros((len(req) + len(delayed), len(all_out)))
    for k, name in enumerate(req):
        S_out[k, row[name]] = 1.0
    for j, lp in enumerate(delayed):
        for name, weight in forces[lp.name]:
            S_in[col[name], len(exo) + j] += weight
        for name, weight in sensors[lp.name]:
            S_out[len(req) + j, row[name]] += weight
    labels_in = [control_name(n) for n in exo] + [control_name(f"{lp.name}.u") for lp in delayed]
    labels_out = [control_name(n) for n in req] + [control_name(f"{lp.name}.y") for lp in delayed]
    out = control.ss(A, B @ S_in, S_out @ C, S_out @ D @ S_in, inputs=labels_in, outputs=labels_out,
                     states=list(ss.state_labels), name=ss.name)
    return LinearizedSystem(out, tuple(DelayedLoop(lp.name, lp.gain, lp.delay) for lp in delayed), None)
