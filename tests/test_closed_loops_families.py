"""Body families in one planar model and in a kinematic loop: what is refused, by name (docs/mixed.md §5).

A planar model runs one deformable family's kernels over its whole sweep, so ``ctmm.fem`` subsystems and
``ctmm.flexible.ModalBeam`` s cannot share a model.  (Cut joints at subsystem nodes: ``tests/test_fem_cut_joints.py``.)
"""
from __future__ import annotations

import pytest

from ctmm.errors import ModelError
from ctmm.fem import BeamElement, FiniteElementModel
from ctmm.flexible import ModalBeam
from ctmm.planar import Pinned, PlanarModel, SmoothHinge


def _subsystem(name: str):
    nodes = {f"n{k}": (k * 0.25, 0.0) for k in range(3)}
    elements = [BeamElement(f"e{k}", f"n{k}", f"n{k + 1}", 20.0, 5e3, 0.8) for k in range(2)]
    return FiniteElementModel(name, nodes, elements).subsystem(name, boundary=("n0", "n2"))


def test_subsystems_and_modal_beams_in_one_model_are_refused_by_name():
    beam = ModalBeam("arm", length=0.5, bending_stiffness=50.0, mass_per_length=1.0, n_modes=2)
    with pytest.raises(ModelError, match=r"one body family only.*GlobalSubsystem.*ModalBeam"):
        PlanarModel.chain("mixed", [Pinned("o"), beam, SmoothHinge("h"), _subsystem("plate")])
    PlanarModel.chain("fe_only", [Pinned("o"), _subsystem("arm"), SmoothHinge("h"), _subsystem("plate")])
