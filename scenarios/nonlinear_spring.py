"""Nonlinear hinge springs in the style of seed 002 Fig. 7.12: laws, backbone curve and a damped response.

Own parameters (the seed's were lost): a uniform link (1 kg, 1 m; ``J = 1/3 kg m^2`` about the hinge) on
a ground hinge without gravity, with the rotary spring ``M = K1 theta + K2 theta^3`` (seed 002 §7.6.1 names
the two coefficients of its nonlinear rotary spring, eq. (7.202), whose formula was lost: the cubic is our
reading; ours too: ``K1 = 10 N m/rad``, hardening ``K2 = +60``, softening ``K2 = -3 N m/rad^3``), a clearance spring
(gap 0.05 rad, 20 N m/rad, stop at 0.4 rad adding 200 N m/rad) and a quadratic damper.

* Backbone: the period of free undamped oscillations against the amplitude, ctmm (the TMM sweep with the
  law; RK4 at 1 ms for the cubic springs, DOP853 at 1e-12 for the clearance law, whose kinks cut fixed-step
  RK4 to about second order: 1e-5 relative at 1 ms) vs the exact period of the energy quadrature
  ``T(A) = 4 int_0^A dtheta / sqrt(2 (V(A) - V(theta)) / J)`` (independent of the TMM).
* Damped response: hardening spring + quadratic damper (``0.05 theta' |theta'|`` N m), RK4 and DT-TMM
  Newmark (the Newton iteration on the law's tangent) vs the global DAE reference
  (:mod:`ctmm.reference.planar_dae`, DOP853 1e-11).
"""
from __future__ import annotations

import math
import time
from pathlib import Path

import numpy as np
import scipy.integrate

import ctmm
from ctmm.nonlinear_laws import ClearanceSpring, CubicSpring, Law, PowerDamper
from ctmm.planar import Fixed, NonlinearHinge, PlanarModel, RigidBody
from ctmm.reference.planar_dae import PlanarDAE
from ctmm.scenario import accuracy

from .planar_common import save_figure

NAME = "nonlinear_spring"
DESCRIPTION = ("Nonlinear hinge springs (seed 002 Fig. 7.12 forms): laws, backbone period vs amplitude against the "
               "exact energy quadrature, damped response vs the global DAE")
INERTIA = 1.0 / 3.0
LAWS = {"hardening K2 = +60": CubicSpring(10.0, 60.0), "softening K2 = -3": CubicSpring(10.0, -3.0),
        "clearance + stop": ClearanceSpring(20.0, clearance=0.05, stop=0.4, stop_stiffness=200.0)}
DAMPER = PowerDamper(0.05, 2.0)


def link(law: Law) -> PlanarModel:
    """The link on a ground hinge carrying ``law``, no gravity."""
    return PlanarModel("nonlinear_spring", [Fixed("g"), RigidBody.uniform_link("l", mass=1.0, length=1.0),
                                            NonlinearHinge("h", parent="g", child="l", moment_law=law)],
                       gravity=(0.0, 0.0))


def exact_period(law: Law, amplitude: float) -> float:
    """Period from the energy quadrature (``theta = A sin(phi)``: no endpoint singularity)."""
    V = law.potential

    def integrand(p: float) -> float:
        return amplitude * math.cos(p) / math.sqrt(2.0 * (V(amplitude) - V(amplitude * math.sin(p))) / INERTIA)

    # the clearance corners as break points of the integrand
    points = [math.asin(c / amplitude) for c in (0.05, 0.4) if c < amplitude]
    return 4.0 * scipy.integrate.quad(integrand, 0.0, math.pi / 2, points=points or None, epsabs=1e-14,
                                      epsrel=1e-13, limit=400)[0]


def measured_period(t: np.ndarray, x: np.ndarray) -> float:
    """Mean spacing of the upward zero crossings (linear interpolation)."""
    up = np.flatnonzero((x[:-1] < 0.0) & (x[1:] >= 0.0))
    times = t[up] - x[up] * (t[up + 1] - t[up]) / (x[up + 1] - x[up])
    return float(np.mean(np.diff(times)))


