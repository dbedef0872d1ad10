"""Spatial cut joints at deformable points (issue 16 item 2, docs/closed_loops.md §8.7): a spherical cut pins a
point of a SpatialBeam (its tip or a station, with the beam's modal deflection: both bending planes, twist, axial,
and the foreshortening of a stiffening beam) or a boundary node of a ``ctmm.fem`` spatial subsystem to the ground.

Independent references, the loop closed by a Lagrange multiplier on their own point kinematics:
``ctmm/reference/spatial_beam_lagrange.py`` (assumed modes, casadi AD; the pinned point's position written here
from its mode shapes) and ``ctmm/reference/spatial_fe_global.py`` (the FE frame in minimal coordinates, its node
position and Jacobian).  No TMM or cut code on the reference side.
"""
from __future__ import annotations

import functools

import casadi as ca
import numpy as np
import pytest

import ctmm
from ctmm.errors import ModelError
from ctmm.nonlinear_laws import LinearLaw
from ctmm.reference.beams import beta_roots, clamped_free_mode
from ctmm.reference.spatial_beam_lagrange import HubBeam, SpatialBeamLagrange
from ctmm.spatial import Revolute, SpatialBeam, SpatialBody, SpatialCutJoint, SpatialKinematicLoopModel, \
    SpatialModel, Weld
from test_spatial_beam import BEAM, GRAVITY, HUB_INERTIA, MOUNT
from test_spatial_fem import chain

MOUNT_POINT = (0.15, 0.1, 0.05)
HUB = dict(hub_mass=2.0, hub_inertia=HUB_INERTIA, hub_center=(0.03, 0.01, 0.02))


@functools.lru_cache(maxsize=None)
def hub_beam(stiffening: bool, gravity=GRAVITY) -> SpatialBeamLagrange:
    return SpatialBeamLagrange(HubBeam(**BEAM, **HUB, axes=((0, 0, 1),), mount=MOUNT_POINT, mount_rotation=MOUNT,
                                       geometric_stiffening=stiffening, gravity=gravity, points=32))


