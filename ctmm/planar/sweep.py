"""Acceleration-based transfer matrix method for planar chains and trees: explicit forward dynamics.

State vector at a connection point (layout ``PLANAR_ACCELERATION``):
``A = [a_x, a_y, alpha]`` (acceleration of the point, angular acceleration of the outboard
body) and ``F = [f_x, f_y, tau]`` (force and moment exerted by the inboard part on the
outboard part), FORMULAS section 3.4 / seed 003 (6.4)-(6.6) / seed 000 eq. (1).

:func:`body_terms` and :func:`hinge_torques` evaluate a rigid model's body and hinge-law terms for
all bodies at once with numpy (``K = X_C^T diag(m, m, J_C) X_C``, ``b`` the velocity, gravity and
load terms, ``E`` the parent-point data).  The sweep is the one articulated sweep
(:func:`ctmm.articulated.articulated_sweep`): rigid revolute, driven and free-base trees through
:class:`ctmm.planar.rigid_sweep.RigidTreeSweep` (their terms, the sweep traced once per structure);
models with modal beams go through :class:`ctmm.flexible.kernel.FlexibleSystem`, models with
translational-spring hinges through :class:`ctmm.planar.body_forms.PlanarScene` -- both
:func:`ctmm.articulated.articulated_sweep`.
"""
from __future__ import annotations

from collections.abc import Callable, Sequence
from dataclasses import dataclass, field

import numpy as np

from .. import validation
from ..errors import ModelError, SimulationError
from .hinge_laws import law_torques
from .model import PlanarModel
from .ports import ActuatorInputs
from .rigid_sweep import model_sweep


@dataclass(frozen=True)
class InstantaneousSolution:
    """Accelerations and internal forces of all bodies at one instant.

    Attributes
    ----------
    qddot : ndarray, shape (n_coordinates,)
        Second derivatives of the generalised coordinates.
    body_acceleration : ndarray, shape (n_bodies, 3)
        ``[a_x, a_y, alpha]`` of each body at its inboard end [m/s^2, rad/s^2].
    joint_force : ndarray, shape (n_bodies, 3)
        ``[f_x, f_y, tau]`` exerted by the parent (or ground) on each body at its inboard
        end [N, N m] (the hinge torque is ``tau``).
    hinge_acceleration : ndarray, shape (n_bodies,)
        Relative angular acceleration of each body's inboard hinge [rad/s^2].
    modal_acceleration : dict
        ``{beam name: eta''}`` of flexible bodies (:class:`~ctmm.flexible.ModalBeam`), else empty.
    """

    qddot: np.ndarray
    body_acceleration: np.ndarray
    joint_force: np.ndarray
    hinge_acceleration: np.ndarray
    modal_acceleration: dict = field(default_factory=dict)


# ------------------------------------------------------------------------------------------
# per-body terms (vectorised over all bodies)
# ------------------------------------------------------------------------------------------
def body_terms(model: PlanarModel, theta: np.ndarray, omega: np.ndarray, t: float):
    """Vectorised body data: ``K`` (nb, 9), ``b`` (nb, 3), end data (nb, 6) and levers.

    End data row ``j`` = ``(kx, ky, lx, ly, cx, cy)`` of the parent end carrying body ``j``
    (kinematic third column of ``X``, lever column of ``X^T``, velocity term ``c``).  Plane vectors are
    complex numbers ``x + i y`` here (one numpy operation per pair on these small arrays): the rotation
    ``R(theta) r`` is ``e^{i theta} r``, ``k x r`` is ``i r``; the end data is the float view of three
    complex columns ``(i r, i r, -omega_p^2 r)``.
    """
    nb = model.n_bodies
    turn = np.empty(nb, dtype=complex)                  # e^{i theta}: cos and sin as numpy computes them
    np.cos(theta, out=turn.real)
    np.sin(theta, out=turn.imag)
    c, s = turn.real, turn.imag
    m, inertia = model.mass, model.inertia
    rc = turn * np.ascontiguousarray(model.com).view(complex)[:, 0]        # centre of mass from the inboard end
    rcx, rcy = rc.real, rc.imag
    mrc = m * rc
    K = np.zeros((nb, 9))
    K[:, 0] = m
    K[:, 4] = m
    K[:, 2] = K[:, 6] = -mrc.imag
    K[:, 5] = K[:, 7] = mrc.real
    K[:, 8] = inertia + m * (rcx * rcx + rcy * rcy)
    gx, gy = model.gravity
    w2 = omega * omega
    b = np.empty((nb, 3))
    velocity_gravity = -m * (w2 * rc + complex(gx, gy))
    b[:, 0] = velocity_gravity.real
    b[:, 1] = velocity_gravity.imag
    b[:, 2] = m * (rc * complex(gx, -gy)).imag           # -m (rcx gy - rcy gx)
    if len(model.load_body):
        loads = model.loads(t)
        lb = model.load_body
        px, py = model.load_point[:, 0], model.load_point[:, 1]
        rex = c[lb] * px - s[lb] * py
        rey = s[lb] * px + c[lb] * py
        np.add.at(b[:, 0], lb, -loads[:, 0])
        np.add.at(b[:, 1], lb, -loads[:, 1])
        np.add.at(b[:, 2], lb, -(rex * loads[:, 1] - rey * loads[:, 0] + loads[:, 2]))
    p = np.maximum(model.parent, 0)
    r = turn[p] * np.ascontiguousarray(model.end_vector).view(complex)[:, 0]   # parent end from its inboard end
    ends = np.empty((nb, 3), dtype=complex)
    ends[:, 0] = ends[:, 1] = 1j * r
    ends[:, 2] = -w2[p] * r
    return K, b, ends.view(float), (rcx, rcy, r.real, r.imag)


