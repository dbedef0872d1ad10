"""Exact spatial fields of trees in gravity (issues 14/15, ``fields="exact"``): every branch hangs or stands
along gravity from its joint; beams carry the weight of their own subtree, rigid bodies the pendulum
stiffness of their outboard first moment (ctmm/spatial_exact_gravity.py).

References, none of them transfer matrices:

* rigid trees: the global Newton-Euler model (ctmm/reference/spatial_tree.py) linearised by complex steps
  (its geometric stiffness of gravity comes from differentiating the nonlinear equations), which also
  refuses the point if it is not an equilibrium;
* trees of beams: the planar Hermite finite-element tree with the consistent geometric stiffness of the
  statically computed tension (ctmm/reference/hanging_tree_fe.py), one model per bending plane,
  Richardson over 12 / 24 elements per piece; every one of the lowest 24 frequencies is certified by the
  exact tree's own Wittrick-Williams count in a bracket around the finite-element value;
* a rigid hub carrying beams off its vertical: the modal model's linearisation (``ctmm.natural_frequencies``
  with the default fields, about the equilibrium it finds): upper bounds that close in on the exact
  frequencies as the modes increase (an inextensible-like axial stiffness, since the modal model keeps
  the static stretch that the exact form neglects).
"""
from __future__ import annotations

import numpy as np
import pytest

import ctmm
import ctmm.spatial as sp
from ctmm.errors import ModelError
from ctmm.reference import spatial_tree as ref
from ctmm.reference.hanging_tree_fe import HangingTree, TreeBeam
from ctmm.spatial_exact_fields import exact_form

# The references here are linear theory about the unstretched beams, as the exact fields; the static stretch
# they neglect is measured and warned in tests/test_spatial_exact_stretch.py.
pytestmark = pytest.mark.filterwarnings("ignore::ctmm.spatial_exact_gravity.StretchWarning")

G = 9.81
X, Y = (1.0, 0.0, 0.0), (0.0, 1.0, 0.0)
DOWN = np.array([[0.0, 0.0, 1.0], [0.0, 1.0, 0.0], [-1.0, 0.0, 0.0]])      # beam x along world -z, beam y = world y

# a hub whose children hang off its vertical, balanced (first moment x: 0.4 * 0.3 - 0.6 * 0.2 = 0), the right
# pendulum carrying two bobs at +-0.1 sideways (nested); name, parent, kind, mass, centre, inertia, points, axes,
# point on the parent, joint stiffness
RIGID = [("hub", None, "universal", 1.0, (0, 0, -0.1), (0.02, 0.03, 0.04), {"left": (0.3, 0, -0.2), "right": (-0.2, 0, -0.2)},
          [X, Y], None, 4.0),
         ("l", "hub", "revolute", 0.4, (0, 0, -0.25), (0.004, 0.005, 0.002), {}, [Y], "left", 2.0),
         ("r", "hub", "universal", 0.2, (0, 0, -0.15), (0.002, 0.003, 0.001), {"a": (0, 0.1, -0.3), "b": (0, -0.1, -0.3)},
          [X, Y], "right", 3.0),
         ("ra", "r", "revolute", 0.2, (0, 0, -0.1), (0.001, 0.001, 0.0005), {}, [X], "a", 1.0),
         ("rb", "r", "universal", 0.2, (0, 0, -0.12), (0.001, 0.0012, 0.0005), {}, [X, Y], "b", 1.5)]


def rigid_tree(gravity: float, spring: float = 1.0, parts=RIGID) -> sp.SpatialModel:
    elements: list = []
    for name, parent, kind, mass, center, inertia, points, axes, point, k in parts:
        elements.append(sp.SpatialBody(name, mass, np.diag(inertia), center_of_mass=center, points=points))
        joint = dict(name=f"j_{name}", parent=parent, child=name, stiffness=spring * k, actuated=parent is None)
        if parent is not None:
            joint["point"] = point
        elements.append(sp.Revolute(axis=axes[0], **joint) if kind == "revolute"
                        else sp.Universal(axis1=axes[0], axis2=axes[1], **joint))
    return sp.SpatialModel("hub_tree", elements, gravity=(0.0, 0.0, gravity))


def newton_euler_tree(gravity: float, spring: float = 1.0) -> ref.SpatialTree:
    names = [part[0] for part in RIGID]
    bodies = []
    for name, parent, kind, mass, center, inertia, points, axes, point, k in RIGID:
        index = -1 if parent is None else names.index(parent)
        at = np.zeros(3) if parent is None else np.array(RIGID[index][6][point], dtype=float)
        bodies.append(ref.SpatialBody(name, index, kind, mass, np.array(center, dtype=float), np.diag(inertia),
                                      axes=np.array(axes), joint_position=at, stiffness=spring * k))
    return ref.SpatialTree(bodies, gravity=np.array([0.0, 0.0, gravity]))


