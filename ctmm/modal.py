"""Linear MSTMM in the time domain: modal superposition of an undamped lumped chain.

The seed's "transfer matrix method for linear multibody systems" (seed 002, Fig. 7.3, symbol
``*``): natural frequencies and mode shapes come from the transfer matrices
(:func:`~ctmm.frequency.mode_shapes`), the static deflection under the constant loads from the
TMM at ``omega = 0``; the response is

    x(t) = x_s + sum_k phi_k [ q_k(0) cos(w_k t) + qdot_k(0) / w_k sin(w_k t) ]

with modal coordinates ``q_k = phi_k^T M (x - x_s) / (phi_k^T M phi_k)`` from the lumped masses
(mode shapes are M-orthogonal).  Limited to undamped chains of lumped masses with constant loads.
"""
from __future__ import annotations

import numpy as np

from .capabilities import refuse_loops
from .elements.lumped import PointElement
from .errors import ModelError
from .frequency import mode_shapes, steady_state_response
from . import validation
from .system import Chain, require_system
from .timestep import initial_state


def modal_response(system: Chain, times: np.ndarray, *, x0=None, v0=None, n_modes: int | None = None) -> dict:
    """Displacements of all masses by modal superposition (see module docstring).

    Parameters
    ----------
    system : Chain
        Undamped chain of lumped masses and springs (constant loads only).
    times : ndarray
        Times [s] (t0 = 0).
    x0, v0 : mapping, optional
        Initial absolute positions [m] / velocities [m/s] by element name, as in
        :func:`ctmm.simulate`.
    n_modes : int, optional
        Number of modes kept (default: all).

    Returns
    -------
    dict
        ``{mass name: displacement history [m]}`` in absolute coordinates.
    """
    system = refuse_loops(system, "modal_response", "ctmm.simulate (loops closed in time)")
    system = require_system(system, controlled=False)
    given = times
    times = validation.finite_array("times", times, ndim=1)
    if times.size == 0 or np.any(times < 0):
        raise ModelError(f"times must be a non-empty 1-D array of times [s] >= 0 (t0 = 0), got {given!r}")
    if n_modes is not None:
        n_modes = validation.integer("n_modes", n_modes, minimum=1)
    masses = [(j, e) for j, e in enumerate(system.body, start=1) if isinstance(e, PointElement) and e.mass > 0]
    n_dof = len(masses)
    if n_dof == 0:
        raise ModelError(f"chain {system.name!r} has no masses")
    modes = mode_shapes(system, n_modes=n_modes or n_dof)
    x_init, v_init = initial_state(system, x0, v0)
    static = steady_state_response(system, 0.0, outputs=[f"{e.name}.x" for _, e in masses])
    rest = {e.name: float(x_init[j - 1, 0]) for j, e in masses}
    from .timestep import rest_positions

    rest_pos = rest_positions(system)
    xs = np.array([rest_pos[j - 1] + static[f"{e.name}.x"].real for j, e in masses])
    m = np.array([e.mass for _, e in masses])
    phi = np.array([[modes.shapes[k, j - 1, 0].real for j, _ in masses] for k in range(len(modes.natural_frequencies))])
    u0 = np.array([rest[e.name] for _, e in masses]) - xs
    ud0 = np.array([v_init[j - 1, 0] for j, _ in masses])
    modal_mass = (phi * m) @ phi.T
    if np.max(np.abs(modal_mass - np.diag(np.diag(modal_mass)))) > 1e-8 * np.max(np.diag(modal_mass)):
        raise ModelError("mode shapes are not mass-orthogonal: the chain is not a plain lumped chain")
    q0 = (phi * m) @ u0 / np.diag(modal_mass)
    qd0 = (phi * m) @ ud0 / np.diag(modal_mass)
    w = modes.natural_frequencies
    t = np.asarray(times, dtype=float)[:, None]
    with np.errstate(divide="ignore", invalid="ignore"):
        q = q0 * np.cos(w * t) + np.where(w > 0, qd0 / np.where(w > 0, w, 1.0) * np.sin(w * t), qd0 * t)
    x = xs + q @ phi
    return {e.name: x[:, i] for i, (_, e) in enumerate(masses)}