def run(output_dir: Path, quick: bool = False) -> dict:
    import matplotlib
    matplotlib.use("Agg")
    import matplotlib.pyplot as plt

    h = 1e-3
    amplitudes = np.array([0.6]) if quick else np.array([0.1, 0.2, 0.3, 0.45, 0.6, 0.8])
    backbone, worst, wall = {}, 0.0, 0.0
    for label, law in LAWS.items():
        rows = []
        for amplitude in amplitudes:
            expected = exact_period(law, amplitude)
            t_final = h * math.ceil(2.2 * expected / h)
            if isinstance(law, ClearanceSpring):   # kinks: fixed-step RK4 drops to ~2nd order; adaptive DOP853
                result = ctmm.simulate(link(law), t_final, method="DOP853", rtol=1e-12, atol=1e-13, max_step=2 * h,
                                       x0={"l.theta": float(amplitude)})
            else:
                result = ctmm.simulate(link(law), t_final, h, method="rk4", x0={"l.theta": float(amplitude)})
            wall += result.info["wall_time_s"]
            period = measured_period(result.time, result["l.theta"])
            worst = max(worst, abs(period - expected) / expected)
            rows.append((float(amplitude), period, expected))
        backbone[label] = rows
    # damped response vs the global DAE
    law = LAWS["hardening K2 = +60"] + DAMPER
    t_final = 1.0 if quick else 4.0
    rk4 = ctmm.simulate(link(law), t_final, 1e-3, method="rk4", x0={"l.theta": 0.8})
    newmark = ctmm.simulate(link(law), t_final, 1e-3, method="newmark", x0={"l.theta": 0.8})
    dae = PlanarDAE(gravity=(0.0, 0.0))
    dae.add_body("l", mass=1.0, inertia=1.0 / 12, points={"in": (-0.5, 0.0)})
    dae.add_revolute(None, (0.0, 0.0), "l", "in", moment=lambda d, v: float(law.force(d, v)))
    began = time.perf_counter()
    ref = dae.simulate(dae.assemble({"l": 0.8}, {"l": 0.0}), t_final, t_eval=rk4.time)
    reference_wall = time.perf_counter() - began
    error_rk4 = float(np.max(np.abs(rk4["l.theta"] - ref.angle("l"))))
    error_newmark = float(np.max(np.abs(newmark["l.theta"] - ref.angle("l"))))

    fig, axes = plt.subplots(1, 3, figsize=(15, 4.2))
    theta = np.linspace(-0.8, 0.8, 401)
    for label, law_k in LAWS.items():
        axes[0].plot(theta, law_k.force(theta), label=label)
    axes[0].plot(theta, 10.0 * theta, "k:", label="linear K1 = 10")
    axes[0].set(xlabel="hinge angle [rad]", ylabel="spring moment [N m]", title="laws (seed 002 Fig. 7.12 forms)")
    axes[0].legend(fontsize="small")
    for label, rows in backbone.items():
        a, measured, exact = np.array(rows).T
        line, = axes[1].plot(a, exact, "-", label=f"{label}: exact quadrature")
        axes[1].plot(a, measured, "o", color=line.get_color(), label=f"{label}: ctmm")
    axes[1].axhline(2 * math.pi / math.sqrt(10.0 / INERTIA), color="k", ls=":", label="linear")
    axes[1].set(xlabel="amplitude [rad]", ylabel="period [s]", title="backbone")
    axes[1].legend(fontsize="x-small")
    axes[2].plot(rk4.time, rk4["l.theta"], label="ctmm RK4 1 ms")
    axes[2].plot(newmark.time, newmark["l.theta"], "--", label="ctmm DT-TMM Newmark 1 ms")
    axes[2].plot(ref.t, ref.angle("l"), "k:", label="global DAE")
    axes[2].set(xlabel="t [s]", ylabel="angle [rad]", title="hardening spring + quadratic damper")
    axes[2].legend(fontsize="small")
    save_figure(fig, output_dir, NAME)
    source = "docs/planar.md §2.2a: nonlinear hinge laws (targets of this scenario)"
    return {
        "accuracy": [
            accuracy("backbone period error vs exact quadrature", worst, "relative", 1e-6,
                     "max over the laws and amplitudes of |T_ctmm - T_exact| / T_exact (RK4 1 ms; clearance law "
                     "DOP853 1e-12; zero crossings)",
                     source=source),
            accuracy("damped response error vs global DAE", error_rk4, "rad", 1e-6,
                     "max |theta_ctmm (RK4 1 ms) - theta_DAE| over the run", source=source)],
        "newmark_error_rad": error_newmark,
        "newmark_newton_iterations_mean": newmark.info.get("newton_iterations_mean"),
        "backbone": {label: [{"amplitude_rad": a, "period_s": p, "exact_period_s": e} for a, p, e in rows]
                     for label, rows in backbone.items()},
        "wall_time_s": wall + rk4.info["wall_time_s"],
        "reference_wall_time_s": reference_wall,
        "energy_drift": None,
        "energy_drift_note": "the damped run dissipates; the backbone periods check the conservative laws",
    }
