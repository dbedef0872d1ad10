"""Delay stability of a linearised spatial model under a delayed PD loop, against the independent
global reference: the characteristic roots and the critical delay of ``ctmm.stability`` on the
spatial linearisation must zero ``det(M s^2 + C s + K + b (kp + kd s) e^{-s tau} e^T)`` built from the
reference's ``M, C, K`` (``ctmm/reference/spatial_tree.py``).

The loop is assembled here as a ``LinearizedSystem`` with its delay left open (input ``"pd_u"``,
output ``"pd_y"``, ``u(t) = -gain y(t - tau)``), the form ``ctmm.control.with_feedback`` gives on
spatial models once it lands (``docs/spatial.md`` §9).

Tolerances: each root within its own error estimate of the reference's root (Newton on the reference's
determinant); at the critical delay, smallest singular value of the reference's dynamic matrix below 1e-8
of its norm.
"""
from __future__ import annotations

import control
import numpy as np
import scipy.optimize

import ctmm
from ctmm.linearize import DelayedLoop, LinearizedSystem
from ctmm.stability import characteristic_roots, delay_margin
from ctmm.stability_chart import stability_chart
from spatial_linear_helpers import elastic_hinge_body, reference_matrices

KP, KD = 10.0, 0.5


def delayed_pd(delay: float) -> tuple[LinearizedSystem, object]:
    """The elastic-hinge body (seed 001 Fig. 9.44) with ``m_z = -(kp r_z + kd w_z)(t - delay)``."""
    model = elastic_hinge_body()
    lin = ctmm.linearize(model, inputs=["hinge.wrench_mz"], outputs=["hinge.rz", "hinge.wz"])
    ss = lin.state_space
    loop = control.ss(ss.A, ss.B, np.array([[KP, KD]]) @ ss.C, 0.0, inputs=["pd_u"], outputs=["pd_y"],
                      states=list(ss.state_labels), name="hinge")
    return LinearizedSystem(loop, (DelayedLoop("pd", 1.0, delay),), lin.operating_point), model


def dynamic_matrix(model, q0: np.ndarray, s: complex, delay: float) -> np.ndarray:
    mass, damping, stiffness = reference_matrices(model, q0)
    loop = np.zeros((6, 6), dtype=complex)
    loop[5, 5] = (KP + KD * s) * np.exp(-s * delay)          # moment about z on the rotation about z
    return mass * s * s + damping * s + stiffness + loop


def relative_singularity(model, q0: np.ndarray, s: complex, delay: float) -> float:
    sv = np.linalg.svd(dynamic_matrix(model, q0, s, delay), compute_uv=False)
    return float(sv[-1] / sv[0])


def reference_root(model, q0: np.ndarray, s: complex, delay: float) -> complex:
    """The root of the reference's ``det Z(s)`` nearest ``s`` (Newton from ``s``)."""
    return complex(scipy.optimize.newton(lambda z: np.linalg.det(dynamic_matrix(model, q0, z, delay)), s,
                                         tol=1e-14, maxiter=100))


def test_roots_and_critical_delay_zero_the_reference_characteristic() -> None:
    delay = 0.02
    system, model = delayed_pd(delay)
    q0 = system.operating_point.q
    roots = characteristic_roots(system, re_min=-3.0, im_max=150.0)
    assert roots.reliable and roots.roots.size >= 2
    for s, error in zip(roots.roots, roots.error_estimates):
        # each root within its own error estimate of a root of the reference, and (nearly) that root
        exact = reference_root(model, q0, complex(s), delay)
        assert abs(s - exact) <= max(error, 1e-12 * abs(s)) and abs(s - exact) <= 1e-4 * abs(s), (s, exact, error)
    dm = delay_margin(system)
    assert dm.stable and 0.0 < dm.critical_delay < np.inf
    s = 1j * dm.critical_frequency
    assert relative_singularity(model, q0, s, dm.critical_delay) < 1e-8
    # just past the critical delay a root crosses: the rightmost root moves to the right half plane
    past, _ = delayed_pd(dm.critical_delay * 1.05)
    assert characteristic_roots(past, re_min=-1.0, im_max=150.0).roots[0].real > 0.0


def test_stability_chart_of_the_loop_agrees_with_the_margin() -> None:
    system, _ = delayed_pd(0.02)
    dm = delay_margin(system)
    chart = stability_chart(system, ("gain", [1.0, 1.5]), ("delay", [dm.critical_delay * 0.9, dm.critical_delay * 1.1]),
                            verify=True)
    assert chart.verified
    # at the loop's own gain: stable below the critical delay, unstable above
    assert bool(chart.stable[0, 0]) and not bool(chart.stable[1, 0])
