"""Spatial model building, validation messages and driven joints (issue 14)."""
from __future__ import annotations

import numpy as np
import pytest

import ctmm.spatial as sp
from ctmm.errors import ModelError


def body(name: str = "b", **kw) -> sp.SpatialBody:
    return sp.SpatialBody(name, kw.pop("mass", 1.0), kw.pop("inertia", (0.1, 0.2, 0.25)),
                          kw.pop("center_of_mass", (0.0, 0.0, -0.5)), kw.pop("points", {"tip": (0.0, 0.0, -1.0)}))


@pytest.mark.parametrize("kwargs, words", [
    (dict(mass=-1.0), ["b: mass", "> 0"]),
    (dict(inertia=[[1, 0, 0], [0, 1, 0], [0, 0, 3]]), ["b: inertia", "triangle inequality"]),
    (dict(inertia=[[1, 0.5, 0], [0, 1, 0], [0, 0, 1]]), ["b: inertia", "symmetric"]),
    (dict(inertia=(1.0, -1.0, 1.0)), ["b: inertia", "positive definite"]),
    (dict(center_of_mass=(0.0, 1.0)), ["b: center_of_mass", "3 finite numbers"]),
    (dict(points={"tip": (0.0, np.nan, 0.0)}), ["b: points['tip']", "finite"]),
    (dict(points={"origin": (0.0, 0.1, 0.0)}), ["b: points['origin']", "(0, 0, 0)"]),
])
def test_body_validation_names_parameter_value_and_rule(kwargs, words) -> None:
    with pytest.raises(ModelError) as error:
        body(**kwargs)
    for word in words:
        assert word in str(error.value)


@pytest.mark.parametrize("make, words", [
    (lambda: sp.Revolute(name="j", parent=None, child="b", axis=(0, 0, 0)), ["j: axis", "non-zero"]),
    (lambda: sp.Revolute(name="j", parent=None, child="b", rotation=np.diag([1.0, 1.0, -1.0])),
     ["j: rotation", "proper rotation"]),
    (lambda: sp.Universal(name="j", parent=None, child="b", axis1=(1, 0, 0), axis2=(2, 0, 0)), ["parallel"]),
    (lambda: sp.Revolute(name="j", parent=None, child="b", stiffness=-1.0), ["j: stiffness", ">= 0"]),
    (lambda: sp.Universal(name="j", parent=None, child="b", damping=(1.0, 2.0, 3.0)), ["j: damping", "2 numbers"]),
    (lambda: sp.Elastic6(name="j", parent=None, child="b", stiffness=-np.eye(6)), ["j: stiffness", "semi-definite"]),
    (lambda: sp.Revolute(name="j", parent=None, child="b", position=0.0), ["position, rate and acceleration"]),
    (lambda: sp.Revolute(name="j", parent=None, child="b", position=np.sin, rate=np.sin, acceleration=np.cos),
     ["rate[0]", "not the time derivative"]),
    (lambda: sp.Load("l", "b", force=(1.0, 2.0)), ["l: force", "3 signal"]),
    (lambda: sp.Load("l", "b", force=np.array(1.0)), ["l: force", "3 signal"]),          # was numpy's TypeError
    (lambda: sp.Universal(name="j", parent=None, child="b", position=np.array(0.3), rate=np.array(0.0),
                          acceleration=np.array(0.0)), ["j: position", "2 signal"]),
])
def test_joint_validation(make, words) -> None:
    with pytest.raises(ModelError) as error:
        make()
    for word in words:
        assert word in str(error.value)


def test_driven_joint_takes_zero_dimensional_arrays_as_numbers() -> None:
    """A 0-d array is a number where a float is (it was iterated: TypeError 'iteration over a 0-d array')."""
    joint = sp.Revolute(name="j", parent=None, child="b", position=np.array(0.3), rate=np.array(0.0),
                        acceleration=np.float64(0.0))
    assert [signal(0.7) for signal in joint.position] == [0.3]
    assert [signal(0.7) for signal in joint.rate + joint.acceleration] == [0.0, 0.0]
    load = sp.Load("l", "b", force=(np.array(1.0), 0.0, np.array(-2.0)))
    assert [signal(0.0) for signal in load.force] == [1.0, 0.0, -2.0]


