"""Planar model construction: validation messages, chain sugar, coordinates, tree topology."""
from __future__ import annotations

import math

import numpy as np
import pytest

from ctmm.errors import ModelError, UnknownNameError
from ctmm.planar import (ActuatedHinge, DamperHinge, DrivenHinge, ElasticHinge, Fixed, Free,
                         FreeBase, Load, Pinned, PlanarModel, RigidBody, SmoothHinge,
                         SpringDamperHinge)


def link(name, **kw):
    return RigidBody.uniform_link(name, mass=1.0, length=1.0, **kw)


def test_body_parameters_are_validated():
    with pytest.raises(ModelError, match=r"b: mass must be > 0, got -1"):
        RigidBody("b", mass=-1, inertia=1.0)
    with pytest.raises(ModelError, match=r"b: inertia must be > 0, got 0"):
        RigidBody("b", mass=1.0, inertia=0)
    with pytest.raises(ModelError, match=r"b: center_of_mass must be a 2-vector"):
        RigidBody("b", mass=1.0, inertia=1.0, center_of_mass=(1, 2, 3))
    with pytest.raises(ModelError, match=r"element name must be a non-empty string"):
        RigidBody("a.b", mass=1.0, inertia=1.0)
    with pytest.raises(ModelError, match=r"load force_x must be callable"):
        Load(force_x=lambda: 1.0)


def test_hinge_parameters_are_validated():
    with pytest.raises(ModelError, match=r"k: stiffness must be > 0, got -2"):
        ElasticHinge("k", stiffness=-2)
    with pytest.raises(ModelError, match=r"k: stiffness is required"):
        ElasticHinge("k")
    with pytest.raises(ModelError, match=r"c: damping must be > 0"):
        DamperHinge("c", damping=0.0)
    with pytest.raises(ModelError, match=r"kc: damping must be >= 0"):
        SpringDamperHinge("kc", stiffness=1.0, damping=-1.0)
    with pytest.raises(ModelError, match=r"m: kp must be >= 0"):
        ActuatedHinge("m", kp=-1.0)
    with pytest.raises(ModelError, match=r"reference_rate is required"):
        ActuatedHinge("m", kd=1.0, reference=lambda t: math.sin(t))
    with pytest.raises(ModelError, match=r"d: rate\(.*\) .* is not the time derivative"):
        DrivenHinge("d", angle=lambda t: t * t, rate=lambda t: t, acceleration=2.0)


def test_chain_sugar_and_coordinates():
    model = PlanarModel.chain("c", [Pinned("base"), link("a"), SmoothHinge("h1"), link("b"),
                                    DrivenHinge("d", angle=0.3), link("c"), Free("tip")])
    assert model.coordinates == ("a.theta", "b.theta")
    assert model.joint_names == ("base", "h1", "d")
    floating = PlanarModel.chain("f", [FreeBase("fb"), link("a"), SmoothHinge("h"), link("b")])
    assert floating.coordinates == ("a.x", "a.y", "a.theta", "b.theta")
    welded = PlanarModel.chain("w", [Fixed("g", angle=0.2), link("a"), SmoothHinge("h"), link("b")])
    assert welded.coordinates == ("b.theta",)
    theta, _ = welded.body_angles(np.array([1.0]), np.array([0.0]), 0.0)
    assert theta[0] == pytest.approx(0.2)


def test_chain_sugar_errors():
    with pytest.raises(ModelError, match="must start with Fixed, Pinned or FreeBase"):
        PlanarModel.chain("c", [link("a")])
    with pytest.raises(ModelError, match="follows a body directly"):
        PlanarModel.chain("c", [Pinned("o"), link("a"), link("b")])
    with pytest.raises(ModelError, match="has no outboard body"):
        PlanarModel.chain("c", [Pinned("o"), link("a"), SmoothHinge("h")])
    with pytest.raises(ModelError, match="follow each other"):
        PlanarModel.chain("c", [Fixed("g"), SmoothHinge("h"), SmoothHinge("k"), link("a")])


