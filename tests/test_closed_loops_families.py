"""Body families in one planar model and in a kinematic loop: what is refused, by name (docs/mixed.md §5).

A planar model runs one deformable family's kernels over its whole sweep, so ``ctmm.fem`` subsystems and
``ctmm.flexible.ModalBeam`` s cannot share a model; a cut joint cannot end on a subsystem node.
"""
from __future__ import annotations

import pytest

from ctmm.errors import ModelError
from ctmm.fem import BeamElement, FiniteElementModel
from ctmm.flexible import ModalBeam
from ctmm.planar import Fixed, Pinned, PlanarModel, RigidBody, SmoothHinge
from ctmm.planar.closed_loops import CutJoint, KinematicLoopModel


def _subsystem(name: str):
    nodes = {f"n{k}": (k * 0.25, 0.0) for k in range(3)}
    elements = [BeamElement(f"e{k}", f"n{k}", f"n{k + 1}", 20.0, 5e3, 0.8) for k in range(2)]
    return FiniteElementModel(name, nodes, elements).subsystem(name, boundary=("n0", "n2"))


def test_subsystems_and_modal_beams_in_one_model_are_refused_by_name():
    beam = ModalBeam("arm", length=0.5, bending_stiffness=50.0, mass_per_length=1.0, n_modes=2)
    with pytest.raises(ModelError, match=r"one body family only.*GlobalSubsystem.*ModalBeam"):
        PlanarModel.chain("mixed", [Pinned("o"), beam, SmoothHinge("h"), _subsystem("plate")])
    PlanarModel.chain("fe_only", [Pinned("o"), _subsystem("arm"), SmoothHinge("h"), _subsystem("plate")])


def test_a_cut_joint_on_a_subsystem_node_is_refused_by_name():
    tree = PlanarModel("loop", [Fixed("g", position=(0.0, 0.0)), Fixed("g2", position=(0.5, 0.0)),
                                _subsystem("frame"), SmoothHinge("h1", parent="g", child="frame"),
                                RigidBody.uniform_link("link", mass=0.5, length=0.5),
                                SmoothHinge("h2", parent="g2", child="link")])
    with pytest.raises(ModelError, match="ctmm.fem subsystem"):
        KinematicLoopModel(tree, [CutJoint("h3", parent="link.out", child="frame.n2")])
