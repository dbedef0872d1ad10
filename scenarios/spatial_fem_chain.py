"""Spatial chain of rigid bodies with a finite-element beam (issue 16 item 1, spatial counterpart of seed 001
§9.3's chain with an FE beam): mixed MSTMM at d = 6.

Own parameters (all SI), gravity ``(0, 0, -9.81)``:

* body 1 (1.5 kg, a column: centre ``(0, 0, 0.15)``, tip ``(0, 0, 0.3)``) on a yaw joint about ``z`` at
  the origin; body 2 (0.8 kg, an arm: centre ``(0.15, 0, 0)``, tip ``(0.3, 0, 0)``) on a pitch joint about
  ``y`` at body 1's tip;
* beam 1: 1.0 m along its frame's ``x``, three 12-DOF Euler-Bernoulli elements (nodes n0-n3), ``EA = 5e3 N``,
  ``GJ = 15 N m^2``, ``EI_y = 36 N m^2``, ``EI_z = 60 N m^2``, ``rhoA = 0.6 kg/m``, ``rho I_p = 4e-3 kg m``,
  Rayleigh ``C = 2e-4 K``, a 0.1 kg point mass with inertia at node n2; its floating frame at n0 (the
  connected point), on a revolute joint about body 2's ``z`` at body 2's tip;
* body 3 (0.4 kg, a pendulum: centre ``(0, 0, -0.12)``) on a revolute joint about the ``y`` of the frame
  of node n3 (the frame follows that node's displacement and rotation);
* released with pitch 0.3 rad, beam joint 0.5 rad, the others 0, and a yaw rate of 1.5 rad/s; over the
  0.6 s run the nodes move by up to 19 mm (2 % of the beam's length) (inside the small deformation of the
  floating frame: no ``SmallDeformationWarning``).

The beam is a :class:`ctmm.fem.SpatialSubsystem` (``docs/mixed.md`` §7): its 18 internal DOFs eliminated
exactly by the one articulated sweep.  Outputs: the connected point (world), the displacements of nodes
n1-n3 (frame axes), the joint angles ("azimuths") of bodies 1-3, the interaction force of beam 1 on body 3.

Independent reference: :mod:`ctmm.reference.spatial_fe_global` (one global model in minimal coordinates,
its own FE interpolation and inertia), integrated with the same RK4 step (the coupling to round-off);
the implicit DT-TMM Newmark run is compared with the reference at half the step.
"""
from __future__ import annotations

import time
from pathlib import Path

import numpy as np

import ctmm
import ctmm.spatial as sp
from ctmm.fem import SpatialBeamElement, SpatialFiniteElementModel, SpatialPointMass
from ctmm.reference.spatial_fe_global import FEFrame, FrameBeam, FrameMass, Link, SpatialFEChain
from ctmm.scenario import accuracy

from .planar_common import save_figure

NAME = "spatial_fem_chain"
DESCRIPTION = ("Spatial chain of rigid bodies with a 12-DOF finite-element beam (issue 16): mixed MSTMM at d = 6 "
               "(FE subsystem on the one sweep) + RK4 / Newmark vs a global model in minimal coordinates")

BODIES = {"body1": dict(mass=1.5, inertia=(0.02, 0.02, 0.005), center=(0.0, 0.0, 0.15)),
          "body2": dict(mass=0.8, inertia=(0.001, 0.008, 0.008), center=(0.15, 0.0, 0.0)),
          "body3": dict(mass=0.4, inertia=(0.002, 0.002, 0.0005), center=(0.0, 0.0, -0.12))}
BEAM = dict(length=1.0, elements=3, axial=5.0e3, torsional=15.0, bending_y=36.0, bending_z=60.0, mass_per_length=0.6,
            polar_inertia_per_length=4.0e-3)
NODE_MASS = dict(node="n2", mass=0.1, inertia=(2e-4, 3e-4, 3e-4))
RAYLEIGH = (0.0, 2.0e-4)
STEP = 5.0e-4
INITIAL = {"pitch.angle": 0.3, "connection.angle": 0.5}
INITIAL_RATE = {"yaw.angle_rate": 1.5}
BOUND_SAME_INTEGRATOR = 1e-8
BOUND_FORCE = 1e-8


def _nodes() -> dict:
    b = BEAM
    return {f"n{k}": (k * b["length"] / b["elements"], 0.0, 0.0) for k in range(b["elements"] + 1)}


