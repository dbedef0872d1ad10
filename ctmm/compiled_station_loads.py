"""Beam station forces and moments in the generated planar sweep (issue 13 item 1).

A station force ``"<beam>.<station>.force"`` or moment ``"<beam>.<station>.moment"`` of a modal beam
(:mod:`ctmm.planar.ports`) loads the beam's modal equations (``phi_k(x) F`` or ``phi_k'(x) M``) and its
floating frame: the wrench ``(0, F, x F)`` or ``(0, 0, M)`` in frame axes, moment about the frame's root
(:attr:`ctmm.planar.ports.ActuatorInputs.frame_wrench`; a station force needs an axially rigid first-order
beam, so its arm ``x`` is a constant).  Per unit value both are numbers, so the loads of inputs ``u`` are
affine in ``u``: the modal part enters the body's element terms as its modal actuator forces
(:func:`ctmm.compiled_scene_fold.symbolic_inputs`), the frame part as an applied wrench at the inboard point.  On
the protocol (:mod:`ctmm.protocol`, ``[F_in ; 0] = M x + h + ...``) that is
``h <- h - [R f ; m ; 0]`` (``R`` the frame's rotation), what the numpy sweep does with
:meth:`~ctmm.planar.ports.ActuatorInputs.inboard_wrench` (and what :mod:`ctmm.compiled_cut_points` does with a
cut force on a beam point).
"""
from __future__ import annotations

from dataclasses import replace
from typing import Any, Mapping, Sequence

import numpy as np

from .compiled_planar_sensors import SymbolicKinematics
from .compiled_scene_fold import symbolic_inputs
from .ops import CASADI
from .planar.body_forms import PlanarScene
from .planar.model import PlanarModel
from .planar.ports import ActuatorInputs

__all__ = ["frame_wrenches", "symbolic_terms_with_station_loads"]


def frame_wrenches(units: Sequence[ActuatorInputs], u: Any) -> dict[int, list]:
    """``{beam body: [f_x, f_y, moment about the root]}`` (frame axes [N, N, N m]) of the inputs ``u`` (casadi
    symbols, one per unit): ``sum_k u_k units[k].frame_wrench``."""
    frame: dict[int, list] = {}
    for k, unit in enumerate(units):
        for j, wrench in unit.frame_wrench.items():
            row = frame.setdefault(int(j), [0.0, 0.0, 0.0])
            for c in range(3):
                if wrench[c]:
                    row[c] = row[c] + u[k] * float(wrench[c])
    return frame


def symbolic_terms_with_station_loads(model: PlanarModel, units: Sequence[ActuatorInputs], q: Any, v: Any, u: Any,
                                      numbers: Any, frame_loads: Mapping[int, tuple[Any, Any]] | None = None
                                      ) -> tuple[PlanarScene, list, list]:
    """``(scene, bodies, joints)``: the element terms of ``model`` on the casadi SX symbols ``q, v`` with the inputs
    ``u`` (one per entry of ``units``, each input's loads per unit value, station loads included: module docstring)
    and the scene's numbers ``numbers`` (:func:`ctmm.compiled_parameters.symbolic_numbers`), for
    :func:`ctmm.articulated.articulated_sweep` on ``scene.tree``.

    ``frame_loads``: further loads ``{deformable body: (wrench, generalised forces)}`` (expressions), the wrench
    ``(f_x, f_y, moment about the root)`` [N, N, N m] in frame axes on its floating frame and the forces on its
    internal coordinates, added to those of ``u`` (cut forces at deformable points, :mod:`ctmm.compiled_cut_points`).
    """
    import casadi as ca

    plain = [ActuatorInputs(unit.hinge_torque, unit.body_force, unit.modal_force) for unit in units]
    given = symbolic_inputs(model, plain, u)
    frame = frame_wrenches(units, u)
    if frame_loads:
        if given is None:
            given = ActuatorInputs(np.zeros(model.n_bodies, dtype=object), np.zeros((model.n_bodies, 3), dtype=object),
                                   {})
        modal = dict(given.modal_force)
        for j, (wrench, forces) in frame_loads.items():
            current = modal.get(j, np.zeros(len(forces), dtype=object))
            modal[j] = np.empty(len(forces), dtype=object)
            modal[j][:] = [current[i] + forces[i] for i in range(len(forces))]
            row = frame.setdefault(int(j), [0.0, 0.0, 0.0])
            frame[int(j)] = [row[c] + wrench[c] for c in range(3)]
        given = ActuatorInputs(given.hinge_torque, given.body_force, modal)
    scene = PlanarScene(model)
    bodies, joints = scene.terms(CASADI, q, v, 0.0, given, numbers)
    if frame:
        kinematics = SymbolicKinematics(model, q, v, driven=numbers.driven)
        for j, (f1, f2, moment) in frame.items():
            c, s = kinematics.cos[j], kinematics.sin[j]
            applied = ca.vertcat(c * f1 - s * f2, s * f1 + c * f2, moment, ca.SX.zeros(len(model.modal_index[j])))
            bodies[j] = replace(bodies[j], h=bodies[j].h - applied)
    return scene, bodies, joints
