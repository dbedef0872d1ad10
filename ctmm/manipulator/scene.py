"""The controlled flexible manipulator as a scene of general elements and general loops.

The plant is an ordinary planar model -- ``Fixed("ground")`` -> ``ActuatedHinge("motor")``
(a torque input, no law of its own) -> ``RigidBody("hub")`` -> ``FixedMounting("mount")`` ->
:class:`~ctmm.flexible.ModalBeam` ``"arm"`` -- and both control laws of seed 001 §9.6.1 are
ordinary :class:`~ctmm.control.Feedback` loops on its ports (:mod:`ctmm.planar.ports`):

* ``"hub_pd"`` -- the PD motor law (seed eq. (9.64))
  ``tau = kp (theta_d - theta) + kd (theta_d_dot - theta_dot)`` at ``t - delay``:
  sensor ``y = kp * motor.angle + kd * motor.rate``, gain 1, actuator ``motor.torque``,
  reference ``r(t) = kp theta_d(t) + kd theta_d_dot(t)`` (:func:`scene_references`);
* ``"<patch>"`` for every PZT patch -- the slope-rate law ``V = -G Psi eta_dot`` (seed eq.
  (9.65); :class:`~ctmm.manipulator.PZTFeedback`) on the arm's **station ports**
  (:mod:`ctmm.flexible.stations`; stations ``"<patch>_x1"``, ``"<patch>_x2"`` at the patch
  ends): patch ``j``'s loop senses ``sum_i G_ji (arm.<patch_i>_x2.slope_rate -
  arm.<patch_i>_x1.slope_rate)`` with gain 1, so its output ``"<patch>.u"`` is the voltage
  ``V_j`` [V], and acts with the moment pair ``[(arm.<patch_j>_x1.moment, -c_a_j),
  (arm.<patch_j>_x2.moment, +c_a_j)]``.  On the modal beam that is ``Q_k = c_a_j Psi_jk V_j``,
  ``Psi_jk = phi_k'(x2_j) - phi_k'(x1_j)``; the ports are physical (slopes and moments at
  points), so the same loops close an exact beam field as well.

The arm also has a station ``"tip"`` (:data:`TIP_STATION`) at its free end: ``"arm.tip.w"`` is
the tip deflection in the hub frame (the arm's root tangent), ``u(L)`` [m] -- the quantity the
seed's figures and the frequency responses report.

So the manipulator is simulated by :func:`ctmm.simulate`, linearised by :func:`ctmm.linearize`
and analysed by the stability tools like any other controlled model; nothing in the verbs knows
it is a manipulator.  The PZT amplifier limit (``pzt.on_limit="saturate"``) is each patch loop's
``saturation=(-V_max, V_max)`` [V] (:class:`~ctmm.control.Feedback`): honoured by
:func:`ctmm.simulate` (every method; ``"<patch>.u_demand"``, ``"<patch>.saturated"`` and
``info["time_saturated_s"]`` in the result), refused by the linear verbs (build the scene with
``on_limit="report"`` for the small-signal model inside the limits).  With ``on_limit="report"`` the
loops are unclipped and the result's ``"<patch>.u"`` are the demanded voltages (compare them with
``manipulator.voltage_limit``); ``on_limit="raise"`` is refused here (only
:class:`~ctmm.manipulator.compiled.CompiledManipulator` checks it, after its run).
"""
from __future__ import annotations

from typing import Any, Callable

import numpy as np

from .. import validation
from ..control.controlled_model import ControlledModel
from ..control.loops import Feedback
from ..errors import ModelError
from ..flexible import ModalBeam
from ..planar import ActuatedHinge, Fixed, PlanarModel, RigidBody
from ..planar.elements import FixedMounting
from .laws import HubPD, PZTFeedback, check_pzt
from .parameters import Manipulator

__all__ = ["manipulator_plant", "manipulator_scene", "scene_references", "arm_beam", "patch_slope_matrix",
           "patch_stations", "HUB_LOOP", "TIP_STATION"]

HUB_LOOP = "hub_pd"
#: Station at the arm's free end: ``"arm.tip.w"`` is the hub-frame tip deflection ``u(L)`` [m].
TIP_STATION = "tip"


def manipulator_plant(manipulator: Manipulator, *, n_modes: int = 3, geometric_stiffening: bool = True,
                      hub_mass: float = 1.0) -> PlanarModel:
    """The open-loop manipulator: hub on a torque-driven hinge carrying the modal beam ``"arm"``.

    Parameters
    ----------
    manipulator : Manipulator
        Arm, hub and patches (:mod:`ctmm.manipulator.parameters`).
    n_modes : int
        Clamped-free modes of the arm (seed: 3).
    geometric_stiffening : bool
        Centrifugal stiffening of the arm.
    hub_mass : float
        Hub mass [kg] (its centre is the pivot: it enters only the pivot reaction).
    """
    if not isinstance(manipulator, Manipulator):
        raise ModelError(f"manipulator must be a ctmm.manipulator.Manipulator, got {manipulator!r}")
    if isinstance(n_modes, bool) or not isinstance(n_modes, (int, np.integer)) or n_modes < 1:
        raise ModelError(f"n_modes must be an integer >= 1, got {n_modes!r}")
    beam = arm_beam(manipulator, n_modes, geometric_stiffening)
    hub = RigidBody("hub", mass=validation.positive("hub_mass", hub_mass), inertia=manipulator.hub.inertia,
                    center_of_mass=(0.0, 0.0), outboard=(manipulator.hub.radius, 0.0))
    return PlanarModel.chain("manipulator", [Fixed("ground"), ActuatedHinge("motor"), hub, FixedMounting("mount"), beam],
                             gravity=(0.0, 0.0))