@pytest.mark.parametrize("gravity, spring", [(-G, 1.0), (G, 8.0)])     # hanging; standing on stiffer joints
def test_a_rigid_tree_hanging_off_its_vertical_equals_the_newton_euler_linearisation(gravity, spring):
    reference = ref.natural_frequencies(newton_euler_tree(gravity, spring), np.zeros(8))   # refuses a non-equilibrium
    # every frequency certified by the exact tree's own count in a bracket of 1e-11 around the reference's (the
    # bisection of ctmm.natural_frequencies finds them 5e-15 apart; the count is what it bisects on)
    count = exact_form(rigid_tree(gravity, spring)).chain.eigenvalue_count(
        np.concatenate([reference * (1 - 1e-11), reference * (1 + 1e-11)])).reshape(2, 8)
    np.testing.assert_array_equal(count, [np.arange(8), np.arange(1, 9)])
    weightless = ref.natural_frequencies(newton_euler_tree(0.0, spring), np.zeros(8))
    assert np.min(np.abs(reference / weightless - 1.0)) > 1e-6 and np.max(np.abs(reference / weightless - 1.0)) > 0.1


def test_the_response_of_a_rigid_tree_in_gravity_equals_the_newton_euler_receptance():
    omega = np.array([0.7, 6.0, 13.0, 30.0])
    outputs = ["j_hub.q1", "j_l.angle", "j_r.q1", "j_ra.angle", "j_rb.q1"]      # l swings about y: not excited
    frf = ctmm.frequency_response(rigid_tree(-G), omega, input="j_hub.torque1", output=outputs, fields="exact")
    mass, _, stiffness = ref.linearize(newton_euler_tree(-G), np.zeros(8))
    columns = [0, 2, 3, 5, 6]                       # hub q1 q2, l, r q1 q2, ra, rb q1 q2: the outputs' coordinates
    for k, w in enumerate(omega):
        expected = np.linalg.solve(stiffness - w * w * mass, np.eye(8)[0])[columns]
        got = np.array([frf(name, "j_hub.torque1")[k] for name in outputs])
        assert np.max(np.abs(got - expected)) <= 1e-9 * np.max(np.abs(expected)), w      # 6e-15 measured


# beams of a tree hanging along gravity: name, parent, (station, x), length, rhoA, EI_y, EI_z, tip mass, tip inertia
BEAMS = [("trunk", None, None, 1.2, 0.5, 3.0, 4.2, 0.5, (1e-5, 0.002, 0.002)),
         ("side", "trunk", ("mid", 0.5), 0.6, 0.3, 1.0, 1.4, 0.3, (1e-5, 0.001, 0.001)),
         ("twig", "side", ("knot", 0.3), 0.3, 0.2, 0.5, 0.65, 0.1, (1e-5, 0.0004, 0.0004)),
         ("tail", "trunk", ("tip", 1.2), 0.4, 0.25, 0.8, 0.7, 0.2, (1e-5, 0.0012, 0.0012))]


def beam_tree(gravity: float, turned: str = "") -> sp.SpatialModel:
    """Torsion and stretching stiff (their first frequencies ~2000 rad/s): the lowest 24 modes bend;
    ``turned``: that beam is welded turned by ``DOWN.T`` (across gravity)."""
    elements: list = []
    for name, parent, at, length, rho, EIy, EIz, mass, inertia in BEAMS:
        stations = {b[2][0]: b[2][1] for b in BEAMS if b[1] == name and b[2][0] != "tip"}
        elements += [sp.SpatialBeam(name, length=length, mass_per_length=rho, bending_stiffness_y=EIy,
                                    bending_stiffness_z=EIz, torsional_stiffness=50.0, polar_inertia_per_length=1e-4,
                                    axial_stiffness=1e7, n_modes_y=1, n_modes_z=1, n_torsion_modes=1, n_axial_modes=1,
                                    stations=stations),
                     sp.Weld(name=f"{name}_root", parent=None, child=name, rotation=DOWN) if parent is None
                     else sp.Weld(name=f"{name}_root", parent=parent, point=at[0], child=name,
                                  rotation=DOWN.T if name == turned else np.eye(3)),
                     sp.SpatialBody(f"{name}_end", mass, np.diag(inertia)),           # its centre at the tip
                     sp.Weld(name=f"{name}_grip", parent=name, point="tip", child=f"{name}_end")]
    return sp.SpatialModel("beam_tree", elements, gravity=(0.0, 0.0, gravity))


