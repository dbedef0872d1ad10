"""Newton step of the implicit DT-TMM (every :mod:`ctmm.schemes` scheme) for models with modal beams.

Per iteration the body relations (:mod:`ctmm.flexible.kernel`) are linearised about the iterate.
Each body's relations depend nonlinearly only on its own angle, rate, modal coordinates and
rates, and the integrator ties these to the body's own unknowns:
``d theta = beta' h^2 d alpha``, ``d omega = gamma' h d alpha``,
``d eta = beta' h^2 d eta''``, ``d eta' = gamma' h d eta''`` (``docs/planar.md`` sections 4, 4a:
``beta' h^2`` and ``gamma' h`` are the scheme's ``position_weight`` and ``velocity_weight``).
The tangent columns ``T = d r / d x_own`` of the residuals

``r_rows = M x_k + h + sum_e RF_e F_e,k``,   ``r_kin,e = Kin_e x_k + c_e``

are computed by **complex-step differentiation** of the body terms (one batched evaluation
with ``1 + n_j`` imaginary directions; exact to round-off, no step-size choice), and added to
the columns of ``M`` and ``Kin`` that multiply ``alpha`` and ``eta''``.  The linearised
relations keep the transfer form, so each Newton iteration is one O(n) sweep; convergence is
quadratic.  The modal stiffness and damping enter exactly (``beta' h^2 K + gamma' h D``, the
modal analogue of the hinge's ``kappa``), as do hinge laws (``kappa = k beta' h^2 + c gamma' h``).
"""
from __future__ import annotations

import numpy as np

from ..planar.hinge_laws import law_kappa
from .kernel import system_of

_EPS = 1e-30