class PinnedBeamReference:
    """The hub + beam of :class:`HubBeam` with the beam point at ``x`` pinned to the world point ``p0`` by a
    multiplier ``lambda`` (the force on the beam, world axes): ``M u' = rhs + Q lambda``, ``J u' = -J' u``
    (``J = d r_x / d q``), the generalised force ``Q lambda`` that of the reference's own point-force actuator at
    ``x`` (virtual power ``J^T lambda`` and, with geometric stiffening, ``-G1(x) q`` times the beam-axis component)."""

    def __init__(self, stiffening: bool, x: float, gravity=GRAVITY, alignments=None) -> None:
        self.model = hub_beam(stiffening, gravity)
        n, L = self.model.n, BEAM["length"]
        q, u = ca.SX.sym("q", n), ca.SX.sym("u", n)
        rows = self.model.deflection_rows(x)
        rho = ca.mtimes(ca.DM(rows), q) + ca.DM([x, 0.0, 0.0])
        c, sn = ca.cos(q[0]), ca.sin(q[0])
        Rz = ca.vertcat(ca.horzcat(c, -sn, 0), ca.horzcat(sn, c, 0), ca.horzcat(0, 0, 1))
        r = ca.mtimes(Rz, ca.DM(MOUNT_POINT) + ca.mtimes(ca.DM(MOUNT), rho))
        self.rows = 3
        if alignments is not None:      # (section axis u, [world b_i]): rows (R_s u) . b_i, the reference's section
            theta = ca.mtimes(ca.DM(self.model.section_rows(x)), q)
            turn = [ca.vertcat(ca.horzcat(1, 0, 0), ca.horzcat(0, ca.cos(theta[0]), -ca.sin(theta[0])),
                               ca.horzcat(0, ca.sin(theta[0]), ca.cos(theta[0]))),
                    ca.vertcat(ca.horzcat(ca.cos(theta[1]), 0, ca.sin(theta[1])), ca.horzcat(0, 1, 0),
                               ca.horzcat(-ca.sin(theta[1]), 0, ca.cos(theta[1]))),
                    ca.vertcat(ca.horzcat(ca.cos(theta[2]), -ca.sin(theta[2]), 0),
                               ca.horzcat(ca.sin(theta[2]), ca.cos(theta[2]), 0), ca.horzcat(0, 0, 1))]
            R_s = ca.mtimes(ca.mtimes(Rz, ca.DM(MOUNT)), ca.mtimes(turn[2], ca.mtimes(turn[1], turn[0])))
            axis, across = alignments
            self._section_axis = ca.Function("section_axis", [q], [ca.mtimes(R_s, ca.DM(axis))])
            r = ca.vertcat(r, *[ca.dot(ca.mtimes(R_s, ca.DM(axis)), ca.DM(b)) for b in across])
            self.rows += len(across)
            self.across = [np.asarray(b, float) for b in across]
        J = ca.jacobian(r, q)
        self._point = ca.Function("point", [q, u], [r, J, ca.mtimes(ca.jacobian(ca.mtimes(J, u), q), u)])
        self._axis = ca.Function("axis", [q], [ca.mtimes(Rz, ca.DM(MOUNT[:, 0]))])
        lam = ca.SX.sym("lambda", self.rows)
        self._hessian = ca.Function("hessian", [q, lam], [ca.jacobian(ca.mtimes(J.T, lam), q)])
        self.G1 = np.zeros((n, n))
        if stiffening:                  # int_0^x (w_y' dw_y' + w_z' dw_z'), the reference's own shapes
            nodes, weights = np.polynomial.legendre.leggauss(40)
            s, w = (nodes + 1) * x / 2, weights * x / 2
            start = 1
            for count in (BEAM["n_modes_y"], BEAM["n_modes_z"]):
                slopes = np.array([clamped_free_mode(b, s / L, 1) / L for b in beta_roots("clamped-free", count)])
                self.G1[start:start + count, start:start + count] = (slopes * w) @ slopes.T
                start += count

    def point(self, q, u):
        return (np.asarray(a, float).reshape(-1) if k != 1 else np.asarray(a, float)
                for k, a in enumerate(self._point(q, u)))

    def constraint_hessian(self, q, lam):
        """``d(J^T lambda)/dq`` (n x n) at ``q``: the stiffness of the pin force ``lambda`` (held fixed)."""
        return np.asarray(self._hessian(q, lam), float)

    def solve(self, q, u):
        """``(u', lambda)``: accelerations and the force on the beam at the point [N] (world axes)."""
        M, rhs = self.model.mass_and_bias(q, u)
        _, J, Jdu = self.point(q, u)
        n = len(q)
        Q = J.T.copy()
        Q[:, :3] -= np.outer(self.G1 @ q, np.asarray(self._axis(q), float).ravel())
        kkt = np.block([[M, -Q], [J, np.zeros((self.rows, self.rows))]])
        out = np.linalg.solve(kkt, np.concatenate([rhs, -Jdu]))
        return out[:n], out[n:]


def assembled(reference, q, u_guess):
    """``(u, p0)``: ``u_guess`` projected onto ``J u = 0`` and the world point the cut holds."""
    p0, J, _ = reference.point(q, u_guess)
    N = np.linalg.svd(J)[2][len(p0):].T
    return N @ (N.T @ u_guess), p0[:3]


def beam_loop(stiffening: bool, station: str, p0, gravity=GRAVITY, baumgarte=20.0, **cut_options):
    tree = SpatialModel("pinned_beam", [
        SpatialBody("hub", mass=2.0, inertia=HUB_INERTIA, center_of_mass=(0.03, 0.01, 0.02),
                    points={"out": MOUNT_POINT}),
        Revolute(name="yaw", parent=None, child="hub", axis=(0, 0, 1)),
        SpatialBeam("b", **BEAM, geometric_stiffening=stiffening, stations={"p": 0.7}),
        Weld(name="mount", parent="hub", child="b", point="out", rotation=MOUNT)], gravity=gravity)
    cut = SpatialCutJoint(name="pin", parent=None, point=tuple(p0), child="b", child_point=station, **cut_options)
    return SpatialKinematicLoopModel(tree, [cut], baumgarte=baumgarte)


