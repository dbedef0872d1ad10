"""Rigid bodies carrying a reticulated particle-spring net (seed 001 §9.2, Example 9.1, Figs. 9.1-9.4).

The seed's parameters were lost; this scenario chooses its own (all SI): a chain of four uniform rigid
links (bodies 1, 3, 4, 5 as in Fig. 9.4; length 0.4 m, masses 1.0, 0.8, 0.6, 0.5 kg, smooth hinges, the
first on a ground pivot) with a 5 x 5 net of particles (0.04 kg each, spacing 0.1 m) welded to the tip
of body 5: the net's frame is body 5's, its first column hangs 0.1 m beyond the tip, the middle
particle of that column is tied to the tip and its two neighbours to anchors on the body (0.05 m to
either side).  Springs (exact: rest length = undeformed distance, force along the current line) join
horizontal and vertical neighbours (800 N/m) and diagonal ones (300 N/m); no damping, gravity
``(0, -9.81)``.  Released at rest with the links swung out 0.5 rad from hanging.  Particles are
numbered 1..25 column by column from body 5 (particle ``k`` at column ``(k - 1) // 5``, row
``(k - 1) % 5``); the seed's particles 2, 17 and 24 are plotted.

The net is a :class:`ctmm.fem.GlobalSubsystem` (lumped masses, ``K = 0``, its springs written exactly
in ``nonlinear_force`` in the frame: exact at any deformation, ``docs/mixed.md``), welded to body 5
(:class:`ctmm.planar.elements.FixedMounting`); the one articulated sweep condenses it onto body 5.
Independent reference: the global Lagrange model of :mod:`ctmm.reference.mixed_global`
(:class:`~ctmm.reference.mixed_global.ParticleNet`: springs from the particles' global positions),
integrated with the same RK4 step; the total mechanical energy of the undamped run is the physical
check (seed Fig. 9.4h).
"""
from __future__ import annotations

from pathlib import Path

import numpy as np

from ctmm.fem import GlobalSubsystem
from ctmm.planar import PlanarModel
from ctmm.reference.mixed_global import GlobalChain, ParticleNet, RigidSegment
from ctmm.scene_files import load_scene

from .mixed_common import (coordinates_accuracy, largest_net_displacement, particle_positions, plot_energy,
                           plot_rotations, same_step_run)
from .planar_common import save_figure

NAME = "particle_net"
DESCRIPTION = ("Rigid bodies carrying a 5 x 5 particle-spring net (seed 001 Example 9.1, Figs. 9.1-9.4): the net as a "
               "global subsystem on the one sweep vs a global Lagrange model; energy")

MASSES = (1.0, 0.8, 0.6, 0.5)
LINK = 0.4
SPACING, GRID, PARTICLE = 0.1, 5, 0.04
AXIAL, DIAGONAL = 800.0, 300.0
STEP = 5e-4
INITIAL_ANGLE = -np.pi / 2 + 0.5
BOUND_SAME_INTEGRATOR = 1e-8
BODY_NAMES = ("body1", "body3", "body4", "body5")


