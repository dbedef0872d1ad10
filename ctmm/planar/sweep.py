"""Acceleration-based transfer matrix method for planar chains and trees: the Riccati sweep.

State vector at a connection point (layout ``PLANAR_ACCELERATION``):
``A = [a_x, a_y, alpha]`` (acceleration of the point, angular acceleration of the outboard
body) and ``F = [f_x, f_y, tau]`` (force and moment exerted by the inboard part on the
outboard part), FORMULAS section 3.4 / seed 003 (6.4)-(6.6) / seed 000 eq. (1).

Notation (one body ``j``, inboard end ``I``, outboard end ``O`` where child ``c`` hangs):

* kinematics, rigid body I -> O:   ``A_O = X A_I + c``,
  ``X = [[1, 0, -r_y], [0, 1, r_x], [0, 0, 1]]``, ``c = [-w^2 r_x, -w^2 r_y, 0]``,
  ``r = R(theta) (O - I)``;
* Newton-Euler of the body about ``I`` (all loads moved to ``I`` by ``X^T``):
  ``F_I = K A_I + b + sum_c X_c^T F_Oc``, ``K = X_C^T diag(m, m, J_C) X_C``,
  ``b = [-m w^2 r_C - m g - f_e ; -r_C x m g - r_E x f_e - tau_e]``;
* hinge ``c`` (child inboard end = parent end ``O``): ``A_c = A_O + e3 alpha``, law
  ``tau_c = e3^T F_c = tau_tilde - kappa alpha`` (``kappa = 0`` explicit), driven:
  ``alpha`` given.

Riccati (articulated) form ``F = Phi A + psi`` from the tips to the base (FORMULAS 4.3):
``D = Phi_22 + kappa``, ``Phi_hat = Phi - Phi[:, 2] Phi[2, :] / D``,
``psi_hat = psi + Phi[:, 2] (tau_tilde - psi_2) / D``, moved to the parent's inboard point
with ``X_c^T (.) X_c``.  Base to tips: ``alpha = (tau_tilde - Phi[2, :] A_O - psi_2) / D``,
``A_c = A_O + e3 alpha``, ``F_c = Phi A_c + psi``.  ``Phi`` may be non-symmetric: the Newton
step of the implicit DT-TMM (:mod:`ctmm.planar.implicit`) feeds the same kernel with
tangent-modified ``X`` (kinematic column) and ``K``.

The recursion itself runs on Python floats (one small block per body, no numpy call per
body); everything that does not depend on the recursion is computed for all bodies at once
with numpy.
"""
from __future__ import annotations

from collections.abc import Callable
from dataclasses import dataclass, field

import numpy as np