def beam_state(seed=2):
    rng = np.random.default_rng(seed)
    q = np.concatenate([[0.4], rng.normal(size=6) * 0.02])
    return q, rng.normal(size=7) * 0.5


@pytest.mark.parametrize("stiffening", [True, False])
@pytest.mark.parametrize("station, x", [("tip", BEAM["length"]), ("p", 0.7)])
def test_beam_point_pinned_accelerations_and_cut_force_equal_the_lagrange_multiplier_model(stiffening, station, x):
    reference = PinnedBeamReference(stiffening, x)
    q, u = beam_state()
    u, p0 = assembled(reference, q, u)
    loop = beam_loop(stiffening, station, p0)
    phi, rate = loop.constraints(q, u)
    assert np.abs(phi).max() < 1e-14 and np.abs(rate).max() < 1e-13      # the same point kinematics
    expected, force = reference.solve(q, u)
    got, lam = loop.solve(q, u)
    assert np.abs(got - expected).max() < 1e-10 * np.abs(expected).max()
    assert np.abs(lam - force).max() < 1e-10 * np.abs(force).max()
    free = reference.model.accelerations(q, u)
    assert np.abs(free - expected).max() > 0.1 * np.abs(expected).max()        # the cut acts


def _reference_run(reference, q0, u0, t_final, steps):
    """The reference's index-1 equations by classical RK4 (written here), ``steps`` steps."""
    n, y, h = len(q0), np.concatenate([q0, u0]), t_final / steps

    def f(y):
        return np.concatenate([y[n:], reference.solve(y[:n], y[n:])[0]])
    for _ in range(steps):
        k1 = f(y)
        k2 = f(y + h / 2 * k1)
        k3 = f(y + h / 2 * k2)
        y = y + h / 6 * (k1 + 2 * k2 + 2 * k3 + f(y + h * k3))
    return y


def hinged_tip(q, kind="revolute", stiffening=True):
    """``(reference, cut options)`` of a revolute (universal) cut at the beam tip at ``q``: the tip section's z axis
    (section axes) kept parallel to (perpendicular to) a ground axis."""
    probe = PinnedBeamReference(True, BEAM["length"])
    R_b = np.array([[np.cos(q[0]), -np.sin(q[0]), 0], [np.sin(q[0]), np.cos(q[0]), 0], [0, 0, 1]]) @ MOUNT
    theta = probe.model.section_rows(BEAM["length"]) @ q
    c, s = np.cos(theta), np.sin(theta)
    E = (np.array([[c[2], -s[2], 0], [s[2], c[2], 0], [0, 0, 1]])
         @ np.array([[c[1], 0, s[1]], [0, 1, 0], [-s[1], 0, c[1]]])
         @ np.array([[1, 0, 0], [0, c[0], -s[0]], [0, s[0], c[0]]]))
    a = R_b @ E @ np.array([0.0, 0.0, 1.0])                            # the tip section's z axis, world
    b1 = np.cross(a, [1.0, 0.0, 0.0])
    b1 /= np.linalg.norm(b1)
    across = [b1, np.cross(a, b1)] if kind == "revolute" else [b1]
    reference = PinnedBeamReference(stiffening, BEAM["length"], alignments=((0.0, 0.0, 1.0), across))
    return reference, dict(kind=kind, axis=(0, 0, 1), parent_axis=tuple(a if kind == "revolute" else b1))


@pytest.mark.parametrize("kind", ["spherical", "revolute"])
def test_beam_tip_cut_rk4_is_fourth_order_against_the_reference(kind):
    q0, u0 = beam_state(4)
    reference, options = (PinnedBeamReference(True, BEAM["length"]), {}) if kind == "spherical" else hinged_tip(q0)
    u0, p0 = assembled(reference, q0, u0)
    loop = beam_loop(True, "tip", p0, **options)
    exact = _reference_run(reference, q0, u0, 0.02, 40)          # dt = 0.5 ms: 1/256 of the 2 ms error
    errors = []
    for dt in (4e-3, 2e-3):
        run = ctmm.simulate(loop, 0.02, dt, x0=q0, v0=u0)
        final = np.array([run[name][-1] for name in loop.tree.coordinates])
        errors.append(np.abs(final - exact[:7]).max())
        assert run["drift"].max() < 1e-12
    assert errors[1] < 1e-7 and errors[0] / errors[1] > 12.0, errors


