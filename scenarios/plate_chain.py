"""Rigid bodies carrying an equivalent flexible plate (seed 001 §9.2, Example 9.2, Figs. 9.5-9.7b).

Example 9.2 replaces Example 9.1's particle-spring net by an "equivalent flexible plate" with five rows
and columns of nodes (Fig. 9.6).  The seed's parameters were lost; this scenario chooses its own (SI),
with the chain of ``particle_net``: four uniform rigid links (bodies 1, 3, 4, 5; length 0.4 m, masses
1.0, 0.8, 0.6, 0.5 kg, smooth hinges, the first on a ground pivot), released at rest swung out 0.5 rad
from hanging, gravity ``(0, -9.81)``, no damping.  The plate, 0.5 m x 0.4 m, 5 mm thick, rho = 1000
kg/m^3 (1 kg), E = 10 MPa, nu = 0.3 (a stiff rubber sheet: lowest in-plane frequency clamped ~ 150
rad/s, of the order of the net's), is welded along its edge ``x = 0`` (a rigid bar across the tip
of body 5, perpendicular to the link) and meshed by 5 x 4 plane-stress quadrilaterals
(:class:`ctmm.fem.MembraneElement`); its 25 free nodes are numbered 1..25 column by column from body 5
(node ``k`` at ``x = 0.1 (1 + (k - 1) // 5)``, ``y = 0.1 ((k - 1) % 5 - 2)`` in body 5's axes, as the
particles of ``particle_net``); the seed's nodes 2, 17, 24 are plotted.

**Planar projection.**  The planar core moves everything in one plane, so the plate is the plate
*in its own plane*: membrane (plane-stress) stiffness and in-plane inertia; its out-of-plane bending
and the rotary inertia of its thickness are not part of a planar motion and are not modelled.

The plate is a :class:`ctmm.fem.FiniteElementModel` turned into a :class:`ctmm.fem.GlobalSubsystem`
(frame at the middle node of the welded edge, the other edge nodes held in the frame), welded to body
5 with :class:`ctmm.planar.elements.FixedMounting`; the one articulated sweep condenses it onto body 5.
Independent reference: the global Lagrange model of :mod:`ctmm.reference.mixed_global`
(:class:`~ctmm.reference.mixed_global.MembranePlate`: its own bilinear interpolation, mass at Gauss
points, stiffness from the strain energy), integrated with the same RK4 step; the total mechanical
energy of the undamped run is the physical check (seed Fig. 9.5h).
"""
from __future__ import annotations

from pathlib import Path

import numpy as np

from ctmm.fem import FiniteElementModel, MembraneElement
from ctmm.planar import PlanarModel, Pinned, RigidBody, SmoothHinge
from ctmm.planar.elements import FixedMounting
from ctmm.reference.mixed_global import GlobalChain, MembranePlate, RigidSegment
from ctmm.scenario import accuracy

from .mixed_common import same_step_run
from .planar_common import save_figure

NAME = "plate_chain"
DESCRIPTION = ("Rigid bodies carrying an equivalent flexible plate (seed 001 Example 9.2, Figs. 9.5-9.7b): plane-stress "
               "quadrilaterals as a global subsystem on the one sweep vs a global Lagrange model; energy")

MASSES = (1.0, 0.8, 0.6, 0.5)
LINK = 0.4
SPACING, COLUMNS, ROWS = 0.1, 5, 5
THICKNESS, DENSITY, YOUNG, POISSON = 0.005, 1000.0, 1.0e7, 0.3
STEP = 2.5e-4
INITIAL_ANGLE = -np.pi / 2 + 0.5
BOUND_SAME_INTEGRATOR = 1e-8
BODY_NAMES = ("body1", "body3", "body4", "body5")


