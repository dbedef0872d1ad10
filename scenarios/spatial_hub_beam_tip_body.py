"""Hub-beam with a terminal rigid body solved with the spatial beam (seed 003 section 6.6.2, Figs. 6.9-6.12).

As ``spatial_hub_beam`` (same parameters, square-wave hub moment, zero initial conditions) with a
rigid body of 0.2 kg and (practically) zero moment of inertia (1e-9 kg m^2) welded to the beam tip
(fixed mounting flexible -> rigid: the body follows the tip section).  The tip body's axial force
adds to the centrifugal stiffening; the reference carries it too (``f_1`` of the Lagrange model).
"""
from __future__ import annotations

from pathlib import Path

from ctmm.scenarios.spatial_hub_beam import run_case

NAME = "spatial_hub_beam_tip_body"
DESCRIPTION = ("Hub-beam with a 0.2 kg terminal rigid body solved with the spatial beam (seed 003 6.6.2, "
               "Figs. 6.9-6.12) vs assumed-modes Lagrange")


def run(output_dir: Path, quick: bool = False) -> dict:
    return run_case(output_dir, quick, 0.2, NAME)
