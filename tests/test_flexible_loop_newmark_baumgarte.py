"""Why the flexible four-bar's implicit Newmark differed from a global Newmark of the Lagrange reference by ~1e-8.

The DT-TMM schemes on a kinematic loop step the accelerations of :meth:`KinematicLoopModel.solve`, which impose the
cut constraint at the acceleration level with Baumgarte stabilisation, ``Phi'' = -2 alpha Phi' - alpha^2 Phi``
(``alpha = baumgarte``, 20 1/s by default), and do not project.  The global Newmark of session 7 stepped the
reference's accelerations with ``alpha = 0`` (``Phi'' = 0``).  Newmark keeps the constraint only to its truncation
error, so the discrete solutions carry a drift ``Phi_n = O(h^2)``; on it the two right-hand sides differ by
``2 alpha Phi' + alpha^2 Phi = O(alpha h^2)``, hence the gap shrinking with ``h^2`` (docs/closed_loops.md, "Newmark on
a loop and the constraint level").  With the same constraint level on both sides they agree to Newton's tolerance.

Independent reference: :mod:`ctmm.reference.flexible_loop_lagrange` (assumed modes, Lagrange multipliers) stepped
by the global Newmark written in ``test_flexible_second_order_newmark``.
"""
from __future__ import annotations

import numpy as np
import pytest

import ctmm
from ctmm.planar.closed_loops import KinematicLoopModel
from ctmm.planar.implicit_kinematic_loops import simulate_loop_scheme
from ctmm.schemes import as_scheme
from ctmm.reference.flexible_loop_lagrange import FlexibleFourBarLagrange
from ctmm.scenarios.four_bar import COUPLER, CRANK, GROUND, MASSES, ROCKER

from test_flexible_second_order import RHO_A, _bent_moving_state, _four_bar
from test_flexible_second_order_newmark import _global_newmark

H, STEPS = 2e-4, 4


def _reference() -> FlexibleFourBarLagrange:
    return FlexibleFourBarLagrange((MASSES["crank"], CRANK), (COUPLER, RHO_A, 20.0), (MASSES["rocker"], ROCKER),
                                   GROUND, 3, inertia="second_order")


def _newmark(loop: KinematicLoopModel, q: np.ndarray, v: np.ndarray) -> np.ndarray:
    """The loop's Newmark with Baumgarte alone (``projection=False``: the formulation compared here; the default
    projects after every step, docs/closed_loops.md section 3b)."""
    run, _ = simulate_loop_scheme(loop, q, v, t_final=H * STEPS, dt=H, scheme=as_scheme("newmark"), projection=False)
    return run.q[-1]


@pytest.mark.slow
def test_loop_newmark_is_the_global_newmark_at_the_same_constraint_level():
    """Bent, vibrating coupler with the second-order inertia, 4 steps of 0.2 ms (slow: ~1 s of loop Newton steps): the loop's Newmark equals the
    global Newmark of the reference with the loop's Baumgarte rate to round-off (measured 6e-15)
    and differs from the reference's with ``alpha = 0`` by the Baumgarte terms on the discrete drift; a loop
    model built with ``baumgarte=0`` equals that one instead."""
    reference = _reference()
    stabilised = _four_bar(20.0, 3, True)
    q, v = _bent_moving_state(stabilised)
    assert stabilised.baumgarte == 20.0
    plain = KinematicLoopModel(stabilised.tree, stabilised.cuts, baumgarte=0.0)
    expected = {alpha: _global_newmark(lambda Q, V: reference.accelerations(Q, V, alpha)[0], q, v, H, STEPS)
                for alpha in (0.0, 20.0)}
    scale = np.abs(expected[20.0] - q).max()                       # the motion over the run: ~2e-2
    gap = np.abs(expected[20.0] - expected[0.0]).max()
    assert gap > 1e-7 * scale                    # the constraint level shows (measured 2.5e-9 m of 4.7e-3: 5e-7)
    for loop, alpha in ((stabilised, 20.0), (plain, 0.0)):
        difference = np.abs(_newmark(loop, q, v) - expected[alpha]).max()
        assert difference < 1e-4 * gap, alpha