def geometry() -> tuple[dict, list]:
    """Nodes ``{name: (x, y)}`` (body 5 axes, from its tip: edge nodes ``e0..e4``, then ``p1..p25``) and the
    quadrilaterals as node-name quadruples (counter-clockwise)."""
    def node(c: int, r: int) -> str:
        return f"e{r}" if c == 0 else f"p{(c - 1) * ROWS + r + 1}"
    nodes = {node(c, r): (SPACING * c, SPACING * (r - ROWS // 2)) for c in range(COLUMNS + 1) for r in range(ROWS)}
    quads = [(node(c, r), node(c + 1, r), node(c + 1, r + 1), node(c, r + 1))
             for c in range(COLUMNS) for r in range(ROWS - 1)]
    return nodes, quads


def plate_model() -> FiniteElementModel:
    """The plate as plane-stress quadrilaterals."""
    nodes, quads = geometry()
    return FiniteElementModel("plate", nodes, [MembraneElement(f"q{k}", quad, THICKNESS, YOUNG, POISSON, DENSITY)
                                               for k, quad in enumerate(quads)])


def model() -> PlanarModel:
    """Four links and the welded plate (module docstring)."""
    links = [RigidBody.uniform_link(name, mass=m, length=LINK) for name, m in zip(BODY_NAMES, MASSES)]
    items = [Pinned("base"), links[0]]
    for k, link in enumerate(links[1:]):
        items += [SmoothHinge(f"h{k + 2}"), link]
    hub = f"e{ROWS // 2}"
    plate = plate_model().subsystem("plate", boundary=(hub,),
                                    frame_nodes=tuple(f"e{r}" for r in range(ROWS) if r != ROWS // 2))
    return PlanarModel.chain(NAME, items + [FixedMounting("weld"), plate])


def reference() -> GlobalChain:
    """The same system as one global Lagrange model (coordinates: the four angles, then ``p1..p25`` ``[u_x, u_y]``)."""
    nodes, quads = geometry()
    names = list(nodes)
    plate = MembranePlate(tuple(map(tuple, nodes.values())), tuple(tuple(names.index(n) for n in q) for q in quads),
                          tuple(range(ROWS)), THICKNESS, YOUNG, POISSON, DENSITY)
    return GlobalChain([RigidSegment(LINK, m, m * LINK ** 2 / 12, LINK / 2) for m in MASSES] + [plate])


def reference_columns(names: tuple) -> list[int]:
    """Indices of the reference's coordinates in the mixed model's coordinate list."""
    return ([names.index(f"{b}.theta") for b in BODY_NAMES]
            + [names.index(f"plate.p{k}_{axis}") for k in range(1, COLUMNS * ROWS + 1) for axis in ("ux", "uy")])


def run(output_dir: Path, quick: bool = False) -> dict:
    import matplotlib
    matplotlib.use("Agg")
    import matplotlib.pyplot as plt

    t_final = 0.01 if quick else 1.0
    mixed, ref = model(), reference()
    names = mixed.coordinates
    order = reference_columns(names)
    q0 = np.zeros(mixed.n_coordinates)
    q0[[names.index(f"{b}.theta") for b in BODY_NAMES]] = INITIAL_ANGLE
    run_ = same_step_run(mixed, ref, q0, t_final, STEP, order)
    t, q, q_ref, every, energy, energy_ref = run_.time, run_.q, run_.q_ref, run_.every, run_.energy, run_.energy_ref
    nodes, _ = geometry()

    def node_global(k: int, row: np.ndarray) -> np.ndarray:
        """Global position [m] of free node ``k`` (1-based) at one reference-ordered state."""
        tip = ref.hinge_positions(row)[-1]
        th = row[3]
        R = np.array([[np.cos(th), -np.sin(th)], [np.sin(th), np.cos(th)]])
        return tip + R @ (np.asarray(nodes[f"p{k}"]) + row[4 + 2 * (k - 1):6 + 2 * (k - 1)])

    mine_rows = q[:, order]
    fig, axes = plt.subplots(2, 3, figsize=(15, 7.5))
    for i, body in enumerate(BODY_NAMES):
        axes[0, 0].plot(t, mine_rows[:, i], label=body)
        axes[0, 0].plot(t[::every * 4], q_ref[::every * 4, i], "kx")
    axes[0, 0].set(xlabel="t [s]", ylabel="rotation angle [rad]", title="bodies 1, 3, 4, 5 (Fig. 9.5a-d)")
    for k, ax in zip((2, 17, 24), (axes[0, 1], axes[0, 2], axes[1, 0])):
        mine = np.array([node_global(k, row) for row in mine_rows[::every]])
        theirs = np.array([node_global(k, row) for row in q_ref[::every * 4]])
        ax.plot(t[::every], mine[:, 0], label="x mixed")
        ax.plot(t[::every], mine[:, 1], label="y mixed")
        ax.plot(t[::every * 4], theirs[:, 0], "kx", t[::every * 4], theirs[:, 1], "kx")
        ax.set(xlabel="t [s]", ylabel="coordinate [m]", title=f"plate node {k} (Fig. 9.5e-g; x: global model)")
    axes[1, 1].plot(t[::every], energy - energy[0], label="mixed (RK4)")
    axes[1, 1].plot(t[::every], energy_ref - energy_ref[0], "k--", label="global model (RK4)")
    axes[1, 1].set(xlabel="t [s]", ylabel="E(t) - E(0) [J]",
                   title=f"total mechanical energy, E(0) = {energy[0]:.4g} J (Fig. 9.5h)")
    last = mine_rows[-1]
    hinges = ref.hinge_positions(last)
    plate = np.array([node_global(k, last) for k in range(1, COLUMNS * ROWS + 1)])
    axes[1, 2].plot(hinges[:, 0], hinges[:, 1], "o-k")
    axes[1, 2].plot(plate[:, 0], plate[:, 1], ".")
    axes[1, 2].set(xlabel="x [m]", ylabel="y [m]", title=f"positions at t = {t[-1]:g} s (Fig. 9.7b)", aspect="equal")
    for ax in axes.flat[:5]:
        ax.legend(fontsize="small")
    save_figure(fig, output_dir, NAME)
    same = f"same RK4 step h = {STEP * 1e3:g} ms, global Lagrange model of ctmm.reference.mixed_global"
    displacement = q[:, [i for i, c in enumerate(names) if c.startswith("plate.p")]]
    return {
        "accuracy": [accuracy("coordinates vs global model, same integrator", run_.error, "rad or m", BOUND_SAME_INTEGRATOR,
                              f"max over t and all coordinates (angles, plate node displacements) of "
                              f"|q_TMM - q_global|, {same}",
                              source="issue 16: mixed model vs global reference to 1e-8 with the same integrator")],
        "energy_drift_relative": run_.energy_drift,
        "energy_drift_definition": "(max - min) / max |E| of the kinetic + gravity + strain energy of the mixed run "
                                   "(model.energy; undamped: RK4 error only)",
        "energy_vs_global_model_relative": run_.energy_error,
        "largest_node_displacement_m": float(np.max(np.abs(displacement))),
        "lowest_clamped_plate_frequency_rad_s": float(plate_model().natural_frequencies(
            clamped=[f"e{r}" for r in range(ROWS)])[0]),
        "wall_time_s": run_.wall_time_s,
        "parameters": {"masses_kg": MASSES, "link_length_m": LINK, "spacing_m": SPACING, "columns": COLUMNS,
                       "rows": ROWS, "thickness_m": THICKNESS, "density_kg_m3": DENSITY, "youngs_modulus_Pa": YOUNG,
                       "poisson_ratio": POISSON, "step_s": STEP, "t_final_s": t_final,
                       "initial_angles_rad": INITIAL_ANGLE},
    }
