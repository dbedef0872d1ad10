"""A DT-TMM step of a planar model with feedback loops that does not converge names the loops that may be unstable
(``ctmm.simulate``, numpy and generated paths), as a diverging run with loops does (``ctmm.guard.unstable_loops_hint``):
the failure of a positive-feedback PD is an unstable closed loop, not a step too long.  The instability itself is
certified independently of the runs (``ctmm.stability.unstable_root_count`` of the same system: no unstable root with
the right sign, several with the wrong one).  The two paths agree to round-off up to the first failure; they need not
fail at the same step: the generated Newton forms the exact tangent and converged 75 steps longer here (the links
spinning at 1e5 rad) than the numpy transfer-form iteration, whose failure came at 7 rad."""
from __future__ import annotations

import numpy as np
import pytest

import ctmm
from ctmm.codegen import find_compiler
from ctmm.control import ControlledModel, Feedback
from ctmm.errors import ModelError
from ctmm.planar import PlanarModel, Pinned, RigidBody, SmoothHinge

DT = 1e-3


def controlled(gain: float, n: int = 2) -> ControlledModel:
    """``n`` uniform links (1 kg, 1 m) hanging under gravity with a PD on every hinge, ``u = -gain (20 angle + 2
    rate)`` (gain -1: positive feedback)."""
    elements = [Pinned("base")]
    for i in range(n):
        elements += [SmoothHinge(f"h{i}")] if i else []
        elements.append(RigidBody.uniform_link(f"link{i}", mass=1.0, length=1.0))
    loops = [Feedback("pd0", [("link0.theta", 20.0), ("link0.omega", 2.0)], "base.torque", gain=gain)]
    loops += [Feedback(f"pd{i}", [(f"h{i}.angle", 20.0), (f"h{i}.rate", 2.0)], f"h{i}.torque", gain=gain)
              for i in range(1, n)]
    return ControlledModel(PlanarModel.chain(f"chain{n}", elements, gravity=(0.0, -9.81)), loops)


def has_compiler() -> bool:
    try:
        find_compiler()
    except ModelError:
        return False
    return True


@pytest.fixture(scope="module")
def kernel_cache(tmp_path_factory):
    """One kernel folder for the module (a cold cache is not the point here): the positive-feedback kernel
    is built once for both tests that run it generated."""
    return tmp_path_factory.mktemp("kernels")


def test_the_positive_feedback_is_unstable_by_the_root_count():
    assert int(ctmm.stability.unstable_root_count(controlled(1.0), loop="pd0")[0]) == 0
    assert int(ctmm.stability.unstable_root_count(controlled(-1.0), loop="pd0")[0]) > 0


@pytest.mark.parametrize("compiled", [False, pytest.param(True, marks=pytest.mark.skipif(
    not has_compiler(), reason="no C compiler"))])
def test_a_newton_failure_with_loops_names_them(compiled, kernel_cache, monkeypatch):
    monkeypatch.setenv("CTMM_CACHE", str(kernel_cache))
    stable = ctmm.simulate(controlled(1.0), 0.6, DT, method="newmark", compiled=compiled,
                           x0={"link0.theta": 0.1})
    assert len(stable.time) == 601 and np.all(np.abs(stable["link0.theta"]) < np.pi / 2)    # the right sign holds it
    with pytest.raises(ctmm.ConvergenceError, match=r"did not converge.*reduce dt, or the closed loop\(s\) "
                       r"\['pd0', 'pd1'\] may be unstable: check ctmm.stability.unstable_root_count\(system, "
                       r"loop='pd0'\)") as failure:
        ctmm.simulate(controlled(-1.0), 2.0, DT, method="newmark", compiled=compiled, x0={"link0.theta": 0.1})
    partial = failure.value.partial_result
    assert failure.value.time == pytest.approx(partial.time[-1] + DT)     # the step after the last stored row
    assert np.max(np.abs(partial["link0.theta"])) > 1.0                   # it grew before the iteration failed


def test_both_paths_agree_to_round_off_up_to_the_first_failure(kernel_cache, monkeypatch):
    if not has_compiler():
        pytest.skip("no C compiler")
    monkeypatch.setenv("CTMM_CACHE", str(kernel_cache))
    partials = []
    for compiled in (False, True):
        with pytest.raises(ctmm.ConvergenceError, match="may be unstable") as failure:
            ctmm.simulate(controlled(-1.0), 2.0, DT, method="newmark", compiled=compiled, x0={"link0.theta": 0.1})
        partials.append(failure.value.partial_result)
    rows = min(len(partial.time) for partial in partials)
    np.testing.assert_array_equal(partials[0].time[:rows], partials[1].time[:rows])
    for name in ("link0.theta", "link1.theta", "link1.theta_dot", "pd0.u", "pd1.u"):
        first, second = partials[0][name][:rows], partials[1][name][:rows]
        assert np.max(np.abs(first - second)) <= 1e-11 * np.max(np.abs(first)), name
