"""A multi-rigid-flexible chain with a particle-spring subsystem between two rigid bodies (seed 001 §9.2,
Figs. 9.8-9.9).

What the seed keeps: Fig. 9.8 ("MRFS model") is lost; Fig. 9.9 plots, for the mixed method against the
Newton-Euler method, (a) the rotations of rigid bodies 2 and 6, (b) the coordinates of particles 2 and 3
and (c) of particles 4 and 5 -- a chain whose elements 2 and 6 are rigid bodies and 2-5 particles.  This
scenario builds such a system with its own parameters (SI): a ground pivot, rigid body 2 (uniform link
0.5 m, 1 kg), a particle-spring subsystem welded to its tip (particles 2, 3, 4, 5 of 0.2 kg at
``(0.15, 0.1), (0.15, -0.1), (0.3, 0.1), (0.35, 0)`` in body 2's axes from its tip; ten springs of
3000 N/m along their undeformed lines -- small deformation -- between the particles, the tip and two
anchors ``(0, +-0.1)`` on body 2) and rigid body 6 (uniform link 0.4 m, 0.5 kg) pinned to particle 5:
the subsystem sits *between* two transfer chains, so its boundary has an inboard side (body 2) and an
outboard one (particle 5, where body 6's hinge force is a boundary unknown).  Released at rest with
body 2 at 0.6 rad and body 6 at 1.0 rad from hanging, gravity ``(0, -9.81)``, no damping.

Mixed model: :class:`ctmm.fem.FiniteElementModel` (point masses, node springs) as a
:class:`ctmm.fem.GlobalSubsystem` with boundary ``("hub", "p5")``, welded to body 2
(:class:`ctmm.planar.elements.FixedMounting`), body 6 on a smooth hinge at ``p5``.  Reference (the
"Newton-Euler" curves): the global Lagrange model of :mod:`ctmm.reference.mixed_global`
(:class:`~ctmm.reference.mixed_global.ParticleNet` with ``linear=True, outboard=3``), same RK4 step.
"""
from __future__ import annotations

from pathlib import Path

import numpy as np

from ctmm.planar import PlanarModel
from ctmm.reference.mixed_global import GlobalChain, ParticleNet, RigidSegment
from ctmm.scene_files import load_scene

from .mixed_common import (coordinates_accuracy, largest_net_displacement, particle_positions, plot_energy,
                           plot_rotations, same_step_run)
from .planar_common import save_figure

NAME = "particle_chain"
DESCRIPTION = ("Rigid bodies 2 and 6 joined by a particle-spring subsystem (seed 001 §9.2, Figs. 9.8-9.9): the "
               "subsystem between two transfer chains on the one sweep vs a global Lagrange model")

BODY2, BODY6 = (0.5, 1.0), (0.4, 0.5)                     # (length [m], mass [kg])
PARTICLES = {"p2": (0.15, 0.1), "p3": (0.15, -0.1), "p4": (0.3, 0.1), "p5": (0.35, 0.0)}
ANCHORS = {"hub": (0.0, 0.0), "a_up": (0.0, 0.1), "a_down": (0.0, -0.1)}
SPRINGS = (("a_up", "p2"), ("a_down", "p3"), ("hub", "p2"), ("hub", "p3"), ("p2", "p3"), ("p2", "p4"),
           ("p3", "p4"), ("p3", "p5"), ("p4", "p5"), ("p2", "p5"))
PARTICLE_MASS, STIFFNESS = 0.2, 3000.0
STEP = 5e-4
INITIAL = (-np.pi / 2 + 0.6, -np.pi / 2 + 1.0)
BOUND_SAME_INTEGRATOR = 1e-8


def model() -> PlanarModel:
    """Body 2, the welded particle subsystem, body 6 pinned at particle 5, built from the scene file
    ``scenarios/files/particle_chain.toml`` (the one source of the TMM model; :func:`reference` builds the global
    model from the constants above)."""
    return load_scene(Path(__file__).resolve().parent / "files" / "particle_chain.toml").system


def reference() -> GlobalChain:
    """The same system as one global Lagrange model (coordinates as :func:`model`'s)."""
    names = list(PARTICLES)
    ends = {**{p: i for i, p in enumerate(names)}, **ANCHORS}
    net = ParticleNet(tuple(PARTICLES.values()), (PARTICLE_MASS,) * len(names),
                      tuple((ends[a], ends[b], STIFFNESS) for a, b in SPRINGS), linear=True, outboard=names.index("p5"))
    return GlobalChain([RigidSegment(BODY2[0], BODY2[1], BODY2[1] * BODY2[0] ** 2 / 12, BODY2[0] / 2), net,
                        RigidSegment(BODY6[0], BODY6[1], BODY6[1] * BODY6[0] ** 2 / 12, BODY6[0] / 2)])


def run(output_dir: Path, quick: bool = False) -> dict:
    import matplotlib
    matplotlib.use("Agg")
    import matplotlib.pyplot as plt

    t_final = 0.05 if quick else 2.0
    mixed, ref = model(), reference()
    names = mixed.coordinates
    q0 = np.zeros(mixed.n_coordinates)
    q0[[names.index("body2.theta"), names.index("body6.theta")]] = INITIAL
    run_ = same_step_run(mixed, ref, q0, t_final, STEP)
    t, q, q_ref, every = run_.time, run_.q, run_.q_ref, run_.every
    mine, theirs = (particle_positions(ref, history, names, "body2", 1, PARTICLES)
                    for history in (q[::every], q_ref[::every * 4]))
    fig, axes = plt.subplots(1, 4, figsize=(19, 4.5))
    plot_rotations(axes[0], run_, names, ("body2", "body6"), lambda body: f"{body} (mixed)")
    axes[0].set(xlabel="t [s]", ylabel="rotation [rad]", title="rigid bodies 2 and 6 (Fig. 9.9a; x: global model)")
    for ax, pair, label in ((axes[1], ("p2", "p3"), "b"), (axes[2], ("p4", "p5"), "c")):
        for p in pair:
            ax.plot(t[::every], mine[p][:, 0], label=f"{p} x")
            ax.plot(t[::every], mine[p][:, 1], label=f"{p} y")
            ax.plot(t[::every * 4], theirs[p][:, 0], "kx", t[::every * 4], theirs[p][:, 1], "kx")
        ax.set(xlabel="t [s]", ylabel="coordinate [m]", title=f"particles {pair[0][1]} and {pair[1][1]} (Fig. 9.9{label})")
    plot_energy(axes[3], run_, "total mechanical energy")
    for ax in axes:
        ax.legend(fontsize="x-small")
    save_figure(fig, output_dir, NAME)
    return {
        "accuracy": [coordinates_accuracy(run_.error, BOUND_SAME_INTEGRATOR, "angles, particle displacements", STEP,
                                          "issue 16: mixed model vs global reference to 1e-8 with the same integrator")],
        "energy_drift_relative": run_.energy_drift,
        "energy_vs_global_model_relative": run_.energy_error,
        "largest_particle_displacement_m": largest_net_displacement(q, names),
        "wall_time_s": run_.wall_time_s,
    }
