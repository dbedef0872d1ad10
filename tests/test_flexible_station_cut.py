"""A cut joint at a modal beam's station short of its end: a four-bar whose coupler overhangs the joint to the rocker.

A ``ModalBeam`` names its outboard points at any station ``0 < x_s <= L`` (``outboard={"s": x_s}``); a cut joint at
``"coupler.s"`` reads the station's mode-shape values ``phi(x_s)``, ``phi'(x_s)`` and its foreshortening
``G1(x_s) = int_0^x_s phi' phi'^T`` (``docs/closed_loops.md`` §4d).  Independent reference:
:class:`ctmm.reference.flexible_loop_lagrange.FlexibleFourBarLagrange` with ``cut_station=x_s`` (assumed modes written
from scratch, Gauss mass points over the whole coupler, Lagrange multipliers at the station).
"""
from __future__ import annotations

import numpy as np
import pytest
import scipy.linalg

import ctmm
from ctmm.errors import ModelError
from ctmm.flexible import ModalBeam
from ctmm.planar import Fixed, PlanarModel, RigidBody, SmoothHinge
from ctmm.planar.closed_loops import CutJoint, KinematicLoopModel
from ctmm.planar.equilibrium import hanging_configuration
from ctmm.reference.flexible_loop_lagrange import FlexibleFourBarLagrange

LENGTH, STATION, RHO_A, EI = 0.7, 0.6, 1.0 / 0.6, 20.0        # the coupler overhangs the joint by 0.1 m


def four_bar(second_order: bool, outboard=None) -> KinematicLoopModel:
    beam = ModalBeam("coupler", length=LENGTH, bending_stiffness=EI, mass_per_length=RHO_A, n_modes=3,
                     second_order_inertia=second_order, outboard=outboard or {"s": STATION})
    tree = PlanarModel("four_bar_station", [
        Fixed("g", position=(0.0, 0.0)), Fixed("g4", position=(0.7, 0.0)),
        RigidBody.uniform_link("crank", mass=0.4, length=0.2), SmoothHinge("h1", parent="g", child="crank"),
        beam, SmoothHinge("h2", parent="crank", child="coupler"),
        RigidBody.uniform_link("rocker", mass=0.8, length=0.5), SmoothHinge("h4", parent="g4", child="rocker")],
        gravity=(0.0, -9.81))
    return KinematicLoopModel(tree, [CutJoint("h3", parent="rocker.out", child="coupler.s")])


def reference(form: str) -> FlexibleFourBarLagrange:
    return FlexibleFourBarLagrange((0.4, 0.2), (LENGTH, RHO_A, EI), (0.8, 0.5), 0.7, 3, inertia=form,
                                   cut_station=STATION)


def bent_moving_state(loop: KinematicLoopModel) -> tuple[np.ndarray, np.ndarray]:
    """Crank at 80 deg turning at 6 rad/s, the coupler bent and vibrating, the rest assembled."""
    names = loop.tree.coordinates
    q = {"crank.theta": 1.4, "coupler.theta": 0.5, "rocker.theta": 1.8,
         "coupler.q1": 0.012, "coupler.q2": -0.003, "coupler.q3": 0.001}
    v = {"crank.theta": 6.0, "coupler.q1": 0.4, "coupler.q2": -0.5, "coupler.q3": 0.3}
    modal = [name for name in names if name.startswith("coupler.q")]
    return loop.consistent_state([q.get(n, 0.0) for n in names], [v.get(n, 0.0) for n in names],
                                 keep=["crank.theta", *modal])


@pytest.mark.parametrize("second_order, form", [(False, "stiffening"), (True, "second_order")])
@pytest.mark.parametrize("outboard", [None, {"s": STATION, "out": LENGTH}])
def test_accelerations_and_cut_force_match_the_lagrange_model(second_order, form, outboard):
    """At a bent, moving state, with the first-order beam (geometric stiffening) and with the second-order inertia,
    and with a second (free) outboard end at the tip: accelerations and cut force to 1e-10 (measured 1e-12)."""
    loop, ref = four_bar(second_order, outboard), reference(form)
    q, v = bent_moving_state(loop)
    assert np.max(np.abs(ref.constraints(q, v)[0])) < 1e-12
    expected, force = ref.accelerations(q, v)
    got, cut_force = loop.solve(q, v)
    assert np.max(np.abs(got - expected)) < 1e-10 * np.max(np.abs(expected))
    assert np.max(np.abs(cut_force[0] - force)) < 1e-10 * np.max(np.abs(force))


