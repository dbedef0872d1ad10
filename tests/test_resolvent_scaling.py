"""The resolvent rule (``ctmm.controlled_linearization.resolvent``) measures the conditioning of the system it
solves: the balanced ``s I - A`` scaled by rows and columns.  A stiff model (a 2 mm aluminium plate subsystem,
omega_max ~ 7e4 rad/s, beside links on soft joints) is answered at low frequencies -- the balanced matrix alone has
condition ~1e8 there and was refused -- and matches the global finite-element model of
ctmm/reference/spatial_fe_global.py (own element code); a frequency within 1e-10 (relative) of its undamped pole is
still refused.  Closed forms: a diagonal ``A`` answers ``1 / (s - a_i)``."""
from __future__ import annotations

import numpy as np
import pytest
import scipy.linalg

import ctmm
import ctmm.spatial as sp
from ctmm.controlled_linearization import RESOLVENT_CONDITION, FrequencyAtPoleError, resolvent
from ctmm.fem import SpatialFiniteElementModel, SpatialPlateElement
from ctmm.reference.spatial_fe_global import FEFrame, FramePlate, Link, SpatialFEChain

from test_zero_modes import ALUMINIUM, I1, I2, NODES

QUADS = [(f"{i}_0", f"{i + 1}_0", f"{i + 1}_1", f"{i}_1") for i in range(2)]
HINGE = 0.02                                                    # N m/rad: a 1.7 rad/s mode beside 7e4 rad/s


def stiff_plate_chain():
    """tests/test_zero_modes.py's plate chain (free yaw link, stiff plate on a sprung pitch joint, a link on a soft
    hinge at its corner, no gravity) with an actuated yaw; and the global reference."""
    plates = [SpatialPlateElement(f"p{i}", quad, ALUMINIUM["h"], ALUMINIUM["E"], ALUMINIUM["nu"], ALUMINIUM["rho"])
              for i, quad in enumerate(QUADS)]
    fe = SpatialFiniteElementModel("fe", NODES, plates)
    model = sp.SpatialModel("stiff_plate", [
        sp.SpatialBody("link1", 1.2, I1, center_of_mass=(0.1, 0.0, 0.15), points={"tip": (0.2, 0.0, 0.3)}),
        sp.Revolute(name="yaw", parent=None, child="link1", axis=(0, 0, 1), actuated=True),
        fe.subsystem("panel", boundary=("0_0", "2_1")),
        sp.Revolute(name="pitch", parent="link1", point="tip", child="panel", axis=(0, 1, 0), stiffness=200.0),
        sp.SpatialBody("link2", 0.3, I2, center_of_mass=(0.0, 0.05, -0.1)),
        sp.Revolute(name="hinge", parent="panel", point="2_1", child="link2", axis=(1, 0, 0), stiffness=HINGE)],
        gravity=(0.0, 0.0, 0.0))
    reference = SpatialFEChain([Link(1.2, I1, (0.1, 0.0, 0.15), (0, 0, 1), (0, 0, 0)),
                                FEFrame(NODES, "0_0", [], [], axis=(0, 1, 0), point=(0.2, 0.0, 0.3),
                                        plates=[FramePlate(quad, **ALUMINIUM) for quad in QUADS]),
                                Link(0.3, I2, (0.0, 0.05, -0.1), (1, 0, 0), "2_1")],
                               gravity=(0.0, 0.0, 0.0), joint_springs={1: (200.0, 0.0), 2: (HINGE, 0.0)})
    return model, reference, (np.zeros(model.n_positions), np.zeros(model.n_velocities))


def test_stiff_plate_chain_is_answered_at_low_frequencies_and_matches_the_global_model():
    model, reference, rest = stiff_plate_chain()
    w = np.array([0.3, 0.9, 3.0, 10.0])
    outputs = ["panel.2_1_uz", "hinge.angle", "yaw.angle"]
    frf = ctmm.frequency_response(model, w, input="yaw.torque", output=outputs, operating_point=rest)
    for k, name in enumerate(outputs):
        expected = reference.frequency_response(rest[0], w, load=0, output=model.coordinates.index(name))
        assert np.all(np.abs(expected) > 1e-3)
        np.testing.assert_allclose(np.asarray(frf.response)[k, 0], expected, rtol=1e-8)
    # the regime of the fix: the balanced s I - A alone is worse conditioned than the limit at every one of them
    balanced = scipy.linalg.matrix_balance(np.asarray(ctmm.linearize(model, operating_point=rest).state_space.A),
                                           permute=False)[0]
    assert min(np.linalg.cond(1j * x * np.eye(len(balanced)) - balanced) for x in w) > RESOLVENT_CONDITION


@pytest.mark.parametrize("offset", [1e-10, -1e-10])
def test_a_frequency_next_to_an_undamped_pole_of_the_stiff_chain_is_still_refused(offset):
    model, reference, rest = stiff_plate_chain()
    expected = reference.natural_frequencies(rest[0])[1]                     # the hinge mode, ~1.73 rad/s
    poles = np.linalg.eigvals(np.asarray(ctmm.linearize(model, operating_point=rest).state_space.A))
    pole = poles[np.argmin(np.abs(poles - 1j * expected))]
    assert abs(pole.real) < 1e-9 * expected and abs(pole.imag / expected - 1) < 1e-8
    w = float(pole.imag * (1.0 + offset))
    with pytest.raises(FrequencyAtPoleError, match=rf"'stiff_plate' is singular at omega = {w!r} rad/s.*row- and "
                                                   rf"column-scaled.*nearest pole is .*{expected:.6g}"):
        ctmm.frequency_response(model, [0.9, w], input="yaw.torque", output="hinge.angle", operating_point=rest)


def test_a_fast_stable_mode_beside_a_slow_one_is_answered_exactly_and_a_pole_on_the_axis_refused():
    """Diagonal ``A`` (balancing leaves it as it is): ``(s I - A)^-1 = diag(1 / (s - a_i))``; before the row and
    column scaling the condition number ``|s - a_fast| / |s - a_slow|`` (~1e9) refused it."""
    a = np.array([-1.0, -1e9, -3.0 + 40.0j])
    s = 1j * np.array([0.3, 5.0, 40.0 + 1e-3])
    B = np.array([[1.0, 2.0], [1.0, 0.0], [0.0, -1.0]])
    values = resolvent(np.diag(a), B, s, "diagonal")
    np.testing.assert_allclose(values, B[None, :, :] / (s[:, None] - a[None, :])[:, :, None], rtol=4 * np.finfo(float).eps)
    with pytest.raises(FrequencyAtPoleError, match=r"'diagonal' is singular at omega = 2.0 rad/s.*nearest pole is "
                                                   r"0\+2j"):
        resolvent(np.diag([-1e9, 2.0j, -1.0]), B, np.array([0.3j, 2.0j]), "diagonal")
