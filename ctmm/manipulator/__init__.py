"""Controlled flexible manipulator: PD hub torque and PZT modal-velocity feedback (seed 001 §9.6.1).

Modules: :mod:`~ctmm.manipulator.parameters` (arm, hub, PZT patches, moment per volt,
reference motion), :mod:`~ctmm.manipulator.laws` (PD and PZT control laws),
:mod:`~ctmm.manipulator.frequency` (linearised controlled chain of exact beam fields with
embedded loops), :mod:`~ctmm.manipulator.simulation` (time domain on the modal beam: embedded,
delayed and co-simulated laws), :mod:`~ctmm.manipulator.scene` (the same manipulator as a general planar
model with the PD and PZT laws as :class:`~ctmm.control.Feedback` loops, for the verbs).  Derivations and numbers: ``docs/manipulator.md``.
"""
from .frequency import LinearManipulator, RigidHub, plant_chain
from .laws import HubPD, PZTFeedback
from .simulation import FlexibleManipulator, ManipulatorSimulation
from .scene import manipulator_plant, manipulator_scene, scene_references
from .parameters import (PZT_5A, PZT_5H, SEED_KD, SEED_KP, SEED_MOVE, SEED_PZT_GAIN, Arm, CycloidalMove, Hub,
                         Manipulator, PiezoMaterial, PZTPatch, moment_per_volt, seed_manipulator)

__all__ = ["Arm", "Hub", "PiezoMaterial", "PZT_5A", "PZT_5H", "PZTPatch", "Manipulator", "moment_per_volt",
           "CycloidalMove", "seed_manipulator", "SEED_KP", "SEED_KD", "SEED_PZT_GAIN", "SEED_MOVE", "HubPD", "PZTFeedback", "LinearManipulator", "RigidHub",
           "plant_chain", "FlexibleManipulator", "ManipulatorSimulation", "manipulator_plant", "manipulator_scene",
           "scene_references"]