def beam_subsystem():
    """The finite-element beam ``beam1`` (3 elements, a node mass at ``n2``, Rayleigh damping) as a body with the
    boundary nodes ``n0`` (inboard) and the tip node (named by the scene file ``files/spatial_fem_chain.toml``)."""
    b, tip = BEAM, f"n{BEAM['elements']}"
    elements = [SpatialBeamElement(f"e{k}", f"n{k}", f"n{k + 1}", b["axial"], b["torsional"], b["bending_y"],
                                   b["bending_z"], b["mass_per_length"], b["polar_inertia_per_length"])
                for k in range(b["elements"])]
    elements.append(SpatialPointMass("node_mass", NODE_MASS["node"], NODE_MASS["mass"], NODE_MASS["inertia"]))
    return SpatialFiniteElementModel("beam1", _nodes(), elements, rayleigh=RAYLEIGH).subsystem("beam1", ("n0", tip))


def model() -> sp.SpatialModel:
    """The mixed model (module docstring)."""
    tip = f"n{BEAM['elements']}"
    beam = beam_subsystem()
    body = {name: sp.SpatialBody(name, p["mass"], np.diag(p["inertia"]), center_of_mass=p["center"],
                                 points=({"tip": (0.0, 0.0, 0.3)} if name == "body1" else
                                         {"tip": (0.3, 0.0, 0.0)} if name == "body2" else {}))
            for name, p in BODIES.items()}
    return sp.SpatialModel(NAME, [
        body["body1"], sp.Revolute(name="yaw", parent=None, child="body1", axis=(0, 0, 1)),
        body["body2"], sp.Revolute(name="pitch", parent="body1", point="tip", child="body2", axis=(0, 1, 0)),
        beam, sp.Revolute(name="connection", parent="body2", point="tip", child="beam1", axis=(0, 0, 1)),
        body["body3"], sp.Revolute(name="hinge", parent="beam1", point=tip, child="body3", axis=(0, 1, 0)),
    ], gravity=(0.0, 0.0, -9.81))


def reference() -> SpatialFEChain:
    """The independent global model of the same chain (y' of every element: the frame's y)."""
    b = BEAM
    beams = [FrameBeam(f"n{k}", f"n{k + 1}", b["axial"], b["torsional"], b["bending_y"], b["bending_z"],
                       b["mass_per_length"], b["polar_inertia_per_length"], (0.0, 1.0, 0.0)) for k in range(b["elements"])]
    link = {name: (p["mass"], np.diag(p["inertia"]), p["center"]) for name, p in BODIES.items()}
    return SpatialFEChain([
        Link(*link["body1"], axis=(0, 0, 1), point=(0.0, 0.0, 0.0)),
        Link(*link["body2"], axis=(0, 1, 0), point=(0.0, 0.0, 0.3)),
        FEFrame(_nodes(), "n0", beams, [FrameMass(NODE_MASS["node"], NODE_MASS["mass"], np.diag(NODE_MASS["inertia"]))],
                axis=(0, 0, 1), point=(0.3, 0.0, 0.0), stiffness_damping=RAYLEIGH[1]),
        Link(*link["body3"], axis=(0, 1, 0), point=f"n{b['elements']}"),
    ], gravity=(0.0, 0.0, -9.81))


