"""Every path of ``ctmm.simulate`` refuses a step grid beyond ``validation.MAX_STEPS`` before any work.

Found by a black-box probe: spatial RK4, generated spatial kernels and the ``solve_ivp`` output grids of
planar and spatial models ran (or tried to allocate a 7 TiB time grid) for ``t_final = 1e9 s`` with
``dt = 1 ms``, while chain and planar fixed-step paths refused.  The refusal must come at once and name
dt, the interval and the limit.
"""
from __future__ import annotations

import pytest

import ctmm
import ctmm.spatial as sp
from ctmm.elements import Fixed, Free, Mass, Spring
from ctmm.planar import PlanarModel, Pinned, RigidBody


def spatial_model() -> sp.SpatialModel:
    return sp.SpatialModel("arm", [
        sp.SpatialBody("b", 1.0, (0.01, 0.01, 0.01), center_of_mass=(0, 0, -0.2), points={"t": (0, 0, -0.4)}),
        sp.Revolute(name="j", parent=None, child="b", axis=(1, 0, 0), actuated=True, damping=0.1)],
        gravity=(0, 0, -9.81))


def planar_model() -> PlanarModel:
    return PlanarModel.chain("p", [Pinned("o"), RigidBody.uniform_link("l", mass=1.0, length=1.0)])


def chain() -> ctmm.Chain:
    return ctmm.Chain("c", [Fixed("w"), Spring("k", 10.0), Mass("m", 1.0), Free("e")])


CASES = [
    pytest.param(spatial_model, {"method": "rk4"}, id="spatial-rk4"),
    pytest.param(spatial_model, {"method": "rk4", "compiled": True}, id="spatial-generated"),
    pytest.param(spatial_model, {"method": "DOP853"}, id="spatial-solve_ivp-grid"),
    pytest.param(spatial_model, {"method": "newmark"}, id="spatial-newmark"),
    pytest.param(planar_model, {"method": "RK45"}, id="planar-solve_ivp-grid"),
    pytest.param(planar_model, {"method": "rk4"}, id="planar-rk4"),
    pytest.param(chain, {"method": "RK45"}, id="chain-solve_ivp-grid"),
    pytest.param(chain, {"method": "newmark"}, id="chain-newmark"),
]


@pytest.mark.parametrize("build, options", CASES)
@pytest.mark.parametrize("t_final", [1e9, 1e300])
def test_too_many_steps_are_refused_at_once(build, options, t_final):
    with pytest.raises(ctmm.ModelError, match=r"dt=0\.001 s .* steps; at most 5e\+07 are allowed"):
        ctmm.simulate(build(), t_final, 1e-3, **options)


def test_a_grid_just_inside_the_limit_is_not_refused_by_the_budget():
    """The budget itself is not the refusal for a legitimate run (1000 steps)."""
    result = ctmm.simulate(spatial_model(), 1.0, 1e-3)
    assert len(result.time) == 1001