def test_beam_tip_hinge_with_a_spring_conserves_energy_without_stiffening():
    """A torsion spring across the revolute cut at the tip (``LinearLaw``, rest 0.3 rad off): the reference's energy
    plus the spring's potential (:meth:`cut_potential`) along the RK4 run."""
    from ctmm.nonlinear_laws import LinearLaw

    q0, u0 = beam_state(12)
    reference, options = hinged_tip(q0, stiffening=False)
    u0, p0 = assembled(reference, q0, u0)
    loop = beam_loop(False, "tip", p0, **options)
    rest = loop.cut_coordinates(q0, u0)[0][0] + 0.3
    loop = beam_loop(False, "tip", p0, **options, law=LinearLaw(5.0), rest=rest)
    run = ctmm.simulate(loop, 0.02, 1e-3, x0=q0, v0=u0)
    q = np.column_stack([run[name] for name in loop.tree.coordinates])
    v = np.column_stack([run[name] for name in loop.tree.velocities])
    energy = np.array([reference.model.energy(a, b) + loop.cut_potential(a) for a, b in zip(q, v)])
    kinetic = reference.model.energy(q0, u0) - reference.model.energy(q0, 0 * u0)
    assert abs(loop.cut_potential(q0) - 0.5 * 5.0 * 0.3 ** 2) < 1e-12
    assert np.abs(energy - energy[0]).max() < 1e-8 * kinetic, np.abs(energy - energy[0]).max() / kinetic
    without = np.array([reference.model.energy(a, b) for a, b in zip(q, v)])
    assert np.abs(without - without[0]).max() > 1e-4 * kinetic                 # the spring works


def test_station_pinned_energy_is_conserved_without_stiffening():
    reference = PinnedBeamReference(False, 0.7)
    q0, u0 = beam_state(5)
    u0, p0 = assembled(reference, q0, u0)
    loop = beam_loop(False, "p", p0)
    run = ctmm.simulate(loop, 0.03, 1e-3, x0=q0, v0=u0)
    q = np.column_stack([run[name] for name in loop.tree.coordinates])
    v = np.column_stack([run[name] for name in loop.tree.velocities])
    energy = np.array([reference.model.energy(a, b) for a, b in zip(q, v)])
    kinetic = np.array([reference.model.energy(a, b) - reference.model.energy(a, 0 * b) for a, b in zip(q, v)])
    assert np.abs(energy - energy[0]).max() < 1e-8 * kinetic.max(), np.abs(energy - energy[0]).max()
    assert run["drift"].max() < 1e-12


def test_subsystem_node_pinned_accelerations_and_cut_force_equal_the_global_model():
    model, ref = chain(child=False)
    rng = np.random.default_rng(7)
    q = rng.normal(size=model.n_positions) * 0.6
    q[2:] *= 0.01
    p0, J, _ = ref.node_acceleration_terms(q, np.zeros(ref.n), "n3")
    N = np.linalg.svd(J)[2][3:].T
    u = N @ (N.T @ rng.normal(size=ref.n))
    loop = SpatialKinematicLoopModel(model, [SpatialCutJoint(name="pin", parent=None, point=tuple(p0), child="frame",
                                                             child_point="n3")])
    phi, rate = loop.constraints(q, u)
    assert np.abs(phi).max() < 1e-14 and np.abs(rate).max() < 1e-12
    M, rhs = ref.mass_and_forces(q, u)
    _, J, Jdu = ref.node_acceleration_terms(q, u, "n3")
    out = np.linalg.solve(np.block([[M, -J.T], [J, np.zeros((3, 3))]]), np.concatenate([rhs, -Jdu]))
    got, lam = loop.solve(q, u)
    assert np.abs(got - out[:ref.n]).max() < 1e-10 * np.abs(out[:ref.n]).max()
    assert np.abs(lam - out[ref.n:]).max() < 1e-10 * np.abs(out[ref.n:]).max()
    assert np.abs(lam).max() > 1.0                                              # the pin carries load