class FlexibleNewtonStep:
    """Drop-in replacement of the rigid ``_NewtonStep`` of :mod:`ctmm.planar.implicit`."""

    def __init__(self, model, bh2: float, gh: float) -> None:
        self.model = model
        self.S = system_of(model)
        self.bh2, self.gh = bh2, gh
        self.kappa = (model.stiffness * bh2 + model.damping * gh).tolist()
        self.children = [[c for c in range(self.S.nb) if self.S.parent[c] == j] for j in range(self.S.nb)]
        self.last = None

    def start(self, q, v, t: float) -> None:
        """Iterate data from the explicit solution at the initial state."""
        S = self.S
        driven = self.model.driven(t)
        terms, (theta, omega, _, _, _) = S.all_terms(np.asarray(q, float), np.asarray(v, float), t, driven)
        tau = S.hinge_torques(q, v, theta, omega, t)
        self.last = S.sweep(terms, [0.0] * S.nb, tau.tolist(), S.driven_alpha(t, driven))

    def _linearised_terms(self, q, v, t, driven):
        S = self.S
        x_k, F_k, AO_k, _ = self.last
        theta, omega, eta, eta_dot = S.state(q, v, t, driven)
        loads = self.model.loads(t) if len(self.model.load_body) else np.zeros((0, 3))
        bh2, gh = self.bh2, self.gh
        terms = []
        for j in range(S.nb):
            n = S.n_modal[j]
            nd = 1 + n
            th = np.full(nd, theta[j], dtype=complex)
            om = np.full(nd, omega[j], dtype=complex)
            th[0] += 1j * _EPS * bh2
            om[0] += 1j * _EPS * gh
            et = np.empty((nd, n), dtype=complex)
            et[:] = eta[j]
            etd = np.empty((nd, n), dtype=complex)
            etd[:] = eta_dot[j]
            if n:
                idx = np.arange(n)
                et[1 + idx, idx] += 1j * _EPS * bh2
                etd[1 + idx, idx] += 1j * _EPS * gh
            M, h, ends = S.body_terms(j, th, om, et, etd, t, loads)
            xk = x_k[j]
            # forces at each end from the children's iterate
            Fend = [np.zeros(3) for _ in ends]
            for c in self.children[j]:
                Fend[S.pend[c]] = Fend[S.pend[c]] + F_k[c]
            rows = M @ xk + h
            for (Kin, cc, RF, _, _), fe in zip(ends, Fend):
                rows = rows + RF @ fe
            own = slice(2, 3 + n)                       # the columns of alpha and eta''
            T = rows.imag.T / _EPS                      # (3 + n, 1 + n)
            Mr = M[0].real.copy()
            hr = h[0].real.copy()
            x_own = xk[own]
            Mr[:, own] += T
            hr -= T @ x_own
            ends_r = []
            for Kin, cc, RF, _, _ in ends:
                kin = Kin @ xk + cc
                Tk = kin.imag.T / _EPS                  # (3, 1 + n)
                Kr = Kin[0].real.copy()
                cr = cc[0].real.copy()
                Kr[:, own] += Tk
                cr -= Tk @ x_own
                ends_r.append((Kr, cr, RF[0].real.copy()))
            terms.append([Mr, hr, ends_r])
        return terms, theta, omega

    def sweep(self, q, v, t, A=None, F=None, x=None, inputs=None):
        """One Newton iteration about ``(q, v)`` (the integrator's state for the iterate).

        Returns ``(A_new (nb, 3), F_new (nb, 3), qddot_new)`` like the rigid stepper.
        """
        return self.solve(self.linearise(q, v, t), inputs)

    def linearise(self, q, v, t, A=None, F=None, x=None) -> dict:
        """The tangent relations about ``(q, v)`` and the last solution, before actuator inputs."""
        S = self.S
        if self.last is None:
            self.start(q, v, t)
        x_k, _, AO_k, _ = self.last
        driven = self.model.driven(t)                  # once: angles and prescribed accelerations
        terms, theta, omega = self._linearised_terms(q, v, t, driven)
        tau = S.hinge_torques(q, v, theta, omega, t)
        rel = np.array([x_k[j][2] - AO_k[j][2] for j in range(S.nb)])
        kappa = np.array(self.kappa)            # nonlinear hinge laws: their tangent at the iterate (Newton)
        if self.model.nonlinear_hinges:
            kappa = kappa + law_kappa(self.model, *self.model.relative_angles(theta, omega, q, v), self.bh2, self.gh)
        tau_tilde = tau + kappa * rel
        return dict(terms=terms, theta=theta, tau_tilde=tau_tilde, x_k=x_k, alpha_d=S.driven_alpha(t, driven),
                    kappa=kappa.tolist())

    def solve(self, tangent: dict, inputs=None):
        """One sweep of the tangent relations of :meth:`linearise` with actuator ``inputs``
        (:class:`ctmm.planar.ports.ActuatorInputs`); the solution becomes the next iterate.

        A rigid body's input wrench about its inboard point turns with the body: its angle
        derivative (complex step, as the body terms) enters the column of ``alpha``.
        """
        S = self.S
        terms, tau_tilde = tangent["terms"], tangent["tau_tilde"]
        if inputs is not None:
            x_k = tangent["x_k"]
            wrench = inputs.inboard_wrench(self.model, tangent["theta"] + 1j * _EPS * self.bh2)
            terms = [list(term) for term in terms]
            for j in S.rigid:
                turn = wrench[j].imag / _EPS                     # d wrench / d alpha
                M = terms[j][0].copy()
                M[:, 2] -= turn
                terms[j][0] = M
                terms[j][1] = terms[j][1] - wrench[j].real + turn * x_k[j][2]
            for j in set(inputs.modal_force) | set(inputs.frame_wrench):
                h = terms[j][1].copy()
                h[3:] -= inputs.modal_force.get(j, 0.0)
                if j in inputs.frame_wrench:     # station loads on the beam's floating frame
                    turn = wrench[j].imag / _EPS
                    M = terms[j][0].copy()
                    M[:3, 2] -= turn
                    terms[j][0] = M
                    h[:3] -= wrench[j].real - turn * x_k[j][2]
                terms[j][1] = h
            tau_tilde = tau_tilde + inputs.hinge_torque
        result = S.sweep(terms, tangent["kappa"], tau_tilde.tolist(), tangent["alpha_d"])
        self.last = result
        x, F_new, _, _ = result
        A_new = np.array([xj[:3] for xj in x])
        return A_new, F_new, S.qddot(x)


__all__ = ["FlexibleNewtonStep"]
