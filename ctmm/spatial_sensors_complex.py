"""Complex-step values of the named sensors of a spatial model (:mod:`ctmm.spatial.ports`): exact rows of ``C``.

The output rows of :func:`ctmm.linearize` on a spatial model (``docs/spatial.md`` §9): the derivative
of each sensor's value with respect to the state ``x = [r ; v]`` of
:mod:`ctmm.spatial_linearization` (tangent coordinates ``r``, ``q = q0 (+) r``, and velocities ``v``)
at the operating point.  Taken by **complex step** (step ``1e-30``): the ``2 nv`` states
``q0 (+) i h e_k`` and ``v0 + i h e_k`` go through the one statement of the sensor maps,
:func:`ctmm.spatial.sensor_maps.sensor_values` (complex-step safe; module docstring there), so that
``Im y / h`` is the derivative to round-off (no subtraction, no step to choose).

Refused (:class:`~ctmm.errors.ModelError`) where a sensor is not differentiable at the operating point:
x-y-z angles at gimbal lock (``|angle_y| = pi/2``), a rotation vector of length ``pi`` (where it flips).
"""
from __future__ import annotations

from typing import Any, Sequence

import numpy as np

from .spatial.ports import SpatialPorts
from .spatial.sensor_maps import SINGULAR_MARGIN, sensor_values

__all__ = ["complex_sensor_values", "SINGULAR_MARGIN"]


def complex_sensor_values(model: Any, names: Sequence[str], q: np.ndarray, v: np.ndarray, t: float,
                          ports: SpatialPorts | None = None) -> np.ndarray:
    """Values ``(B, len(names))`` of the sensors ``names`` at a batch of complex-step states (module docstring).

    Parameters
    ----------
    model : SpatialModel
    names : sequence of str
        Sensor names of :class:`ctmm.spatial.ports.SpatialPorts`.
    q, v : ndarray, shape (B, nq), (B, nv)
        States with real parts equal (the operating point) and tiny imaginary parts (the complex step:
        ``q0 (+) i h e_k``, :func:`ctmm.spatial_linearization.retract`).
    t : float
        Time [s].
    ports : SpatialPorts, optional
        The model's resolved ports (built when omitted).

    Returns
    -------
    ndarray, shape (B, len(names)), complex
        ``Im / h`` is the derivative along each row's step.
    """
    ports = SpatialPorts(model) if ports is None else ports
    return sensor_values(model, ports.scene, ports.resolve(list(names)), np.asarray(q, dtype=complex),
                         np.asarray(v, dtype=complex), float(t), differentiable="linearize")
