"""World positions of the body points of a spatial run, added to the result so it can be animated.

:mod:`ctmm.animation` draws a spatial run from the signals ``"<body>.<point>.x|y|z"`` (the point
sensors of :mod:`ctmm.spatial.ports`, world axes [m]). A run simulated without them as ``outputs``
gets them here, from its stored coordinates through the model's own kinematics
(:class:`~ctmm.spatial.body_forms.SpatialScene`, all rows in one batch); the points of a flexible body
(:class:`~ctmm.spatial.SpatialBeam`, every node of a :class:`ctmm.fem.SpatialSubsystem`) are drawn
deformed, moved by :func:`ctmm.spatial.beam_ports.deformed_point` in the body's frame, as the point sensors
of :mod:`ctmm.spatial.ports`.
"""
from __future__ import annotations

from typing import Any

import numpy as np

from .animation import drawing_outputs
from .errors import ModelError
from .ops import NUMPY
from .signal_results import SignalSystem, signal_result
from .spatial.beam_ports import deformed_point
from .spatial.dynamics import scene_of
from .spatial.model import SpatialModel

__all__ = ["pose_signals", "with_pose_signals"]


def _spatial_model(result: Any) -> SpatialModel:
    model = getattr(getattr(result, "system", None), "model", None)
    model = getattr(model, "plant", model)
    if not isinstance(model, SpatialModel):
        raise ModelError(f"with_pose_signals needs the SimulationResult of ctmm.simulate on a spatial model, got "
                         f"{type(result).__name__} of {type(model).__name__}")
    return model


def pose_signals(result: Any) -> dict[str, np.ndarray]:
    """``{"<body>.<point>.x|y|z": history [m]}`` of every name of :func:`ctmm.animation.drawing_outputs`.

    Evaluated at the stored times from the stored coordinates ``q`` (time-dependent driven joints at
    their stored values: the model's joint motions enter through ``q``).
    """
    model = _spatial_model(result)
    if len(result.time) == 0:
        return {name: np.zeros(0) for name in drawing_outputs(model)}
    q = np.column_stack([result[name] for name in model.coordinates])
    v = np.column_stack([result[name] for name in model.velocities])
    states = scene_of(model).terms(NUMPY, q, v, float(result.time[0]), kinematics_only=True)[2]
    batch = len(q)
    out = {}
    for body, state, modal in zip(model.bodies, states, model.modal):
        rotation = np.broadcast_to(np.asarray(state.rotation).reshape(-1, 3, 3), (batch, 3, 3))
        origin = np.broadcast_to(np.asarray(state.origin).reshape(-1, 3), (batch, 3))
        local = dict(body.points)
        local["com"] = np.asarray(body.center_of_mass, float)
        local.update({node: row[0] for node, row in getattr(getattr(body, "data", None), "point_rows", {}).items()})
        for name in drawing_outputs(model):
            owner, point, axis = name.rsplit(".", 2)
            if owner == body.name:
                # a flexible body's point moves with the deformation in its frame (the point sensors' statement)
                arm = (np.asarray(local[point], float)[None] if modal is None else
                       deformed_point(body, local[point], q[:, modal.position]))
                position = origin + np.einsum("bij,bj->bi", rotation, np.broadcast_to(arm, (batch, 3)))
                out[name] = np.array(position[:, "xyz".index(axis)])
    return out


def with_pose_signals(result: Any) -> Any:
    """A copy of a spatial run with the point positions of :func:`pose_signals` added (unit m); other
    signals, time, info and method unchanged."""
    added = pose_signals(result)
    units = dict(getattr(result.system, "stored_units", {}))
    units.update({name: "m" for name in added})
    system = SignalSystem(result.system.model, units, getattr(result.system, "loops", ()))
    return signal_result(system, result.time, {**result.extra, **added}, result.scheme_name, result.info)