def finite_element_planes(gravity: float, count: int) -> tuple[np.ndarray, np.ndarray]:
    """The lowest ``count`` frequencies of both bending planes [rad/s] and their Richardson error estimates."""
    values, bounds = [], []
    for stiffness, axis in ((5, 2), (6, 1)):   # w_y: EI_y, tip turning about beam z; w_z: EI_z, about beam y
        tree = HangingTree([TreeBeam(b[0], b[3], b[stiffness], b[4], b[1], 0.0 if b[2] is None else b[2][1], b[7],
                                     b[8][axis]) for b in BEAMS], gravity)
        coarse, fine = tree.natural_frequencies(12, count), tree.natural_frequencies(24, count)
        values += list(fine + (fine - coarse) / 15.0)
        bounds += list(np.abs(fine - coarse) / 15.0)
    order = np.argsort(values)[:count]
    return np.array(values)[order], np.array(bounds)[order]


def test_a_tree_of_beams_hanging_from_stations_has_the_finite_element_frequencies_up_to_mode_24():
    count = 24
    reference, bound = finite_element_planes(G, count)
    width = 5e-9 * reference + 0.1 * bound          # measured: |exact - reference| <= 5.5e-9 of it, bound <= 1.7e-6
    chain = exact_form(beam_tree(-G)).chain
    below = chain.eigenvalue_count(np.concatenate([reference - width, reference + width])).reshape(2, count)
    np.testing.assert_array_equal(below[0], np.arange(count))               # mode k lies in its bracket
    np.testing.assert_array_equal(below[1], np.arange(1, count + 1))
    weightless, _ = finite_element_planes(0.0, count)
    assert np.min(np.abs(reference - weightless) - 2 * width) > 0.0          # the brackets see the tension


def hub_with_beams(modes: int) -> sp.SpatialModel:
    """A hub on a universal joint with two beams hanging at +-x off its vertical, balanced: first moment x
    0.36 kg * 0.15 m - 0.54 kg * 0.1 m = 0."""
    def arm(name, length, rho, EIy, EIz):
        return sp.SpatialBeam(name, length=length, mass_per_length=rho, bending_stiffness_y=EIy, bending_stiffness_z=EIz,
                              torsional_stiffness=3.0, polar_inertia_per_length=0.002, axial_stiffness=5e7,
                              n_modes_y=modes, n_modes_z=modes, n_torsion_modes=modes, n_axial_modes=modes)
    return sp.SpatialModel("hub_beams", [
        sp.SpatialBody("hub", 1.0, np.diag([0.02, 0.03, 0.04]), center_of_mass=(0, 0, -0.1),
                       points={"left": (0.15, 0, -0.2), "right": (-0.1, 0, -0.2)}),
        sp.Universal(name="pivot", parent=None, child="hub", axis1=X, axis2=Y, stiffness=6.0),
        arm("left", 0.6, 0.4, 2.0, 2.5), sp.Weld(name="lw", parent="hub", point="left", child="left", rotation=DOWN),
        sp.SpatialBody("lb", 0.12, np.diag([0.0002, 0.0003, 0.0003])), sp.Weld(name="lg", parent="left", point="tip", child="lb"),
        arm("right", 0.8, 0.5, 3.0, 3.5), sp.Weld(name="rw", parent="hub", point="right", child="right", rotation=DOWN),
        sp.SpatialBody("rb", 0.14, np.diag([0.0002, 0.0003, 0.0003])), sp.Weld(name="rg", parent="right", point="tip", child="rb")],
        gravity=(0.0, 0.0, -G))


def test_a_hub_carrying_beams_off_its_vertical_is_the_limit_of_the_modal_linearisation():
    exact = ctmm.natural_frequencies(hub_with_beams(3), n_modes=4, fields="exact")
    three, four = (ctmm.natural_frequencies(hub_with_beams(m), n_modes=4) for m in (3, 4))
    gap3, gap4 = (three - exact) / exact, (four - exact) / exact
    assert np.all(gap4 >= -1e-9) and np.all(gap4 <= 0.6 * gap3)             # upper bounds closing in
    assert np.all(gap4[:2] <= 2e-5) and np.all(gap4 <= 3e-4)                 # measured 0.7-1.0e-5, 1.5e-4


def test_gravity_the_tree_cannot_carry_at_rest_is_refused_naming_the_part():
    unbalanced = [RIGID[0][:6] + ({"left": (0.3, 0, -0.2), "right": (-0.25, 0, -0.2)},) + RIGID[0][7:]] + RIGID[1:]
    with pytest.raises(ModelError, match=r"body 'hub' has its outboard first moment .* at \[-0\.03, 0\.0, -0\.3\] kg m"):
        ctmm.natural_frequencies(rigid_tree(-G, parts=unbalanced), n_modes=1, fields="exact")
    with pytest.raises(ModelError, match=r"beam 'twig' lies along \[1\.0, 0\.0, 0\.0\] \(world axes\), not along gravity"):
        ctmm.natural_frequencies(beam_tree(-G, turned="twig"), n_modes=1, fields="exact")