def test_prismatic_cuts_and_unknown_points_at_deformable_bodies_are_refused_by_name():
    loop = beam_loop(True, "tip", (1.0, 0.0, 0.0))
    with pytest.raises(ModelError, match="deformable body.*prismatic cut"):
        SpatialKinematicLoopModel(loop.tree, [SpatialCutJoint(name="c", parent=None, child="b", child_point="tip",
                                                              kind="prismatic", parent_axis=(1, 0, 0))])
    with pytest.raises(ModelError, match="point of b"):
        SpatialKinematicLoopModel(loop.tree, [SpatialCutJoint(name="c", parent=None, child="b", child_point="nope")])
    with pytest.raises(ModelError, match="deformable body.*spherical cut's 3-axis law"):
        SpatialKinematicLoopModel(loop.tree, [SpatialCutJoint(name="c", parent=None, child="b", child_point="tip",
                                                              law=LinearLaw(5.0))])


@pytest.mark.parametrize("kind", ["revolute", "universal"])
def test_beam_tip_hinged_accelerations_and_cut_loads_equal_the_lagrange_multiplier_model(kind):
    """A revolute (universal) cut at the beam tip: the section axis ``u = e_z`` (section axes) kept parallel to
    (perpendicular to) a ground axis; the alignment rows read the tip section's rotation ``[twist, -w_z', w_y']``."""
    q, u = beam_state(8)
    reference, options = hinged_tip(q, kind)
    u, p0 = assembled(reference, q, u)
    loop = beam_loop(True, "tip", p0, **options)
    phi, rate = loop.constraints(q, u)
    assert np.abs(phi).max() < 1e-14 and np.abs(rate).max() < 1e-12
    expected, multipliers = reference.solve(q, u)
    got, lam = loop.solve(q, u)
    assert np.abs(got - expected).max() < 1e-10 * np.abs(expected).max()
    force, moment = loop.cut_loads(q, lam)[0]
    a_now = np.asarray(reference._section_axis(q), float).ravel()
    expected_moment = sum(m * np.cross(a_now, b) for m, b in zip(multipliers[3:], reference.across))
    assert np.abs(force - multipliers[:3]).max() < 1e-10 * np.abs(multipliers[:3]).max()
    assert np.abs(moment - expected_moment).max() < 1e-10 * np.abs(expected_moment).max()
    assert np.abs(expected_moment).max() > 0.1                                 # the hinge carries a moment


def node_loop(seed=7, scale=0.6):
    """The yaw link + FE L-frame on a pitch joint (``test_spatial_fem.chain``, undamped) with its node n3 pinned to
    the ground where it is at a random state, the state's velocities on the pin."""
    model, ref = chain(child=False)
    rng = np.random.default_rng(seed)
    q = rng.normal(size=model.n_positions) * scale
    q[2:] *= 0.01
    p0, J, _ = ref.node_acceleration_terms(q, np.zeros(ref.n), "n3")
    N = np.linalg.svd(J)[2][3:].T
    loop = SpatialKinematicLoopModel(model, [SpatialCutJoint(name="pin", parent=None, point=tuple(p0), child="frame",
                                                             child_point="n3")])
    return loop, ref, q, N @ (N.T @ rng.normal(size=ref.n))


def test_subsystem_node_pinned_rk4_energy_error_vanishes_at_fourth_order():
    """Undamped: the global model's energy along the RK4 runs (with projection) at 0.25 / 0.125 ms; the frame's
    top frequencies (~3e3 rad/s) keep the steps small."""
    loop, ref, q0, v0 = node_loop(seed=11)
    kinetic = ref.energy(q0, v0) - ref.energy(q0, 0 * v0)
    errors = []
    for dt in (2.5e-4, 1.25e-4):
        run = ctmm.simulate(loop, 0.0025, dt, x0=q0, v0=v0)
        q = np.column_stack([run[name] for name in loop.tree.coordinates])
        v = np.column_stack([run[name] for name in loop.tree.velocities])
        energy = np.array([ref.energy(a, b) for a, b in zip(q, v)])
        errors.append(np.abs(energy - energy[0]).max() / kinetic)
        assert run["drift"].max() < 1e-12
    assert errors[1] < 1e-4 and errors[0] / errors[1] > 14.0, errors