def test_tree_validation_lists_every_problem():
    bodies = [link("a"), link("b"), link("c"), link("d"), link("e")]
    elements = bodies + [
        Pinned("o", child="a"),
        SmoothHinge("h1", parent="a", child="zz"),           # unknown child
        SmoothHinge("h2", parent="qq", child="b"),           # unknown parent
        SmoothHinge("h3", parent="c", child="d"),            # c <-> d cycle
        SmoothHinge("h4", parent="d", child="c"),
        SmoothHinge("h5", parent="a.tip", child="e"),        # unknown end
    ]
    with pytest.raises(ModelError) as info:
        PlanarModel("bad", elements)
    text = str(info.value)
    assert "hinge 'h1': unknown child 'zz'; bodies: a, b, c, d, e" in text
    assert "hinge 'h2': unknown parent 'qq'" in text
    assert "cycle: c -> d -> c" in text or "cycle: d -> c -> d" in text
    assert "no path to a base: c, d" in text
    assert "body 'a' has no end 'tip'; ends: out" in text
    assert "bodies without an inboard hinge or base: b, e" in text


def test_tree_ambiguous_end_and_double_parent():
    fork = RigidBody("fork", mass=1.0, inertia=0.1, outboard={"l": (1, 0.5), "r": (1, -0.5)})
    with pytest.raises(ModelError, match=r"parent body 'fork' has ends \['l', 'r'\]"):
        PlanarModel("t", [fork, link("x"), Pinned("o", child="fork"),
                          SmoothHinge("h", parent="fork", child="x")])
    with pytest.raises(ModelError, match="body 'x' has several inboard hinges"):
        PlanarModel("t", [fork, link("x"), Pinned("o", child="fork"),
                          SmoothHinge("h", parent="fork.l", child="x"),
                          SmoothHinge("k", parent="fork.r", child="x")])
    with pytest.raises(ModelError, match="duplicate element name 'x'"):
        PlanarModel("t", [link("x"), link("x"), Pinned("o", child="x")])


def test_unknown_coordinate_lists_names():
    model = PlanarModel.chain("c", [Pinned("o"), link("a")])
    with pytest.raises(UnknownNameError, match=r"unknown coordinate 'b.theta'; available: a.theta"):
        model.coordinate_index("b.theta")


def test_tree_topological_order_and_energy():
    fork = RigidBody("fork", mass=1.0, inertia=0.1, center_of_mass=(0.5, 0.0),
                     outboard={"l": (1, 0.5), "r": (1, -0.5)})
    model = PlanarModel("t", [link("x"), link("y"), fork, Pinned("o", child="fork"),
                              SmoothHinge("h", parent="fork.l", child="x"),
                              SmoothHinge("k", parent="fork.r", child="y")])
    assert model.body_names[0] == "fork"
    assert set(model.body_names[1:]) == {"x", "y"}
    q = np.zeros(3)
    energy = model.energy(q, np.zeros(3))
    # potential: centres at y = 0 (fork), 0.5 (x), -0.5 (y): sum = 0
    assert energy == pytest.approx(0.0, abs=1e-12)


def test_constant_prescribed_motions_read_like_varying_ones():
    """``driven(t)`` reads constant prescribed motions (numbers, welded mountings) once at construction: the
    same tuples as the same motion given as functions of time (evaluated per call), and a varying one still
    follows ``t``."""
    from ctmm.planar.elements import FixedMounting

    def model(angle, rate, acceleration):
        return PlanarModel.chain("m", [Fixed("g"), DrivenHinge("d", angle=angle, rate=rate, acceleration=acceleration),
                                       link("a"), FixedMounting("w", angle=0.25), link("b")])

    constant, functions = model(0.3, 0.0, 0.0), model(lambda t: 0.3, lambda t: 0.0, lambda t: 0.0)
    for t in (0.0, 1.7):
        assert constant.driven(t) == functions.driven(t) == [(0, 0.3, 0.0, 0.0), (1, 0.25, 0.0, 0.0)]
    assert all(type(value) is float for entry in constant.driven(0.0) for value in entry[1:])
    constant.driven(0.0).clear()                        # a caller's list is its own
    assert len(constant.driven(0.0)) == 2
    moving = model(math.sin, math.cos, lambda t: -math.sin(t))
    assert moving.driven(0.5)[0] == (0, math.sin(0.5), math.cos(0.5), -math.sin(0.5))