def run(output_dir: Path, quick: bool = False, results: dict | None = None) -> dict:
    import matplotlib
    matplotlib.use("Agg")
    import matplotlib.pyplot as plt

    t_final = 0.03 if quick else 0.6
    mixed, ref = model(), reference()
    names, rates = mixed.coordinates, mixed.velocities
    q0, v0 = np.zeros(mixed.n_positions), np.zeros(mixed.n_velocities)
    for key, value in INITIAL.items():
        q0[names.index(key)] = value
    for key, value in INITIAL_RATE.items():
        v0[rates.index(key)] = value
    rk4 = ctmm.simulate(mixed, t_final, STEP, method="rk4", x0=q0, v0=v0)
    newmark = ctmm.simulate(mixed, t_final, STEP, method="newmark", x0=q0, v0=v0)
    if results is not None:                      # ctmm run --save / --animate
        results.update(rk4=rk4, newmark=newmark)
    q = np.column_stack([rk4[c] for c in names])
    v = np.column_stack([rk4[c] for c in rates])
    q_nm = np.column_stack([newmark[c] for c in names])
    start = time.perf_counter()
    _, x_ref = ref.rk4(q0, v0, t_final, STEP)
    reference_time = time.perf_counter() - start
    _, x_fine = ref.rk4(q0, v0, t_final, STEP / 2)
    q_ref, v_ref, q_fine = x_ref[:, :ref.n], x_ref[:, ref.n:], x_fine[::2, :ref.n]
    error_same = float(np.max(np.abs(q - q_ref)))
    error_newmark = float(np.max(np.abs(q_nm - q_fine)))
    error_rk4_fine = float(np.max(np.abs(q - q_fine)))
    samples = np.arange(0, rk4.time.size, max(1, rk4.time.size // 100))
    body3 = mixed.body_index("body3")
    force = np.array([sp.reactions(mixed, q[k], v[k])[body3, :3] for k in samples])
    force_ref = np.array([ref.interaction_force(q_ref[k], v_ref[k]) for k in samples])
    error_force = float(np.max(np.abs(force - force_ref)) / np.max(np.abs(force_ref)))
    connected = np.column_stack([rk4[f"beam1.position_{a}"] for a in "xyz"])
    connected_ref = np.array([ref.kinematics(qk)["frame"][1] for qk in q_ref])
    error_connected = float(np.max(np.abs(connected - connected_ref)))
    translations = [names.index(c) for c in names if c.startswith("beam1.") and c[-2] == "u"]
    largest = float(np.max(np.abs(q[:, translations])))

    fig, axes = plt.subplots(2, 3, figsize=(15, 7.5))
    t = rk4.time
    for a, label in enumerate("xyz"):
        axes[0, 0].plot(t, connected[:, a], label=f"{label} mixed MSTMM + RK4")
        axes[0, 0].plot(t[::40], connected_ref[::40, a], "kx")
    axes[0, 0].set(xlabel="t [s]", ylabel="[m]", title="connected point (beam node n0, world)")
    for k in (1, 2, 3):
        for component, style in (("uy", "-"), ("uz", "--")):
            i = names.index(f"beam1.n{k}_{component}")
            axes[0, 1].plot(t, q[:, i] * 1e3, style, label=f"n{k} {component}")
    axes[0, 1].set(xlabel="t [s]", ylabel="[mm]", title="beam nodes n1-n3, frame axes")
    for joint in ("yaw", "pitch", "connection", "hinge"):
        i = names.index(f"{joint}.angle")
        axes[0, 2].plot(t, q[:, i], label=joint)
        axes[0, 2].plot(t[::40], q_ref[::40, i], "kx")
    axes[0, 2].set(xlabel="t [s]", ylabel="[rad]", title="joint angles (x: global model)")
    for a, label in enumerate("xyz"):
        axes[1, 0].plot(t[samples], force[:, a], label=f"F_{label} mixed")
        axes[1, 0].plot(t[samples][::4], force_ref[::4, a], "kx")
    axes[1, 0].set(xlabel="t [s]", ylabel="[N]", title="interaction force beam 1 -> body 3 (world)")
    axes[1, 1].semilogy(t, np.max(np.abs(q - q_ref), axis=1) + 1e-17, label="RK4 vs global RK4 (same step)")
    axes[1, 1].semilogy(t, np.max(np.abs(q_nm - q_fine), axis=1) + 1e-17, label="Newmark DT-TMM vs global (h/2)")
    axes[1, 1].set(xlabel="t [s]", ylabel="max coordinate error", title=f"h = {STEP * 1e3:g} ms")
    axes[1, 2].plot(t, np.max(np.abs(q[:, translations]), axis=1) * 1e3)
    axes[1, 2].set(xlabel="t [s]", ylabel="[mm]", title="largest node displacement (frame axes)")
    for ax in axes.flat[:5]:
        ax.legend(fontsize="small")
    save_figure(fig, output_dir, NAME)
    same = f"same RK4 step h = {STEP * 1e3:g} ms, global model of ctmm.reference.spatial_fe_global"
    return {
        "accuracy": [
            accuracy("coordinates vs global model, same integrator", error_same, "rad or m", BOUND_SAME_INTEGRATOR,
                     f"max over t and all coordinates (joint angles, FE node displacements and rotations) of "
                     f"|q_TMM - q_global|, {same}",
                     source="issue 16: mixed model vs its independent global reference, as fem_chain"),
            accuracy("interaction force vs global model", error_force, "relative", BOUND_FORCE,
                     f"max |F_TMM - F_global| / max |F_global| of the force of beam 1 on body 3 (world), {same}; "
                     "F_global = m_3 (a_3 - g)", source="issue 16: interaction force as in fem_chain"),
        ],
        "connected_point_error_m": error_connected,
        "largest_node_displacement_m": largest,
        "rk4_error_vs_reference_half_step": error_rk4_fine,
        "newmark_error_vs_reference_half_step": error_newmark,
        "newmark_iterations_mean": float(np.mean(newmark.info["iterations"])),
        "wall_time_s": rk4.info["wall_time_s"],
        "newmark_wall_time_s": newmark.info["wall_time_s"],
        "reference_rk4_wall_time_s": reference_time,
        "parameters": {"bodies": BODIES, "beam": BEAM, "node_mass": NODE_MASS, "rayleigh": RAYLEIGH, "step_s": STEP,
                       "t_final_s": t_final, "initial": INITIAL, "initial_rate": INITIAL_RATE},
    }