def test_tree_validation() -> None:
    with pytest.raises(ModelError, match="no inboard joint"):
        sp.SpatialModel("m", [body()])
    with pytest.raises(ModelError, match="two inboard joints"):
        sp.SpatialModel("m", [body(), sp.Weld(name="a", parent=None, child="b"), sp.Weld(name="c", parent=None, child="b")])
    with pytest.raises(ModelError, match="nowhere"):
        sp.SpatialModel("m", [body(), body("c"), sp.Weld(name="a", parent=None, child="b"),
                              sp.Revolute(name="r", parent="b", point="nowhere", child="c")])
    with pytest.raises(ModelError, match="cycle"):
        sp.SpatialModel("m", [body(), body("c"), sp.Revolute(name="a", parent="c", point="tip", child="b"),
                              sp.Revolute(name="r", parent="b", point="tip", child="c")])
    model = sp.SpatialModel("m", [body(), sp.Spherical(name="s", parent=None, child="b")])
    with pytest.raises(ModelError, match="quaternion of joint 's' is zero"):
        sp.accelerations(model, np.zeros(4), np.zeros(3))
    with pytest.raises(ModelError, match="q must have 4 entries"):
        sp.accelerations(model, np.zeros(3), np.zeros(3))
    with pytest.raises(ModelError, match="v must be real numbers"):          # not dropped silently
        sp.accelerations(model, [1.0, 0.0, 0.0, 0.0], np.array([0.0, 1e-20j, 0.0]))
    real = sp.accelerations(model, np.array([1.0 + 0j, 0.0, 0.0, 0.0]), np.zeros(3))
    assert np.array_equal(real, sp.accelerations(model, [1.0, 0.0, 0.0, 0.0], np.zeros(3)))
    assert model.coordinates == ("s.qw", "s.qx", "s.qy", "s.qz") and model.velocities == ("s.wx", "s.wy", "s.wz")



def test_check_state_of_inner_loop_arrays_refuses_and_accepts_as_the_rules_say() -> None:
    """``check_state`` takes float64 arrays of the right sizes (the inner loops' states) through a cheap test: every
    refusal of the full check still holds for them (non-finite entries anywhere in a batch, a quaternion of norm
    below 1e-9, wrong sizes), states near the limits pass (a quaternion of norm 2e-9, entries whose sum overflows),
    and the arrays come back as rows without a copy."""
    model = sp.SpatialModel("m", [body(), body("c"), sp.Spherical(name="s", parent=None, child="b"),
                                  sp.Revolute(name="r", parent="b", point="tip", child="c", axis=(1, 0, 0))])
    q, v = np.array([1.0, 0.0, 0.0, 0.0, 0.3]), np.array([0.1, 0.2, 0.3, 0.4])
    q_rows, v_rows = model.check_state(q, v)
    assert q_rows.shape == (1, 5) and v_rows.shape == (1, 4) and np.shares_memory(q_rows, q)
    batch = np.repeat(q[None], 3, axis=0)
    for bad, words in ((np.nan, "must be finite"), (np.inf, "must be finite")):
        rows = batch.copy()
        rows[2, 4] = bad
        with pytest.raises(ModelError, match=words):
            model.check_state(rows, np.zeros((3, 4)))
        with pytest.raises(ModelError, match=words):
            model.check_state(q, np.array([0.0, bad, 0.0, 0.0]))
    rows = batch.copy()
    rows[1, :4] = [1e-10, 0.0, 0.0, 0.0]
    with pytest.raises(ModelError, match="quaternion of joint 's' is zero"):
        model.check_state(rows, np.zeros(4))
    rows[1, :4] = [2e-9, 0.0, 0.0, 0.0]                          # small but not zero: accepted
    assert model.check_state(rows, np.zeros(4))[0] is rows
    huge = np.array([1e308, 1e308, 0.0, 0.0, 1e308])            # finite entries whose sum overflows
    with np.errstate(over="ignore"):                              # numpy's overflow notes of the sum and the norm
        assert np.array_equal(model.check_state(huge, v)[0], huge[None])
    with pytest.raises(ModelError, match="q must have 5 entries"):
        model.check_state(np.zeros(4), v)
    with pytest.raises(ModelError, match="v must have 4 entries"):
        model.check_state(q, np.zeros((1, 5)))
    with pytest.raises(ModelError, match="q must have 5 entries"):
        model.check_state(np.ones((1, 1, 5)), v)
    swapped = q.astype(">f8")                                   # non-native float64: converted
    assert model.check_state(swapped, v)[0].dtype == np.dtype(float)
    assert np.array_equal(model.check_state(swapped, v)[0], q[None])