def hinge_torques(model: PlanarModel, theta: np.ndarray, omega: np.ndarray, t: float
                  ) -> np.ndarray:
    """Explicit hinge-law torques ``u - k (dtheta - r) - c (dtheta_dot - r_dot)`` [N m]."""
    dtheta, domega = model.relative_angles(theta, omega)
    reference, rate, torque = model.hinge_laws(t)
    tau = torque - model.stiffness * (dtheta - reference) - model.damping * (domega - rate)
    return tau + law_torques(model, dtheta, domega) if model.nonlinear_hinges else tau


def _driven_alpha(model: PlanarModel, t: float) -> list:
    alpha_d = [0.0] * model.n_bodies
    for i, _, _, acceleration in model.driven(t):
        alpha_d[i] = acceleration
    return alpha_d


def coordinate_accelerations(model: PlanarModel, A: np.ndarray, translation: dict | None = None
                             ) -> np.ndarray:
    """Map body accelerations ``(nb, 3)`` (and hinge translations) to ``qddot``; ``A`` with a leading batch axis
    (without ``translation``): ``qddot`` of each row."""
    if model.is_chain and not translation and not len(model.bushing_bodies):
        return A[..., 2].astype(float)          # a revolute chain: one angle per body, in the bodies' order
    qddot = np.empty(A.shape[:-2] + (model.n_coordinates,))
    cb = model.coordinate_bodies
    qddot[..., model.theta_index[cb]] = A[..., cb, 2]
    fb = model.free_bodies
    if len(fb):
        qddot[..., model.xy_index[fb, 0]] = A[..., fb, 0]
        qddot[..., model.xy_index[fb, 1]] = A[..., fb, 1]
    for j, (ddx, ddy) in (translation or {}).items():
        qddot[model.xy_index[j, 0]] = ddx
        qddot[model.xy_index[j, 1]] = ddy
    return qddot


# ------------------------------------------------------------------------------------------
# public forward dynamics
# ------------------------------------------------------------------------------------------
def _checked_state(model: PlanarModel, q, qdot, t, inputs=None) -> tuple[np.ndarray, np.ndarray, float]:
    """Entry validation of the instantaneous solvers: model type, coordinate shapes, time, inputs."""
    if not isinstance(model, PlanarModel):
        raise ModelError(f"model must be a ctmm.planar.PlanarModel, got {model!r}")
    _checked_inputs(inputs)
    q, qdot = model.state(q, qdot)
    return q, qdot, validation.finite("t", t)


def _checked_inputs(inputs) -> None:
    """:class:`ModelError` unless ``inputs`` is :class:`ctmm.planar.ports.ActuatorInputs` or None."""
    if inputs is not None and not isinstance(inputs, ActuatorInputs):
        raise ModelError(f"inputs must be ctmm.planar.ports.ActuatorInputs or None (build it with "
                         f"actuator_inputs(model, {{actuator name: value}})), got {inputs!r:.80}")