@pytest.mark.parametrize("kind", ["spherical", "revolute"])
def test_beam_cut_natural_frequencies_equal_the_reference_on_its_manifold(kind):
    """About the static equilibrium in gravity (no stiffening: the reference's potential is exact) of the station
    pinned (spherical) or the tip hinged (revolute): ctmm's tangent on the cut manifold against
    ``N^T (K - d(J^T lambda)/dq) N`` and ``N^T M N`` of the reference (``N`` the null space of ``J``)."""
    from ctmm.spatial.closed_loop_linear import equilibrium

    q_guess, _ = beam_state(6)
    if kind == "spherical":
        reference, station, options = PinnedBeamReference(False, 0.7), "p", {}
    else:
        (reference, options), station = hinged_tip(q_guess, stiffening=False), "tip"
    _, p0, = assembled(reference, q_guess, np.zeros(7))
    loop = beam_loop(False, station, p0, **options)
    q_eq = equilibrium(loop, q_guess, tolerance=1e-12)
    got = ctmm.natural_frequencies(loop, operating_point=q_eq)
    zero = np.zeros(7)
    M, rhs = reference.model.mass_and_bias(q_eq, zero)
    _, J, _ = reference.point(q_eq, zero)
    lam = np.linalg.lstsq(J.T, -rhs, rcond=None)[0]                # rhs + J^T lambda = 0 at rest
    assert np.abs(rhs + J.T @ lam).max() < 1e-10 * np.abs(rhs).max()   # ctmm's equilibrium is the reference's
    assert len(got) == 7 - reference.rows
    h, K = 1e-6, np.zeros((7, 7))
    for k in range(7):
        e = np.zeros(7)
        e[k] = h
        K[:, k] = -(reference.model.mass_and_bias(q_eq + e, zero)[1] - reference.model.mass_and_bias(q_eq - e, zero)[1]
                    ) / (2 * h)
    K -= reference.constraint_hessian(q_eq, lam)
    N = np.linalg.svd(J)[2][reference.rows:].T
    expected = np.sqrt(np.sort(np.linalg.eigvals(np.linalg.solve(N.T @ M @ N, N.T @ K @ N)).real))
    assert np.abs(got - expected).max() < 1e-11 * expected.max(), (got, expected)   # measured 8.6e-13, 9.2e-13


# compiled=True with deformable cut points: tests/test_compiled_kinematic_loops_spatial_flexible.py


def hinged_node(seed=9):
    """``(model, reference, q, rng, p0, a)``: the yaw link + FE L-frame at a random state, its node n3's position
    ``p0`` and x axis ``a`` there (a revolute cut at n3 keeps them)."""
    model, ref = chain(child=False)
    rng = np.random.default_rng(seed)
    q = rng.normal(size=model.n_positions) * 0.6
    q[2:] *= 0.01
    zero = np.zeros(ref.n)
    return (model, ref, q, rng, ref.node_acceleration_terms(q, zero, "n3")[0],
            ref.node_axis_terms(q, zero, "n3", (1.0, 0.0, 0.0))[0])