def test_driven_joint_matches_pinocchio_partitioned_dynamics() -> None:
    """A driven revolute in the middle of a chain: the free joints' accelerations and the driven joint's
    torque (an output) equal Pinocchio's with the driven acceleration moved to the right-hand side."""
    pin = pytest.importorskip("pinocchio")
    from spatial_pinocchio_helpers import pinocchio_driven_chain

    angle, rate, accel = (lambda t: 0.4 * np.sin(2 * t)), (lambda t: 0.8 * np.cos(2 * t)), (lambda t: -1.6 * np.sin(2 * t))
    elements = [body("a"), body("b"), body("c"),
                sp.Revolute(name="ja", parent=None, child="a", axis=(1, 0, 0)),
                sp.Revolute(name="jb", parent="a", point="tip", child="b", axis=(0, 1, 1), position=angle, rate=rate,
                            acceleration=accel),
                sp.Spherical(name="jc", parent="b", point="tip", child="c")]
    model = sp.SpatialModel("driven", elements)
    t = 0.7
    q, v = np.array([0.3, 0.9, 0.1, -0.3, 0.2]), np.array([0.5, 0.2, -0.4, 0.3])
    ours = sp.solve(model, q, v, t)

    pm, j2 = pinocchio_driven_chain(pin, model)
    data = pm.createData()
    quat = q[1:] / np.linalg.norm(q[1:])
    qp = np.r_[q[0], angle(t), quat[1:], quat[0]]
    vp = np.r_[v[0], rate(t), v[1:]]
    M = pin.crba(pm, data, qp)
    M = np.triu(M) + np.triu(M, 1).T
    bias = pin.nle(pm, data, qp, vp)
    free, fixed = [0, 2, 3, 4], [1]
    a = np.zeros(5)
    a[1] = accel(t)
    a[free] = np.linalg.solve(M[np.ix_(free, free)], -bias[free] - M[np.ix_(free, fixed)] @ a[fixed])
    torque = pin.rnea(pm, data, qp, vp, a)
    np.testing.assert_allclose(ours.velocity_rates[0], a[free], rtol=0, atol=1e-10 * max(1, np.abs(a).max()))
    pin.forwardKinematics(pm, data, qp)
    axis = data.oMi[j2].rotation @ (np.array([0, 1.0, 1.0]) / np.sqrt(2))
    driven_torque = axis @ ours.reactions[0, 1, 3:]             # inboard point = joint origin: moment about it
    assert abs(driven_torque - torque[1]) < 1e-10 * max(1.0, abs(torque[1]))


@pytest.mark.parametrize("call", [lambda m: sp.energy(m, [0.0], [0.0]), lambda m: sp.reactions(m, [0.0], [0.0]),
                                  lambda m: sp.accelerations(m, [0.0], [0.0]), lambda m: sp.solve(m, [0.0], [0.0]),
                                  lambda m: sp.state_rates(m, [0.0, 0.0], 0.0)])