def _with_inputs(model: PlanarModel, theta, b: np.ndarray, tau: np.ndarray, inputs
                 ) -> tuple[np.ndarray, np.ndarray]:
    """Body terms and hinge torques with the actuator ``inputs`` added
    (:class:`ctmm.planar.ports.ActuatorInputs`; loads enter ``b`` with a minus sign)."""
    if inputs is None:
        return b, tau
    if not inputs.has_wrench():                 # torques only (most loops): b - 0 is b, without the lever arithmetic
        return b, tau + inputs.hinge_torque
    return b - inputs.inboard_wrench(model, theta), tau + inputs.hinge_torque


def solve_instant(model: PlanarModel, q, qdot, t: float = 0.0, inputs=None) -> InstantaneousSolution:
    """Forward dynamics at one instant by the acceleration-based TMM (one O(n) sweep).

    Parameters
    ----------
    model : PlanarModel
        The chain or tree.
    q, qdot : array_like, shape (n_coordinates,)
        Generalised coordinates [rad, m] and their rates, ordered as ``model.coordinates``.
    t : float
        Time [s] (for loads, hinge references and driven hinges).
    inputs : ctmm.planar.ports.ActuatorInputs, optional
        Actuator values added to the model's own loads and hinge laws
        (:func:`ctmm.planar.ports.actuator_inputs`).

    Returns
    -------
    InstantaneousSolution
        Coordinate accelerations, body accelerations and joint forces.
    """
    return solve_instant_inputs(model, q, qdot, t, [inputs])[0]


def solve_instant_inputs(model: PlanarModel, q, qdot, t: float, inputs_list: Sequence[ActuatorInputs | None]
                         ) -> list[InstantaneousSolution]:
    """:func:`solve_instant` at one state for each of several actuator inputs (e.g. a kinematic loop's cut loads
    and their unit responses): the state's body terms and hinge laws are evaluated once, then one sweep per entry
    of ``inputs_list`` (each solution the same as a call with those inputs alone)."""
    inputs_list = list(inputs_list)
    if not inputs_list:
        return []
    q, qdot, t = _checked_state(model, q, qdot, t, inputs_list[0])
    for inputs in inputs_list[1:]:
        _checked_inputs(inputs)
    if model.flexible_system is not None:
        return [InstantaneousSolution(sol.qddot, sol.body_acceleration, sol.joint_force, sol.hinge_acceleration,
                                      sol.modal_acceleration)
                for sol in model.flexible_system.solve_inputs(q, qdot, t, inputs_list)]
    if len(model.bushing_bodies):
        return [_scene_solution(model, q, qdot, t, inputs) for inputs in inputs_list]
    batch = _rigid_batch(model, q, qdot, t, lambda theta, b0, tau0: [
        _with_inputs(model, theta, b0, tau0, inputs) for inputs in inputs_list])
    return [InstantaneousSolution(*row) for row in zip(batch.qddot, batch.body_acceleration, batch.joint_force,
                                                       batch.hinge_acceleration)]


def solve_instant_batch(model: PlanarModel, q, qdot, t: float, inputs: ActuatorInputs) -> InstantaneousSolution:
    """:func:`solve_instant_inputs` for a batch of actuator inputs given as one :class:`ActuatorInputs` whose arrays
    all have a leading batch axis (``hinge_torque`` (n_batch, n_bodies), ``body_force`` (n_batch, n_bodies, 3), each
    ``modal_force`` / ``frame_wrench`` entry (n_batch, ...)): the solution's arrays with that leading axis (no
    ``modal_acceleration``), each row the numbers of :func:`solve_instant` with that row's inputs.  A rigid tree on
    the fast path applies the batch at once and runs one sweep over it; other trees one sweep per row."""
    q, qdot, t = _checked_state(model, q, qdot, t, inputs)
    if model.flexible_system is not None or len(model.bushing_bodies):
        rows = solve_instant_inputs(model, q, qdot, t, [ActuatorInputs(
            inputs.hinge_torque[k], inputs.body_force[k], {j: v[k] for j, v in inputs.modal_force.items()},
            {j: v[k] for j, v in inputs.frame_wrench.items()}) for k in range(len(inputs.body_force))])
        return InstantaneousSolution(*(np.array([getattr(row, name) for row in rows]) for name in (
            "qddot", "body_acceleration", "joint_force", "hinge_acceleration")))
    return _rigid_batch(model, q, qdot, t, lambda theta, b0, tau0: _with_inputs(model, theta, b0, tau0, inputs))