def test_subsystem_node_hinged_accelerations_and_cut_loads_equal_the_global_model():
    """A revolute cut at the FE node n3 (a beam node: rotation DOFs): the node's x axis kept parallel to a ground
    axis; the reference's rows ``(R_F E(r) e_x) . b_i`` from its own node frame."""
    model, ref, q, rng, p0, a = hinged_node()
    zero = np.zeros(ref.n)
    b1 = np.cross(a, [0.0, 0.0, 1.0])
    b1 /= np.linalg.norm(b1)
    across = [b1, np.cross(a, b1)]

    def rows(q, u):
        _, J_p, Jd_p = ref.node_acceleration_terms(q, u, "n3")
        a, J_a, Jd_a = ref.node_axis_terms(q, u, "n3", (1.0, 0.0, 0.0))
        return a, np.vstack([J_p] + [b @ J_a for b in across]), np.concatenate([Jd_p, [b @ Jd_a for b in across]])

    _, J, _ = rows(q, zero)
    N = np.linalg.svd(J)[2][5:].T
    u = N @ (N.T @ rng.normal(size=ref.n))
    loop = SpatialKinematicLoopModel(model, [SpatialCutJoint(name="hinge", parent=None, point=tuple(p0), child="frame",
                                                             child_point="n3", kind="revolute", axis=(1, 0, 0),
                                                             parent_axis=tuple(a))])
    phi, rate = loop.constraints(q, u)
    assert np.abs(phi).max() < 1e-14 and np.abs(rate).max() < 1e-12
    M, rhs = ref.mass_and_forces(q, u)
    a_now, J, Jdu = rows(q, u)
    out = np.linalg.solve(np.block([[M, -J.T], [J, np.zeros((5, 5))]]), np.concatenate([rhs, -Jdu]))
    got, lam = loop.solve(q, u)
    assert np.abs(got - out[:ref.n]).max() < 1e-10 * np.abs(out[:ref.n]).max()
    force, moment = loop.cut_loads(q, lam)[0]
    expected_moment = sum(m * np.cross(a_now, b) for m, b in zip(out[ref.n + 3:], across))
    assert np.abs(force - out[ref.n:ref.n + 3]).max() < 1e-10 * np.abs(force).max()
    assert np.abs(moment - expected_moment).max() < 1e-10 * np.abs(expected_moment).max()
    assert np.abs(expected_moment).max() > 0.1


def test_beam_tip_pinned_newmark_is_second_order_against_the_reference():
    """The DT-TMM Newmark scheme on the tree with the pin force re-solved at every iterate (``cut_inputs``: a point
    wrench at the beam tip), drift held by Baumgarte."""
    q0, u0 = beam_state(4)
    reference = PinnedBeamReference(True, BEAM["length"])
    u0, p0 = assembled(reference, q0, u0)
    loop = beam_loop(True, "tip", p0)
    exact = _reference_run(reference, q0, u0, 0.008, 16)
    errors = []
    for dt in (4e-3, 2e-3):
        run = ctmm.simulate(loop, 0.008, dt, x0=q0, v0=u0, method="newmark")
        errors.append(np.abs(np.array([run[name][-1] for name in loop.tree.coordinates]) - exact[:7]).max())
    assert errors[1] < 3e-5 and 3.5 < errors[0] / errors[1] < 4.5, errors          # 4.8e-5 / 1.2e-5