def geometry():
    """Particle positions (body 5 axes, from its tip), anchors and springs ``(a, b, k)``: ``a, b`` particle
    indices (0-based) or anchor points."""
    positions = np.array([[SPACING * (1 + c), SPACING * (r - GRID // 2)] for c in range(GRID) for r in range(GRID)])
    index = {(c, r): c * GRID + r for c in range(GRID) for r in range(GRID)}
    springs = []
    for (c, r), i in index.items():
        for dc, dr, k in ((1, 0, AXIAL), (0, 1, AXIAL), (1, 1, DIAGONAL), (1, -1, DIAGONAL)):
            j = index.get((c + dc, r + dr))
            if j is not None:
                springs.append((i, j, k))
    middle = GRID // 2
    springs += [((0.0, 0.0), index[(0, middle)], AXIAL), ((0.0, 0.05), index[(0, middle + 1)], AXIAL),
                ((0.0, -0.05), index[(0, middle - 1)], AXIAL)]
    return positions, springs


def net_subsystem() -> GlobalSubsystem:
    """The net as user matrices: lumped masses, K = 0, exact springs in ``nonlinear_force`` (frame axes).
    The hub (the frame node, at body 5's tip) and the other anchors are held in the frame."""
    positions, springs = geometry()
    anchors = sorted({a for a, _, _ in springs if not isinstance(a, int)} - {(0.0, 0.0)})
    nodes = {"hub": ((0.0, 0.0), (0, 1))}
    nodes.update({f"anchor{k}": (a, (2 + 2 * k, 3 + 2 * k)) for k, a in enumerate(anchors)})
    first = 2 + 2 * len(anchors)
    nodes.update({f"p{i + 1}": (tuple(p), (first + 2 * i, first + 2 * i + 1)) for i, p in enumerate(positions)})
    n = first + 2 * len(positions)
    M = np.zeros((n, n))
    M[first:, first:] = PARTICLE * np.eye(n - first)
    node_of = {a: f"anchor{k}" for k, a in enumerate(anchors)} | {(0.0, 0.0): "hub"}
    pairs = [(f"p{a + 1}" if isinstance(a, int) else node_of[a], f"p{b + 1}", k) for a, b, k in springs]
    position = {name: np.asarray(xy, float) for name, (xy, _) in nodes.items()}
    dofs = {name: list(d) for name, (_, d) in nodes.items()}
    a_idx = np.array([dofs[a] for a, _, _ in pairs])
    b_idx = np.array([dofs[b] for _, b, _ in pairs])
    stiffness = np.array([k for _, _, k in pairs])
    offset = np.array([position[b] - position[a] for a, b, _ in pairs])
    rest = np.linalg.norm(offset, axis=1)

    def spring_energy(u):
        d = offset + u[b_idx] - u[a_idx]
        return float(0.5 * np.sum(stiffness * (np.sqrt((d * d).sum(1)) - rest) ** 2))

    def spring_forces(u, u_dot, t):
        d = offset + u[b_idx] - u[a_idx]                                # (S, 2), complex-safe
        length = np.sqrt((d * d).sum(1))
        force = -(stiffness * (length - rest) / length)[:, None] * d    # on end b
        f = np.zeros_like(u)
        np.add.at(f, b_idx, force)
        np.add.at(f, a_idx, -force)
        return f

    return GlobalSubsystem("net", mass_matrix=M, damping_matrix=np.zeros((n, n)), stiffness_matrix=np.zeros((n, n)),
                           nodes=nodes, boundary=("hub",), frame_nodes=tuple(f"anchor{k}" for k in range(len(anchors))),
                           nonlinear_force=spring_forces, potential=spring_energy)


def model() -> PlanarModel:
    """Four links and the welded net (module docstring), built from the scene file
    ``scenarios/files/particle_net.toml`` (it takes the net from :func:`net_subsystem`; :func:`reference` builds the
    global model from the constants above)."""
    return load_scene(Path(__file__).resolve().parent / "files" / "particle_net.toml").system


def reference() -> GlobalChain:
    """The same system as one global Lagrange model."""
    positions, springs = geometry()
    return GlobalChain([RigidSegment(LINK, m, m * LINK ** 2 / 12, LINK / 2) for m in MASSES]
                       + [ParticleNet(tuple(map(tuple, positions)), (PARTICLE,) * len(positions), tuple(springs))])


def run(output_dir: Path, quick: bool = False) -> dict:
    import matplotlib
    matplotlib.use("Agg")
    import matplotlib.pyplot as plt

    t_final = 0.05 if quick else 1.0
    mixed, ref = model(), reference()
    names = mixed.coordinates
    q0 = np.zeros(mixed.n_coordinates)
    q0[[names.index(f"{b}.theta") for b in BODY_NAMES]] = INITIAL_ANGLE
    run_ = same_step_run(mixed, ref, q0, t_final, STEP)
    q, q_ref, every, energy = run_.q, run_.q_ref, run_.every, run_.energy
    error, energy_error, drift = run_.error, run_.energy_error, run_.energy_drift
    positions, _ = geometry()
    particles = {f"p{k + 1}": xy for k, xy in enumerate(positions)}

    def particle_global(k: int, history: np.ndarray) -> np.ndarray:
        """Global position of particle ``k`` (1-based) over the run, from the reference's kinematics."""
        return particle_positions(ref, history, names, "body5", -1, {f"p{k}": positions[k - 1]})[f"p{k}"]

    t = run_.time
    fig, axes = plt.subplots(2, 3, figsize=(15, 7.5))
    plot_rotations(axes[0, 0], run_, names, BODY_NAMES, lambda body: body)
    axes[0, 0].set(xlabel="t [s]", ylabel="rotation angle [rad]", title="bodies 1, 3, 4, 5 (Fig. 9.4a-d)")
    for k, ax in zip((2, 17, 24), (axes[0, 1], axes[0, 2], axes[1, 0])):
        mine = particle_global(k, q[::every])
        theirs = particle_global(k, q_ref[::every * 4])
        ax.plot(t[::every], mine[:, 0], label="x mixed")
        ax.plot(t[::every], mine[:, 1], label="y mixed")
        ax.plot(t[::every * 4], theirs[:, 0], "kx", t[::every * 4], theirs[:, 1], "kx")
        ax.set(xlabel="t [s]", ylabel="coordinate [m]", title=f"particle {k} (Fig. 9.4e-g)")
    plot_energy(axes[1, 1], run_, f"total mechanical energy, E(0) = {energy[0]:.4g} J (Fig. 9.4h)")
    last = q[-1]
    net = np.array([xy[0] for xy in particle_positions(ref, q[-1:], names, "body5", -1, particles).values()])
    hinges = ref.hinge_positions(last)
    axes[1, 2].plot(hinges[:, 0], hinges[:, 1], "o-k")
    axes[1, 2].plot(net[:, 0], net[:, 1], ".")
    axes[1, 2].set(xlabel="x [m]", ylabel="y [m]", title=f"positions at t = {t[-1]:g} s (Fig. 9.7a)", aspect="equal")
    for ax in axes.flat[:5]:
        ax.legend(fontsize="small")
    save_figure(fig, output_dir, NAME)
    return {
        "accuracy": [coordinates_accuracy(error, BOUND_SAME_INTEGRATOR, "angles, particle displacements", STEP,
                                          "issue 16 / task H5: mixed model vs global reference to 1e-8 with the same "
                                          "integrator")],
        "energy_drift_relative": drift,
        "energy_drift_definition": "(max - min) / max |E| of the kinetic + gravity + spring energy of the mixed run "
                                   "(model.energy with the net's spring potential; undamped: RK4 error only)",
        "energy_vs_global_model_relative": energy_error,
        "largest_particle_displacement_m": largest_net_displacement(q, names),
        "wall_time_s": run_.wall_time_s,
        "parameters": {"masses_kg": MASSES, "link_length_m": LINK, "spacing_m": SPACING, "grid": GRID,
                       "particle_mass_kg": PARTICLE, "axial_stiffness_N_per_m": AXIAL,
                       "diagonal_stiffness_N_per_m": DIAGONAL, "step_s": STEP, "t_final_s": t_final,
                       "initial_angles_rad": INITIAL_ANGLE},
    }
