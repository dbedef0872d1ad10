"""Shared pieces of the spatial scenarios: the independent global Newton–Euler reference
(``ctmm/reference/spatial_tree.py``) of a ``SpatialModel``, state conversion, and the accuracy figure."""
from __future__ import annotations

import time
from typing import Any

import numpy as np

import ctmm
import ctmm.spatial as sp
from ctmm.codegen import find_compiler
from ctmm.errors import ModelError
from ctmm.reference import spatial_tree as ref
from ctmm.reference.spatial_kinematics import orientations
from ctmm.scenario import accuracy

STATE_BOUND = 1e-6   # [rad/s]: RK4 at the scenario step against the reference at a finer step


def generated_rk4() -> bool:
    """Whether the spatial scenarios' fixed-step RK4 runs take the generated RK4 (``ctmm.simulate(...,
    compiled=True)``): where a C compiler is present.  It is the numpy RK4 to round-off (the contract of the
    generated paths: tests/test_spatial_compiled*.py, tests/test_spatial_beam_body_actuators.py) and, on these runs
    of a few hundred to a few thousand steps, 10-40x cheaper with a cached kernel (first compile ~1-2 s CPU at -O0);
    ``ctmm.simulate``'s own default waits for 5000 steps (:mod:`ctmm.compiled_default`)."""
    try:
        find_compiler()
    except ModelError:
        return False
    return True


def reference_tree(model: sp.SpatialModel) -> ref.SpatialTree:
    """The global Newton–Euler description of a ``SpatialModel`` of rigid bodies on spherical, revolute
    and universal joints without joint laws (the scenarios use only these)."""
    bodies = []
    for j, (body, joint) in enumerate(zip(model.bodies, model.joints)):
        if joint.kind not in ("spherical", "revolute", "universal") or np.any(getattr(joint, "stiffness", 0.0)) \
                or np.any(getattr(joint, "damping", 0.0)) or getattr(joint, "actuated", False) \
                or getattr(joint, "position", None) is not None or getattr(joint, "law", None) is not None:
            raise ValueError(f"reference_tree: joint {joint.name!r} ({joint.kind}) has a law, an input or a driven "
                             "motion, which this converter does not carry: write the reference for it")
        parent = model.parent[j]
        position = joint.point if parent < 0 else model.bodies[parent].points[joint.point]
        axes = {"revolute": [getattr(joint, "axis", None)], "universal": [getattr(joint, "axis1", None),
                                                                          getattr(joint, "axis2", None)]}
        axes = np.array(axes.get(joint.kind, np.zeros((0, 3))), dtype=float)
        bodies.append(ref.SpatialBody(body.name, parent, joint.kind, body.mass, body.center_of_mass, body.inertia,
                                      axes=axes, joint_position=np.asarray(position, float),
                                      joint_rotation=joint.rotation))
    return ref.SpatialTree(tuple(bodies), gravity=model.gravity)


def to_reference(model: sp.SpatialModel, q: np.ndarray) -> np.ndarray:
    """Rows of ``q`` (ctmm layout, quaternions scalar first) in the reference layout (scalar last)."""
    q = np.atleast_2d(q)
    columns = []
    for joint, layout in zip(model.joints, model.layout):
        qj = q[:, layout.position]
        columns.append(np.c_[qj[:, 1:], qj[:, :1]] if joint.kind == "spherical" else qj)
    return np.concatenate(columns, axis=1)


def states(model: sp.SpatialModel, result: Any) -> tuple[np.ndarray, np.ndarray]:
    """``(q, v)`` histories (samples x coordinates) of a ``ctmm.simulate`` run."""
    return (np.array([result[name] for name in model.coordinates]).T,
            np.array([result[name] for name in model.velocities]).T)


def world_angular_velocity(tree: ref.SpatialTree, q_reference: np.ndarray, v: np.ndarray) -> np.ndarray:
    """Angular velocities of every body in world axes [rad/s], (samples, bodies, 3) (the reference's
    rotations and angular velocities only, without positions, accelerations or Jacobians)."""
    return np.array([orientations(tree, qk, vk).omega for qk, vk in zip(q_reference, v)])