def arm_beam(manipulator: Manipulator, n_modes: int, geometric_stiffening: bool) -> ModalBeam:
    """The arm as the modal beam ``"arm"`` (``n_modes`` clamped-free modes, Kelvin-Voigt damping)
    with a station at each patch end (:func:`patch_stations`) and :data:`TIP_STATION` at ``x = L``."""
    arm = manipulator.arm
    return ModalBeam("arm", length=arm.length, bending_stiffness=arm.bending_stiffness,
                     mass_per_length=arm.mass_per_length, n_modes=int(n_modes),
                     stiffness_damping=arm.kelvin_voigt_time, geometric_stiffening=validation.flag("geometric_stiffening", geometric_stiffening),
                     stations={**patch_stations(manipulator), TIP_STATION: arm.length})


def patch_stations(manipulator: Manipulator) -> dict[str, float]:
    """``{"<patch>_x1": start, "<patch>_x2": end}`` [m from the arm root] of every patch."""
    stations = {}
    for patch in manipulator.patches:
        stations[f"{patch.name}_x1"], stations[f"{patch.name}_x2"] = patch.start, patch.end
    return stations


def patch_slope_matrix(beam: ModalBeam, manipulator: Manipulator) -> np.ndarray:
    """``Psi`` (P, n): slope difference over each patch per unit modal coordinate [rad/m],
    ``Psi_jk = phi_k'(x2_j) - phi_k'(x1_j)``."""
    return np.array([beam.mode_slopes(x2) - beam.mode_slopes(x1) for x1, x2 in manipulator.patch_ends]
                    ).reshape(-1, beam.n_modes)


def manipulator_scene(manipulator: Manipulator, *, pd: HubPD | None, pzt: PZTFeedback | None, n_modes: int = 3,
                      geometric_stiffening: bool = True, hub_mass: float = 1.0) -> ControlledModel:
    """The controlled manipulator: :func:`manipulator_plant` with the PD and PZT laws as loops.

    Parameters
    ----------
    manipulator : Manipulator
    pd : HubPD or None
        The hub PD (loop ``"hub_pd"``; its delay is the loop delay).  ``None``: no hub loop.
    pzt : PZTFeedback or None
        Slope-rate feedback to the patches (one loop per patch, named after the patch).  Its
        ``on_limit``: ``"report"`` unclipped loops, ``"saturate"`` loops with
        ``saturation=(-V_max, V_max)``; ``"raise"`` is refused (:class:`ModelError`).
    n_modes, geometric_stiffening, hub_mass
        As in :func:`manipulator_plant`.

    Returns
    -------
    ControlledModel
        Simulate with ``references=scene_references(pd, move)`` so that the hub tracks ``move``.
    """
    plant = manipulator_plant(manipulator, n_modes=n_modes, geometric_stiffening=geometric_stiffening,
                              hub_mass=hub_mass)
    loops = []
    if pd is not None:
        if not isinstance(pd, HubPD):
            raise ModelError(f"pd must be a ctmm.manipulator.HubPD or None, got {pd!r}")
        loops.append(Feedback(HUB_LOOP, sensor=[("motor.angle", pd.kp), ("motor.rate", pd.kd)],
                              actuator="motor.torque", gain=1.0, delay=pd.delay))
    if pzt is not None:
        check_pzt(pzt, manipulator.n_patches)
        if pzt.on_limit == "raise":
            raise ModelError("pzt: on_limit='raise' is not available on the scene (a loop does not stop a run at "
                             "its limit); use on_limit='saturate' (the amplifier clips; '<patch>.u_demand' and "
                             "'<patch>.saturated' in the result), on_limit='report' (unclipped; the voltages are "
                             "'<patch>.u' in the result) or the CompiledManipulator, which raises after its run")
        limit = manipulator.voltage_limit
        saturation = (-limit, limit) if pzt.on_limit == "saturate" else None
        ca = manipulator.moments_per_volt
        patches = manipulator.patches
        for j, patch in enumerate(patches):                         # V_j = -sum_i G_ji slope rate over patch i
            sensor = [(f"arm.{other.name}_x{end}.slope_rate", float(sign * pzt.gains[j, i]))
                      for i, other in enumerate(patches) if pzt.gains[j, i] != 0.0
                      for end, sign in ((1, -1.0), (2, 1.0))]
            actuator = [(f"arm.{patch.name}_x1.moment", -float(ca[j])), (f"arm.{patch.name}_x2.moment", float(ca[j]))]
            if sensor and ca[j] != 0.0:
                loops.append(Feedback(patch.name, sensor=sensor, actuator=actuator, gain=1.0, delay=pzt.delay,
                                      saturation=saturation))
    return ControlledModel(plant, loops)


def scene_references(pd: HubPD, move: Any) -> dict[str, Callable[[float], float]]:
    """``{"hub_pd": r}`` with ``r(t) = kp theta_d(t) + kd theta_d_dot(t)`` for a move with
    ``angle(t)`` [rad] and ``rate(t)`` [rad/s] (e.g. :class:`~ctmm.manipulator.CycloidalMove`)."""
    if not isinstance(pd, HubPD):
        raise ModelError(f"pd must be a ctmm.manipulator.HubPD, got {pd!r}")
    for attribute in ("angle", "rate"):
        if not callable(getattr(move, attribute, None)):
            raise ModelError(f"move must provide angle(t) and rate(t), got {move!r}")
    kp, kd = pd.kp, pd.kd
    return {HUB_LOOP: lambda t: kp * move.angle(t) + kd * move.rate(t)}