def _rigid_batch(model: PlanarModel, q: np.ndarray, qdot: np.ndarray, t: float, applied: Callable
                 ) -> InstantaneousSolution:
    """The solution of a rigid tree on the fast path for a batch of applied terms: the state's body terms and hinge
    laws once, ``applied(theta, b, tau)`` the ``(b, tau)`` of each row (a list of pairs, or one pair with a leading
    batch axis), then the one sweep over the batch; arrays with a leading batch axis."""
    theta, omega = model.body_angles(q, qdot, t)
    K, b0, E, _ = body_terms(model, theta, omega, t)
    tau0, driven, kappa, sweep = hinge_torques(model, theta, omega, t), _driven_alpha(model, t), \
        np.zeros(model.n_bodies), model_sweep(model)
    rows = applied(theta, b0, tau0)
    b, tau = (np.array([b for b, _ in rows]), np.array([tau for _, tau in rows])) if isinstance(rows, list) else rows
    count = len(b) if np.ndim(b) == 3 else len(tau)
    b = b if np.ndim(b) == 3 else np.broadcast_to(b, (count,) + np.shape(b0))      # inputs without body loads
    A, F, alpha = sweep.batch(K, b, E, kappa, tau, driven)
    return InstantaneousSolution(coordinate_accelerations(model, A), A, F, alpha)


def _scene_solution(model: PlanarModel, q: np.ndarray, qdot: np.ndarray, t: float, inputs
                    ) -> InstantaneousSolution:
    """:func:`solve_instant` by the generic sweep (:class:`~ctmm.planar.body_forms.PlanarScene`),
    for models off the fast path (translational-spring hinges)."""
    from .body_forms import PlanarScene             # body_forms imports model and ports only: no cycle

    scene = PlanarScene(model)
    solution = scene.solution(q, qdot, t, inputs)
    A = np.array([x[0, :3, 0] for x in solution.x])
    alpha = np.array([0.0 if r is None else r[0, -1, 0] for r in solution.relative])
    return InstantaneousSolution(scene.coordinate_accelerations(solution)[0], A,
                                 np.array([f[0, :, 0] for f in solution.force]), alpha)


def accelerations(model: PlanarModel, q, qdot, t: float = 0.0, inputs=None) -> np.ndarray:
    """Generalised accelerations ``qddot(q, qdot, t)`` by the O(n) acceleration TMM.

    ``inputs`` (:class:`ctmm.planar.ports.ActuatorInputs`, optional) adds actuator values to the
    model's own loads and hinge laws (see :func:`ctmm.planar.ports.actuator_inputs`).

    Examples
    --------
    >>> import numpy as np
    >>> from ctmm.planar import PlanarModel, Pinned, RigidBody, accelerations
    >>> model = PlanarModel.chain("p", [Pinned("o"), RigidBody.uniform_link("l", mass=1.0,
    ...                                                                    length=1.0)])
    >>> round(float(accelerations(model, [0.0], [0.0])[0]), 9)   # -3 g / (2 L), horizontal rod
    -14.715
    """
    q, qdot, t = _checked_state(model, q, qdot, t, inputs)
    if model.flexible_system is not None:
        return model.flexible_system.accelerations(q, qdot, t, inputs, checked=True)
    if len(model.bushing_bodies):
        return _scene_solution(model, q, qdot, t, inputs).qddot
    theta, omega = model.body_angles(q, qdot, t)
    K, b, E, _ = body_terms(model, theta, omega, t)
    b, tau = _with_inputs(model, theta, b, hinge_torques(model, theta, omega, t), inputs)
    A, _, _ = model_sweep(model)(K, b, E, np.zeros(model.n_bodies), tau, _driven_alpha(model, t))
    return coordinate_accelerations(model, A)


def ode_rhs(model: PlanarModel) -> Callable[[float, np.ndarray], np.ndarray]:
    """Right-hand side ``f(t, y)`` with ``y = [q, qdot]`` for RK4 or ``scipy.integrate.solve_ivp``."""
    n = model.n_coordinates

    def rhs(t: float, y: np.ndarray) -> np.ndarray:
        y = np.asarray(y, dtype=float)
        if y.shape != (2 * n,):
            raise ModelError(f"y must be [q, qdot] of length {2 * n} for model {model.name!r}, got shape {y.shape}")
        out = np.empty(2 * n)
        out[:n] = y[n:]
        out[n:] = accelerations(model, y[:n], y[n:], t)
        return out

    return rhs


__all__ = [
    "InstantaneousSolution",
    "accelerations",
    "body_terms",
    "coordinate_accelerations",
    "hinge_torques",
    "ode_rhs",
    "solve_instant",
]