def run_against_reference(model: sp.SpatialModel, q0: np.ndarray, v0: np.ndarray, t_final: float,
                          dt: float, refinement: int = 4) -> dict:
    """ctmm RK4 (step ``dt`` [s]) and DOP853 (rtol = atol = 1e-10) runs against the reference RK4 at
    ``dt / refinement``.

    Returns the runs, the reference trajectory (on the ``dt`` grid), the world angular velocities of
    all three [rad/s], the largest peak-to-peak reference angular velocity ``omega_range`` [rad/s] and
    the wall times [s]."""
    tree = reference_tree(model)
    start = time.perf_counter()
    reference = ref.simulate(tree, to_reference(model, q0)[0], v0, t_final, dt / refinement,
                              store_every=refinement)
    reference_time = time.perf_counter() - start
    rk4 = ctmm.simulate(model, t_final, dt, x0=q0, v0=v0, compiled=generated_rk4())
    start = time.perf_counter()
    dop = ctmm.simulate(model, t_final, dt, method="DOP853", x0=q0, v0=v0, rtol=1e-10, atol=1e-10)
    dop_time = time.perf_counter() - start
    out = {"refinement": refinement, "tree": tree, "reference": reference, "rk4": rk4, "dop853": dop,
           "reference_wall_time_s": reference_time,
           "rk4_wall_time_s": rk4.info["wall_time_s"], "dop853_wall_time_s": dop_time,
           "omega_reference": world_angular_velocity(tree, reference.q, reference.v)}
    for key, run in (("rk4", rk4), ("dop853", dop)):
        q, v = states(model, run)
        out[f"omega_{key}"] = world_angular_velocity(tree, to_reference(model, q), v)
        out[f"{key}_velocity_error"] = float(np.abs(v - reference.v).max())
    out["omega_range"] = float(np.ptp(out["omega_reference"], axis=0).max())
    return out


def omega_accuracy(runs: dict, body: int, label: str) -> list[dict]:
    """Accuracy figures: world angular velocity of ``body`` by ctmm RK4 and DOP853 against the reference."""
    figures = []
    for key, name in (("rk4", "RK4"), ("dop853", "DOP853 1e-10")):
        error = float(np.abs(runs[f"omega_{key}"][:, body] - runs["omega_reference"][:, body]).max())
        figures.append(accuracy(f"{label} angular velocity error, ctmm {name} vs Newton-Euler", error, "rad/s",
                                STATE_BOUND, f"max over t and x, y, z of |omega_ctmm - omega_ref| (world axes) of "
                                f"{label}; reference: global Newton-Euler (ctmm/reference/spatial_tree.py) RK4 at "
                                f"step / {runs['refinement']}",
                                source="ours: the planar RK4 target 1e-6 (docs/planar.md) "
                                "carried to rad/s"))
    return figures


def scenario_summary(runs: dict, body: int, label: str, parameters: dict) -> dict:
    """The JSON summary of a spatial time scenario: accuracy of ``body``'s angular velocity, state
    errors [rad/s], motion range [rad/s], wall times [s] and the parameters."""
    return {
        "accuracy": omega_accuracy(runs, body, label),
        "velocity_max_error_rk4": runs["rk4_velocity_error"],
        "velocity_max_error_dop853": runs["dop853_velocity_error"],
        "omega_range_rad_s": runs["omega_range"],
        "wall_time_s": runs["rk4_wall_time_s"],
        "rk4_method": str(runs["rk4"].info["method"]),
        "dop853_wall_time_s": runs["dop853_wall_time_s"],
        "reference_wall_time_s": runs["reference_wall_time_s"],
        "reference_step_s": float(runs["reference"].time[1] - runs["reference"].time[0]) / runs["refinement"],
        "parameters": parameters,
    }


def scenario_runs(model: sp.SpatialModel, q0: np.ndarray, v0: np.ndarray, quick: bool,
                  t_final_full: float = 2.0) -> dict:
    """:func:`run_against_reference` over ``t_final_full`` [s] at 1 ms with the reference at a quarter step
    (quick: 0.25 s, the reference at half the step); also records ``t_final`` and ``dt`` [s]."""
    t_final, dt, refinement = (0.25, 1e-3, 2) if quick else (t_final_full, 1e-3, 4)
    runs = run_against_reference(model, q0, v0, t_final, dt, refinement)
    runs.update(t_final=t_final, dt=dt)
    return runs