@pytest.mark.parametrize("other", [None, "arm", 1.0, object()])
def test_the_dynamics_functions_refuse_what_is_not_a_spatial_model(call, other) -> None:
    """Was: ``energy`` read ``model.check_state`` first and failed with AttributeError."""
    with pytest.raises(ModelError, match="model must be a ctmm.spatial.SpatialModel, got"):
        call(other)


@pytest.mark.parametrize("method", ["rk4", "newmark", "RK45"])
@pytest.mark.parametrize("value", ["2", "abc", True, 1j, lambda t: "1"])
def test_joint_input_that_is_not_a_real_number_is_refused_by_name(method: str, value: object) -> None:
    """A string, boolean or complex joint input is refused by name on the numpy paths, as the generated path and
    the port inputs refuse it (``"2"`` and ``True`` were run as 2 N m and 1 N m, ``"abc"`` a bare ValueError)."""
    import ctmm
    model = sp.SpatialModel("m", [sp.SpatialBody("a", 1.0, (1, 1, 1)),
                                  sp.Revolute(name="yaw", parent=None, child="a", actuated=True)])
    with pytest.raises(ModelError, match=r"input 'yaw\.torque' must be 1 finite number\(s\)"):
        ctmm.simulate(model, 0.01, 1e-3, method=method, inputs={"yaw.torque": value}, compiled=False)


def _yaw_arm() -> sp.SpatialModel:
    return sp.SpatialModel("arm", [
        sp.SpatialBody("base", 2.0, (0.02, 0.02, 0.01), center_of_mass=(0, 0, 0.1), points={"top": (0, 0, 0.2)}),
        sp.SpatialBody("link", 1.0, (0.01, 0.01, 0.002), center_of_mass=(0.25, 0, 0)),
        sp.Revolute(name="yaw", parent=None, child="base", axis=(0, 0, 1), actuated=True),
        sp.Spherical(name="ball", parent="base", point="top", child="link")], gravity=(0, 0, -9.81))


def test_batches_of_different_sizes_are_refused_by_name() -> None:
    """q and v of 2 and 3 rows, or a joint input of 3 rows for a batch of 2, are refused with a ModelError naming
    the sizes (were bare numpy broadcasting errors); one row against a batch still broadcasts."""
    model = _yaw_arm()
    q, v = np.tile(model.neutral(), (2, 1)), np.zeros((3, model.n_velocities))
    with pytest.raises(ModelError, match=r"arm: q and v must hold as many states \(rows\) or one of them one, got 2 "
                                         r"and 3"):
        sp.accelerations(model, q, v)
    with pytest.raises(ModelError, match=r"input 'yaw\.torque' must be 1 finite number\(s\) \(or \(B, 1\)\)"):
        sp.accelerations(model, q, v[:2], inputs={"yaw.torque": np.ones((3, 1))})
    one = sp.accelerations(model, q[:1], v[:1], inputs={"yaw.torque": 1.0})
    np.testing.assert_array_equal(sp.accelerations(model, q, v[:1], inputs={"yaw.torque": [[1.0]]}), np.tile(one, (2, 1)))


def test_static_equilibrium_start_and_time_are_checked() -> None:
    """A start of the wrong size was a TypeError from inside the quaternion algebra, t = nan was accepted."""
    from ctmm.spatial_linearization import static_equilibrium
    model = _yaw_arm()
    with pytest.raises(ModelError, match=r"static_equilibrium: start: arm: q must have 5 entries"):
        static_equilibrium(model, start=[1.0, 2.0])
    with pytest.raises(ModelError, match=r"static_equilibrium: start must be one configuration"):
        static_equilibrium(model, start=np.tile(model.neutral(), (2, 1)))
    with pytest.raises(ModelError, match=r"t must be finite"):
        static_equilibrium(model, t=float("nan"))
    with pytest.raises(ModelError, match=r"quaternion of joint 'ball' is zero"):
        static_equilibrium(model, start=[0.0, 0.0, 0.0, 0.0, 0.0])
