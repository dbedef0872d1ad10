"""Hub-beam system with a terminal rigid body (seed 003 section 6.6.2, Figs. 6.11-6.12).

As ``hub_beam`` (same chosen parameters, square-wave hub moment, zero initial conditions) with a
rigid body of 0.2 kg and (practically) zero moment of inertia welded to the beam tip (fixed
mounting flexible -> rigid: the body follows the tip slope).  The tip mass adds to the
centrifugal axial force that stiffens the beam (``N(x)`` includes the tip body's axial force).
"""
from __future__ import annotations

from pathlib import Path

from ctmm.scenarios.hub_beam import run_case

NAME = "hub_beam_tip_body"
DESCRIPTION = ("Hub-beam with a 0.2 kg terminal rigid body (seed 003 6.6.2): modal beam TMM + "
               "RK4 vs assumed-modes Lagrange")


def run(output_dir: Path, quick: bool = False) -> dict:
    return run_case(output_dir, quick, 0.2, NAME)