def test_link_hinged_to_a_subsystem_node_by_a_cut_equals_the_global_model_with_the_hinge():
    """The deformable point on the parent side: link2 on a free joint, hinged to the FE node n3 by a revolute cut
    (axis x of the node's axes and of link2's), against the global model with link2 on a hinge at n3
    (``test_spatial_fem.chain(child=True)``): at one state the frame's and the hinge's accelerations (link2's
    angular and centre-of-mass accelerations, world) and the hinge force ``m (a_c - g)``."""
    from scipy.spatial.transform import Rotation

    from ctmm.spatial import Free
    from test_spatial_fem import I2

    plant, ref = chain(child=False)[0], chain(child=True)[1]
    tree = SpatialModel("cut_hinge", [plant.bodies[0], plant.joints[0], plant.bodies[1], plant.joints[1],
                                      SpatialBody("link2", 0.5, I2, center_of_mass=(0.0, 0.05, -0.1)),
                                      Free(name="float", parent=None, child="link2")], gravity=(0.0, 0.0, -9.81))
    loop = SpatialKinematicLoopModel(tree, [SpatialCutJoint(name="h", parent="frame", point="n3", child="link2",
                                                            kind="revolute", axis=(1, 0, 0), parent_axis=(1, 0, 0))])
    rng = np.random.default_rng(4)
    q_ref, qd_ref = rng.normal(size=ref.n) * 0.6, rng.normal(size=ref.n)
    q_ref[3:] *= 0.01
    h = 1e-30
    (R, center, Jv, Jw), moved = ref.kinematics(q_ref)["links"][-1], ref.kinematics(q_ref + 1j * h * qd_ref)["links"][-1]
    origin, J_o, _ = ref.node_acceleration_terms(q_ref, qd_ref, "n3")
    x, w, z, y = Rotation.from_matrix(R).as_quat()[[0, 3, 2, 1]]
    free_q, free_v = [f"float.{c}" for c in ("x", "y", "z", "qw", "qx", "qy", "qz")], \
        [f"float.{c}" for c in ("vx", "vy", "vz", "wx", "wy", "wz")]
    plant_q = [name for name in tree.coordinates if name not in free_q]           # yaw, pitch, node DOFs
    plant_v = [name for name in tree.velocities if name not in free_v]
    values = dict(zip(plant_q, np.delete(q_ref, 2)), **dict(zip(free_q, [*origin, w, x, y, z])))
    rates = dict(zip(plant_v, np.delete(qd_ref, 2)), **dict(zip(free_v, [*(R.T @ (J_o @ qd_ref)),
                                                                        *(R.T @ (Jw @ qd_ref))])))
    q = np.array([values[name] for name in tree.coordinates])
    v = np.array([rates[name] for name in tree.velocities])
    frame = [tree.velocities.index(name) for name in plant_v]
    linear, angular = ([tree.velocities.index(f"float.{c}") for c in group] for group in (("vx", "vy", "vz"),
                                                                                       ("wx", "wy", "wz")))
    phi, rate = loop.constraints(q, v)
    assert np.abs(phi).max() < 1e-14 and np.abs(rate).max() < 1e-12
    qdd = ref.accelerations(q_ref, qd_ref)
    alpha = Jw @ qdd + (moved[3].imag / h) @ qd_ref
    a_center = Jv @ qdd + (moved[2].imag / h) @ qd_ref
    vdot, lam = loop.solve(q, v)
    assert np.abs(vdot[frame] - np.delete(qdd, 2)).max() < 1e-10 * np.abs(qdd).max()
    omega_b, v_b = v[angular], v[linear]
    assert np.abs(R @ vdot[angular] - alpha).max() < 1e-10 * np.abs(alpha).max()
    arm = center - origin
    a_origin = R @ (np.cross(omega_b, v_b) + vdot[linear])
    omega = R @ omega_b
    assert np.abs(a_origin + np.cross(alpha, arm) + np.cross(omega, np.cross(omega, arm)) - a_center).max() < \
        1e-10 * np.abs(a_center).max()
    force = loop.cut_loads(q, lam)[0][0]
    assert np.abs(force - 0.5 * (a_center - np.array([0.0, 0.0, -9.81]))).max() < 1e-10 * np.abs(force).max()


def test_alignment_cut_at_a_particle_node_is_refused_and_a_spherical_one_accepted():
    """A node held only by node springs has no rotation DOFs (a particle): no axes for alignment rows."""
    from ctmm.fem import SpatialBeamElement, SpatialFiniteElementModel, SpatialNodeSpring, SpatialPointMass
    from ctmm.spatial import Weld

    nodes = {"n0": (0.0, 0.0, 0.0), "n1": (0.4, 0.0, 0.0), "p": (0.6, 0.0, 0.0)}
    fe = SpatialFiniteElementModel("fe", nodes, [
        SpatialBeamElement("e0", "n0", "n1", 4e3, 10.0, 25.0, 40.0, 0.9, 5e-3, orientation=(0, 0, 1)),
        SpatialNodeSpring("s", "n1", "p", 2e3), SpatialPointMass("m", "p", 0.1, np.zeros((3, 3)))])
    tree = SpatialModel("particle", [fe.subsystem("body", boundary=("n0", "p")),
                                     Weld(name="clamp", parent=None, child="body")])
    with pytest.raises(ModelError, match="body.p is a subsystem node without rotation DOFs.*revolute"):
        SpatialKinematicLoopModel(tree, [SpatialCutJoint(name="c", parent=None, point=(0.6, 0, 0), child="body",
                                                         child_point="p", kind="revolute")])
    loop = SpatialKinematicLoopModel(tree, [SpatialCutJoint(name="c", parent=None, point=(0.6, 0, 0), child="body",
                                                            child_point="p")])
    assert np.abs(loop.constraints(*loop.state())[0]).max() < 1e-15
