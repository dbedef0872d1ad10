"""Controlled flexible manipulator: PD hub torque and PZT modal-velocity feedback (seed 001 §9.6.1).

Modules: :mod:`~ctmm.manipulator.parameters` (arm, hub, PZT patches, moment per volt,
reference motion), :mod:`~ctmm.manipulator.laws` (the parameters of the PD and PZT laws),
:mod:`~ctmm.manipulator.scene` (the manipulator as a general planar model with the PD and PZT laws as
:class:`~ctmm.control.Feedback` loops: every verb, both domains -- :func:`ctmm.simulate` in time, with
delays, saturation and co-simulated controllers; its frequency responses on exact beam fields with
``fields="exact"``), :mod:`~ctmm.manipulator.compiled` (the same scene through generated kernels,
returning :class:`ManipulatorSimulation`).  Derivations and numbers: ``docs/manipulator.md``.
"""
from .laws import HubPD, PZTFeedback
from .results import ManipulatorSimulation
from .scene import manipulator_plant, manipulator_scene, scene_references
from .parameters import (PZT_5A, PZT_5H, SEED_KD, SEED_KP, SEED_MOVE, SEED_PZT_GAIN, Arm, CycloidalMove, Hub,
                         Manipulator, PiezoMaterial, PZTPatch, moment_per_volt, seed_manipulator)

__all__ = ["Arm", "Hub", "PiezoMaterial", "PZT_5A", "PZT_5H", "PZTPatch", "Manipulator", "moment_per_volt",
           "CycloidalMove", "seed_manipulator", "SEED_KP", "SEED_KD", "SEED_PZT_GAIN", "SEED_MOVE", "HubPD", "PZTFeedback",
           "ManipulatorSimulation", "manipulator_plant", "manipulator_scene",
           "scene_references"]