from .. import validation
from ..errors import ModelError, SimulationError
from .model import BUSHING, DRIVEN, REVOLUTE, PlanarModel
from .ports import ActuatorInputs


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
    (kinematic third column of ``X``, lever column of ``X^T``, velocity term ``c``).
    """
    c, s = np.cos(theta), np.sin(theta)
    m, inertia = model.mass, model.inertia
    rcx = c * model.com[:, 0] - s * model.com[:, 1]
    rcy = s * model.com[:, 0] + c * model.com[:, 1]
    nb = model.n_bodies
    K = np.zeros((nb, 9))
    K[:, 0] = m
    K[:, 4] = m
    K[:, 2] = K[:, 6] = -m * rcy
    K[:, 5] = K[:, 7] = m * rcx
    K[:, 8] = inertia + m * (rcx * rcx + rcy * rcy)
    gx, gy = model.gravity
    w2 = omega * omega
    b = np.empty((nb, 3))
    b[:, 0] = -m * (w2 * rcx + gx)
    b[:, 1] = -m * (w2 * rcy + gy)
    b[:, 2] = -m * (rcx * gy - rcy * gx)
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
    ex, ey = model.end_vector[:, 0], model.end_vector[:, 1]
    rx = c[p] * ex - s[p] * ey
    ry = s[p] * ex + c[p] * ey
    wp2 = w2[p]
    E = np.column_stack([-ry, rx, -ry, rx, -wp2 * rx, -wp2 * ry])
    return K, b, E, (rcx, rcy, rx, ry)


def hinge_torques(model: PlanarModel, theta: np.ndarray, omega: np.ndarray, t: float
                  ) -> np.ndarray:
    """Explicit hinge-law torques ``u - k (dtheta - r) - c (dtheta_dot - r_dot)`` [N m]."""
    dtheta, domega = model.relative_angles(theta, omega)
    reference, rate, torque = model.hinge_laws(t)
    return torque - model.stiffness * (dtheta - reference) - model.damping * (domega - rate)


# ------------------------------------------------------------------------------------------
# the O(n) kernel
# ------------------------------------------------------------------------------------------
def _bushing_backward(P, s, data):
    """Hinge with translational springs: ``F_c = F_tilde - Kappa (A_c - A_O)``.

    A force element between the parent end ``O`` and the child's inboard end: ``(f, tau)``
    acts on the child, ``-(f, tau)`` on the parent at ``O`` (force pair, power
    ``f . d_dot + tau dtheta_dot``).  ``data = (F_tilde(3), kappa_t, kappa_r, ...)``; returns
    the projected ``(Phi_hat, psi_hat)`` at the parent end and what the forward pass needs.
    With ``Kappa = 0`` (explicit) the child decouples: ``A_c = Phi^-1 (F - psi)``.
    """
    ft, kt, kr = data[0], data[1], data[2]
    P = np.array(P).reshape(3, 3)
    kap = np.diag([kt, kt, kr])
    W = np.linalg.inv(P + kap)
    G = W @ kap - np.eye(3)                     # A_c - A_O = G A_O + h0
    h0 = W @ (np.asarray(ft) - np.asarray(s))
    Fa = -kap @ G                               # F_c = Fa A_O + Fb  (= F at O)
    Fb = np.asarray(ft) - kap @ h0
    return Fa, Fb, (G, h0, Fa, Fb)


def riccati_kernel(parent: list, kind: list, K: list, b: list, E: list, kappa: list,
                   tau: list, alpha_driven: list, want_forces: bool = True,
                   bushing: dict | None = None):
    """Tip-to-base Riccati sweep and base-to-tip pass (pure Python floats, O(n)).

    Parameters are plain lists over bodies in topological order (see :func:`body_terms`);
    ``tau`` holds ``tau_tilde`` of revolute joints, ``alpha_driven`` the prescribed
    relative angular acceleration of driven joints.

    Returns
    -------
    A, F : list of [float, float, float]
        Body accelerations at the inboard ends and joint forces.
    alpha : list of float
        Relative hinge accelerations.
    translation : dict
        ``{j: (ddx, ddy)}``: relative translational accelerations of the hinges with
        translational springs (``bushing`` maps their index to :func:`_bushing_backward` data).
    """
    nb = len(parent)
    bushing_store = {}
    translation = {}
    acc = [list(row) for row in K]
    accb = [list(row) for row in b]
    denominators = [0.0] * nb
    for j in range(nb - 1, -1, -1):
        p00, p01, p02, p10, p11, p12, p20, p21, p22 = acc[j]
        s0, s1, s2 = accb[j]
        kj = kind[j]
        if kj == REVOLUTE:
            d = p22 + kappa[j]
            if not (d != 0.0 and abs(d) < float("inf")):
                raise SimulationError(f"articulated inertia of hinge {j} is singular ({d!r})")
            denominators[j] = d
            r = (tau[j] - s2) / d
            f0, f1, f2 = p02 / d, p12 / d, p22 / d
            q00, q01, q02 = p00 - f0 * p20, p01 - f0 * p21, p02 - f0 * p22
            q10, q11, q12 = p10 - f1 * p20, p11 - f1 * p21, p12 - f1 * p22
            q20, q21, q22 = p20 - f2 * p20, p21 - f2 * p21, p22 - f2 * p22
            t0, t1, t2 = s0 + p02 * r, s1 + p12 * r, s2 + p22 * r
        elif kj == DRIVEN:
            ad = alpha_driven[j]
            q00, q01, q02, q10, q11, q12, q20, q21, q22 = p00, p01, p02, p10, p11, p12, p20, p21, p22
            t0, t1, t2 = s0 + p02 * ad, s1 + p12 * ad, s2 + p22 * ad
        elif kj == BUSHING:
            Q, tt, stored = _bushing_backward(acc[j], accb[j], bushing[j])
            bushing_store[j] = stored
            (q00, q01, q02), (q10, q11, q12), (q20, q21, q22) = Q.tolist()
            t0, t1, t2 = tt.tolist()
        else:
            continue
        par = parent[j]
        if par < 0:
            continue
        kx, ky, lx, ly, cx, cy = E[j]
        z0 = q00 * cx + q01 * cy + t0
        z1 = q10 * cx + q11 * cy + t1
        z2 = q20 * cx + q21 * cy + t2
        c02 = kx * q00 + ky * q01 + q02
        c12 = kx * q10 + ky * q11 + q12
        c22 = kx * q20 + ky * q21 + q22
        a = acc[par]
        a[0] += q00
        a[1] += q01
        a[2] += c02
        a[3] += q10
        a[4] += q11
        a[5] += c12
        a[6] += lx * q00 + ly * q10 + q20
        a[7] += lx * q01 + ly * q11 + q21
        a[8] += lx * c02 + ly * c12 + c22
        bb = accb[par]
        bb[0] += z0
        bb[1] += z1
        bb[2] += lx * z0 + ly * z1 + z2
    A = [None] * nb
    F = [None] * nb
    alpha = [0.0] * nb
    for j in range(nb):
        par = parent[j]
        if par >= 0:
            a0, a1, al = A[par]
            kx, ky, lx, ly, cx, cy = E[j]
            o0, o1, o2 = a0 + kx * al + cx, a1 + ky * al + cy, al
        else:
            o0 = o1 = o2 = 0.0
        p00, p01, p02, p10, p11, p12, p20, p21, p22 = acc[j]
        s0, s1, s2 = accb[j]
        kj = kind[j]
        if kj == REVOLUTE:
            al = (tau[j] - p20 * o0 - p21 * o1 - p22 * o2 - s2) / denominators[j]
            a_j = (o0, o1, o2 + al)
        elif kj == DRIVEN:
            al = alpha_driven[j]
            a_j = (o0, o1, o2 + al)
        elif kj == BUSHING:
            G, h0, Fa, Fb = bushing_store[j]
            rel = G @ np.array([o0, o1, o2]) + h0
            a_j = (o0 + float(rel[0]), o1 + float(rel[1]), o2 + float(rel[2]))
            al = float(rel[2])
            translation[j] = (float(rel[0]), float(rel[1]))
        else:
            sol = np.linalg.solve(np.array(acc[j]).reshape(3, 3), -np.array(accb[j]))
            a_j = (float(sol[0]), float(sol[1]), float(sol[2]))
            al = a_j[2]
        alpha[j] = al
        A[j] = a_j
        if want_forces:
            x0, x1, x2 = a_j
            F[j] = (p00 * x0 + p01 * x1 + p02 * x2 + s0,
                    p10 * x0 + p11 * x1 + p12 * x2 + s1,
                    p20 * x0 + p21 * x1 + p22 * x2 + s2)
    return A, (F if want_forces else None), alpha, translation


def _driven_alpha(model: PlanarModel, t: float) -> list:
    alpha_d = [0.0] * model.n_bodies
    for i, _, _, acceleration in model.driven(t):
        alpha_d[i] = acceleration
    return alpha_d


def coordinate_accelerations(model: PlanarModel, A: np.ndarray, translation: dict | None = None
                             ) -> np.ndarray:
    """Map body accelerations ``(nb, 3)`` (and hinge translations) to ``qddot``."""
    qddot = np.empty(model.n_coordinates)
    cb = model.coordinate_bodies
    qddot[model.theta_index[cb]] = A[cb, 2]
    fb = model.free_bodies
    if len(fb):
        qddot[model.xy_index[fb, 0]] = A[fb, 0]
        qddot[model.xy_index[fb, 1]] = A[fb, 1]
    for j, (ddx, ddy) in (translation or {}).items():
        qddot[model.xy_index[j, 0]] = ddx
        qddot[model.xy_index[j, 1]] = ddy
    return qddot


def bushing_data(model: PlanarModel, q, qdot, tau: np.ndarray, *, kappa_t=None, kappa_r=None,
                 bh2: float = 0.0, forces=None, translation_acc=None) -> dict:
    """Data of the translational-spring hinges for :func:`riccati_kernel` (explicit default)."""
    out = {}
    if not len(model.bushing_bodies):
        return out
    d, dd = model.bushing_offsets(q, qdot)
    for j in model.bushing_bodies.tolist():
        kt, ct = model.translational_stiffness[j], model.translational_damping[j]
        f = -kt * d[j] - ct * dd[j]
        if kappa_t is None:
            out[j] = ((f[0], f[1], tau[j]), 0.0, 0.0, d[j], 0.0, (0.0, 0.0), (0.0, 0.0))
        else:
            ddk = translation_acc[j]
            ft = (f[0] + kappa_t[j] * ddk[0], f[1] + kappa_t[j] * ddk[1], tau[j])
            out[j] = (ft, kappa_t[j], kappa_r[j], d[j], bh2, tuple(forces[j, :2]), tuple(ddk))
    return out


# ------------------------------------------------------------------------------------------
# public forward dynamics
# ------------------------------------------------------------------------------------------
def _checked_state(model: PlanarModel, q, qdot, t, inputs=None) -> tuple[np.ndarray, np.ndarray, float]:
    """Entry validation of the instantaneous solvers: model type, coordinate shapes, time, inputs."""
    if not isinstance(model, PlanarModel):
        raise ModelError(f"model must be a ctmm.planar.PlanarModel, got {model!r}")
    if inputs is not None and not isinstance(inputs, ActuatorInputs):
        raise ModelError(f"inputs must be ctmm.planar.ports.ActuatorInputs or None (build it with "
                         f"actuator_inputs(model, {{actuator name: value}})), got {inputs!r:.80}")
    q, qdot = model.state(q, qdot)
    return q, qdot, validation.finite("t", t)


def _with_inputs(model: PlanarModel, theta, b: np.ndarray, tau: np.ndarray, inputs
                 ) -> tuple[np.ndarray, np.ndarray]:
    """Body terms and hinge torques with the actuator ``inputs`` added
    (:class:`ctmm.planar.ports.ActuatorInputs`; loads enter ``b`` with a minus sign)."""
    if inputs is None:
        return b, tau
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
    q, qdot, t = _checked_state(model, q, qdot, t, inputs)
    if model.flexible_system is not None:
        sol = model.flexible_system.solve(q, qdot, t, inputs)
        return InstantaneousSolution(sol.qddot, sol.body_acceleration, sol.joint_force,
                                     sol.hinge_acceleration, sol.modal_acceleration)
    theta, omega = model.body_angles(q, qdot, t)
    K, b, E, _ = body_terms(model, theta, omega, t)
    b, tau = _with_inputs(model, theta, b, hinge_torques(model, theta, omega, t), inputs)
    nb = model.n_bodies
    A, F, alpha, translation = riccati_kernel(
        model.parent.tolist(), model.joint_kind.tolist(), K.tolist(), b.tolist(), E.tolist(),
        [0.0] * nb, tau.tolist(), _driven_alpha(model, t),
        bushing=bushing_data(model, q, qdot, tau))
    A = np.array(A)
    return InstantaneousSolution(coordinate_accelerations(model, A, translation), A, np.array(F),
                                 np.array(alpha))


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
    >>> float(accelerations(model, [0.0], [0.0])[0])   # -3 g / (2 L) for a horizontal rod
    -14.715
    """
    q, qdot, t = _checked_state(model, q, qdot, t, inputs)
    if model.flexible_system is not None:
        return model.flexible_system.accelerations(q, qdot, t, inputs)
    theta, omega = model.body_angles(q, qdot, t)
    K, b, E, _ = body_terms(model, theta, omega, t)
    b, tau = _with_inputs(model, theta, b, hinge_torques(model, theta, omega, t), inputs)
    A, _, _, translation = riccati_kernel(
        model._parent_list, model._kind_list, K.tolist(), b.tolist(), E.tolist(), model._zeros,
        tau.tolist(), _driven_alpha(model, t), want_forces=False,
        bushing=bushing_data(model, q, qdot, tau))
    return coordinate_accelerations(model, np.array(A), translation)


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
    "bushing_data",
    "coordinate_accelerations",
    "hinge_torques",
    "ode_rhs",
    "riccati_kernel",
    "solve_instant",
]