def test_the_station_is_not_the_end():
    """The same state with the cut moved to the tip is a different mechanism (the test above can fail)."""
    station, tip = reference("second_order"), FlexibleFourBarLagrange((0.4, 0.2), (LENGTH, RHO_A, EI), (0.8, 0.5),
                                                                      0.7, 3, inertia="second_order")
    loop = four_bar(True)
    q, v = bent_moving_state(loop)
    assert np.max(np.abs(tip.constraints(q, v)[0])) > 1e-2
    with pytest.raises(ModelError, match=r"no end 'mid'.*stations named in ModalBeam\(outboard=.*: s"):
        KinematicLoopModel(loop.tree, [CutJoint("h3", parent="rocker.out", child="coupler.mid")])


def test_rk4_run_converges_to_the_lagrange_model():
    """``ctmm.simulate`` (RK4 + projection, 0.01 s from the bent, vibrating state) vs DOP853 of the Lagrange model
    (1e-11, same Baumgarte rate): fourth order, measured 9.2e-5 / 6.2e-6 at 0.5 / 0.25 ms."""
    loop, ref = four_bar(True), reference("second_order")
    q0, v0 = bent_moving_state(loop)
    errors = []
    for dt in (5e-4, 2.5e-4):
        run = ctmm.simulate(loop, 0.01, dt, x0=q0, v0=v0)
        Q, _, drift = ref.simulate(q0, v0, np.asarray(run.time), baumgarte=20.0)
        q = np.column_stack([run[name] for name in loop.tree.coordinates])
        errors.append(np.max(np.abs(q - Q)))
        assert drift < 1e-9 and np.max(run["drift"]) < 1e-12
    assert np.ptp(run["coupler.q1"]) > 1e-2
    assert errors[1] < 1e-5 and errors[0] / errors[1] > 12.0


def test_natural_frequencies_match_the_constrained_lagrange_model():
    """About the hanging equilibrium (found on the Lagrange model: Newton on ``(Q, lambda)``; the library refuses a
    state that is not one): ``ctmm.natural_frequencies`` vs ``eig(N^T K N, N^T M N)`` of the Lagrange model
    (``K = -d(f + C^T lambda)/dQ`` by central differences, ``N`` the null space of ``C``): measured 2.2e-11 with the
    library's Richardson tangent (:func:`ctmm.loop_manifold.accurate_tangent`; its plain central differences at step
    1e-5 gave 7.3e-7, 1.8e-7 at 5e-6)."""
    loop, ref = four_bar(True), reference("second_order")
    hanging = np.asarray(hanging_configuration(loop.tree), float)
    modal = [name for name in loop.tree.coordinates if name.startswith("coupler.q")]
    q0 = loop.consistent_state(hanging, np.zeros(len(hanging)), keep=modal)[0]
    rest, lam, h = np.zeros_like(q0), np.zeros(2), 1e-6

    def residual(Q, lam):
        _, f = ref.dynamics(Q, rest)
        phi, C, _ = ref.constraints(Q, rest)
        return np.concatenate([f + C.T @ lam, phi])

    for _ in range(30):
        x = np.concatenate([q0, lam])
        r = residual(q0, lam)
        jac = np.column_stack([(residual(*np.split(x + h * e, [len(q0)])) - residual(*np.split(x - h * e, [len(q0)])))
                               / (2 * h) for e in np.eye(len(x))])
        step = np.linalg.solve(jac, -r)
        q0, lam = q0 + step[:len(q0)], lam + step[len(q0):]
        if np.max(np.abs(step)) < 1e-13:
            break
    assert np.max(np.abs(ref.accelerations(q0, rest)[0])) < 1e-9
    omega = ctmm.natural_frequencies(loop, operating_point=(q0, rest))
    K = -np.column_stack([(residual(q0 + h * e, lam) - residual(q0 - h * e, lam))[:len(q0)] / (2 * h)
                          for e in np.eye(len(q0))])
    M, _ = ref.dynamics(q0, rest)
    N = scipy.linalg.null_space(ref.constraints(q0, rest)[1])
    values = np.sort(scipy.linalg.eigvals(N.T @ K @ N, N.T @ M @ N).real)
    assert np.max(np.abs(omega - np.sqrt(values)) / np.sqrt(values)) < 2e-10
