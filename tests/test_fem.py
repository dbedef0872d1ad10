"""ctmm.fem: beam elements against closed forms, assembly, refusals, a lumped global subsystem."""
from __future__ import annotations

import dataclasses
import re

import numpy as np
import pytest

from ctmm.errors import ModelError
from ctmm.fem import BeamElement, FiniteElementModel, GlobalSubsystem, NodeSpring, PointMass
from ctmm.planar import PlanarModel, Pinned, RigidBody, SmoothHinge
from ctmm.planar.elements import FixedMounting

EI, EA, RHO_A, LENGTH = 14.0, 3.0e4, 1.2, 2.0
CANTILEVER_BETA_L = np.array([1.8751040687119611, 4.6940911329741746, 7.8547574382376126])


def straight_beam(elements: int, *, axial_force: float = 0.0, length: float = LENGTH, **kwargs) -> FiniteElementModel:
    nodes = {f"n{k}": (k * length / elements, 0.0) for k in range(elements + 1)}
    return FiniteElementModel("beam", nodes, [BeamElement(f"e{k}", f"n{k}", f"n{k + 1}", EI, EA, RHO_A, axial_force)
                                              for k in range(elements)], **kwargs)


def test_cantilever_frequencies_converge_to_the_analytic_ones_at_fourth_order():
    exact = CANTILEVER_BETA_L ** 2 * np.sqrt(EI / (RHO_A * LENGTH ** 4))
    errors = []
    for elements in (4, 8, 16):
        omega = straight_beam(elements).natural_frequencies(clamped=["n0"])
        bending = np.array([w for w in omega if w < 1.2 * exact[-1]])[:3]      # axial modes are far above
        errors.append(np.abs(bending / exact - 1))
    errors = np.array(errors)
    assert np.all(errors[-1] < [3e-7, 1e-5, 1e-4])   # 1.3e-7, 5.1e-6, 4.0e-5
    rates = np.log2(errors[:-1, 0] / errors[1:, 0])
    assert np.all(rates > 3.8)                                  # consistent Hermite mass: O(h^4)


def test_clamped_frequencies_of_a_beam_compressed_above_euler_buckling_are_refused():
    """Above the Euler load ``pi^2 EI / 4 L^2`` of the fixed-free beam, K + K_G has a negative eigenvalue: no
    natural frequency exists (it used to be reported as 0 rad/s); below it the frequencies stay."""
    critical = np.pi ** 2 * EI / (4 * LENGTH ** 2)
    assert straight_beam(8, axial_force=-0.5 * critical).natural_frequencies(clamped=["n0"])[0] > 0.0
    with pytest.raises(ModelError, match=r"beam: statically unstable.*negative stiffness.*axial_force"):
        straight_beam(8, axial_force=-2.0 * critical).natural_frequencies(clamped=["n0"])


def test_model_verbs_on_a_buckled_subsystem_refuse_by_name_instead_of_a_singular_inertia():
    """Without an operating point, the static-equilibrium search descends from the unstable straight beam and runs
    away (the linear subsystem has no stable equilibrium): a ModelError naming the unstable direction's omega^2
    (= the lowest eigenvalue of eigh(K + K_G, M) clamped at n0), not the sweep's 'singular inertia'."""
    import scipy.linalg

    import ctmm
    from ctmm.planar import Fixed

    critical = np.pi ** 2 * EI / (4 * LENGTH ** 2)
    fe = straight_beam(8, axial_force=-2.0 * critical)
    model = PlanarModel.chain("buckled", [Fixed("ground"), fe.subsystem("beam", boundary=("n0", "n8"))],
                              gravity=(0.0, 0.0))
    free = [i for i in range(fe.n_dofs) if i not in fe.dofs["n0"]]
    lowest = scipy.linalg.eigh(fe.stiffness[np.ix_(free, free)], fe.mass[np.ix_(free, free)], eigvals_only=True)[0]
    with np.errstate(all="ignore"), pytest.raises(ModelError, match="no statically stable equilibrium") as info:
        ctmm.natural_frequencies(model, n_modes=3)
    stated = float(re.search(r"omega\^2 = (\S+) rad", str(info.value)).group(1))
    assert lowest < 0.0 and stated == pytest.approx(lowest, rel=1e-5)
    assert "operating_point" in str(info.value)


def test_axial_frequencies_and_euler_buckling_load():
    fe = straight_beam(20)
    axial = np.pi / 2 * np.sqrt(EA / RHO_A) / LENGTH             # fixed-free rod, first mode
    assert np.min(np.abs(fe.natural_frequencies(clamped=["n0"]) / axial - 1)) < 1e-3
    unit = straight_beam(20, axial_force=-1.0)                   # compression of 1 N in every element
    geometric = unit.stiffness - fe.stiffness
    keep = [i for i in range(fe.n_dofs) if i not in fe.dofs["n0"]]
    sub = np.ix_(keep, keep)
    inverse_loads = np.linalg.eigvals(np.linalg.solve(fe.stiffness[sub], -geometric[sub])).real
    loads = [1.0 / np.max(inverse_loads)]                        # K_G is singular on the axial DOFs
    assert loads[0] == pytest.approx(np.pi ** 2 * EI / (4 * LENGTH ** 2), rel=1e-6)


def test_quadrature_inertia_matches_the_consistent_mass_and_rigid_body_sums():
    nodes = {"a": (0.0, 0.0), "b": (0.6, 0.8), "c": (1.6, 0.8)}
    fe = FiniteElementModel("frame", nodes, [BeamElement("ab", "a", "b", EI, EA, RHO_A),
                                             BeamElement("bc", "b", "c", EI, EA, 2 * RHO_A),
                                             PointMass("tip", "c", 0.3, 0.01)])
    inertia = fe.floating_inertia("a")
    beam_mass = fe.mass.copy()
    beam_mass[fe.dofs["c"][2], fe.dofs["c"][2]] -= 0.01          # the rotary inertia is not translational
    assert np.allclose(inertia.translational_mass, beam_mass, atol=1e-14)
    assert inertia.mass == pytest.approx(RHO_A * 1.0 + 2 * RHO_A * 1.0 + 0.3)
    # first moment and polar moment of the undeformed mass by hand
    first = RHO_A * np.array([0.3, 0.4]) + 2 * RHO_A * np.array([1.1, 0.8]) + 0.3 * np.array([1.6, 0.8])
    assert np.allclose(inertia.first_moment, first)
    polar = (RHO_A * 1.0 / 3.0 + 2 * RHO_A * (1.0 / 12 + 1.1 ** 2 + 0.8 ** 2) + 0.3 * (1.6 ** 2 + 0.8 ** 2) + 0.01)
    assert inertia.polar == pytest.approx(polar)
    assert np.allclose(inertia.gyroscopic, -inertia.gyroscopic.T)


@pytest.mark.parametrize("build, message", [
    (lambda: FiniteElementModel("m", {"a": (0, 0)}, [BeamElement("e", "a", "z", 1.0, 1.0, 1.0)]), "unknown node 'z'"),
    (lambda: BeamElement("e", "a", "b", -1.0, 1.0, 1.0), "bending_stiffness"),
    (lambda: FiniteElementModel("m", {"a": (0, 0), "b": (0, 0)}, [BeamElement("e", "a", "b", 1.0, 1.0, 1.0)]),
     "coincide"),
    (lambda: FiniteElementModel("m", {"a": (0, 0), "b": (1, 0)}, [NodeSpring("s", "a", "b", 1.0)]).subsystem(
        "s", ("a", "b")), "positive definite.*massless: \\['b_ux', 'b_uy'\\]"),
    (lambda: straight_beam(2).subsystem("s", ("n0",), frame_nodes=("n7",)), "frame_nodes"),
    (lambda: GlobalSubsystem("g", mass_matrix=straight_beam(1).mass, damping_matrix=np.zeros((6, 6)),
                             stiffness_matrix=straight_beam(1).stiffness,
                             nodes={"n0": ((0, 0), (0, 1, 2)), "n1": ((2, 0), (3, 4, 5))}, boundary=("n0",),
                             inertia_integrals=dataclasses.replace(straight_beam(1).floating_inertia("n0"),
                                                                   sigma=np.zeros(3))),
     r"inertia_integrals.sigma must have shape \(6,\)"),
    (lambda: straight_beam(2).subsystem("s", ("n9",)), "inboard node"),
    (lambda: GlobalSubsystem("g", mass_matrix=straight_beam(1).mass, damping_matrix=np.zeros((6, 6)),
                             stiffness_matrix=straight_beam(1).stiffness,
                             nodes={"n0": ((0, 0), (0, 1, 2)), "n1": ((2, 0), (3, 4, 5))}, boundary=("n0",)),
     "not lumped"),
])
def test_bad_input_is_refused_by_name(build, message):
    with pytest.raises(ModelError, match=message):
        build()


def test_natural_frequencies_with_a_massless_free_node_are_refused_by_name():
    """A node joined by a spring only has no mass: eigh(K, M) cannot factor M (was scipy's LinAlgError)."""
    fe = FiniteElementModel("m", {"a": (0, 0), "b": (1, 0), "c": (2, 0)},
                            [BeamElement("e", "a", "b", 1.0, 1.0, 1.0), NodeSpring("s", "b", "c", 1.0)])
    with pytest.raises(ModelError, match=r"positive definite mass.*nodes without mass: \['c'\]"):
        fe.natural_frequencies(clamped=["a"])
    assert fe.natural_frequencies(clamped=["a", "c"]).size == 3          # held, it is fine


@pytest.mark.parametrize("index", [2.5, 2.0, "2", True])
def test_global_subsystem_dof_index_must_be_an_integer(index):
    """A non-integer DOF index was truncated by int() (2.5 -> DOF 2): a silently different model."""
    with pytest.raises(ModelError, match="nodes\\['b'\\].*integer DOF indices"):
        GlobalSubsystem("g", mass_matrix=np.eye(4), damping_matrix=np.zeros((4, 4)), stiffness_matrix=np.eye(4),
                        nodes={"a": ((0, 0), (0, 1)), "b": ((1, 0), (index, 3))}, boundary=("a",))


def particle_net() -> GlobalSubsystem:
    """A hub (the frame node, with a rotary inertia) and an anchor fixed in the frame carrying three particles
    joined by springs: user matrices."""
    positions = {"hub": (0.0, 0.0), "p1": (0.5, 0.0), "p2": (1.0, 0.0), "p3": (0.75, 0.4), "anchor": (0.0, 0.4)}
    springs = [("hub", "p1", 3000.0), ("p1", "p2", 2000.0), ("p2", "p3", 2500.0), ("p1", "p3", 1500.0),
               ("hub", "p3", 1000.0), ("anchor", "p3", 1000.0), ("anchor", "p1", 800.0)]
    masses = {"p1": 0.2, "p2": 0.3, "p3": 0.25}
    dofs = {"hub": (0, 1, 2), "p1": (3, 4), "p2": (5, 6), "p3": (7, 8), "anchor": (9, 10)}
    n = 11
    M, K = np.zeros((n, n)), np.zeros((n, n))
    M[2, 2] = 0.05
    for p, m in masses.items():
        M[dofs[p][0], dofs[p][0]] = M[dofs[p][1], dofs[p][1]] = m
    for a, b, k in springs:
        d = np.subtract(positions[b], positions[a])
        e = d / np.linalg.norm(d)
        row = np.zeros(n)
        row[list(dofs[b][:2])] += e
        row[list(dofs[a][:2])] -= e
        K += k * np.outer(row, row)
    nodes = {p: (positions[p], dofs[p]) for p in positions}
    return GlobalSubsystem("net", mass_matrix=M, damping_matrix=np.zeros((n, n)), stiffness_matrix=K, nodes=nodes,
                           boundary=("hub", "p2"), frame_nodes=("anchor",))


def test_lumped_global_subsystem_conserves_energy_on_a_pendulum():
    import ctmm
    net = particle_net()
    link = RigidBody.uniform_link("arm", mass=1.0, length=0.8)
    tail = RigidBody.uniform_link("tail", mass=0.2, length=0.3)
    model = PlanarModel.chain("net_pendulum", [Pinned("base"), link, FixedMounting("weld", angle=0.3), net,
                                               SmoothHinge("t"), tail])
    q0 = np.zeros(model.n_coordinates)
    q0[model.coordinates.index("arm.theta")] = -0.4
    q0[model.coordinates.index("net.p3_uy")] = 0.01
    result = ctmm.simulate(model, 0.3, 2.5e-4, method="rk4", x0=q0)
    names = model.coordinates
    Q = np.column_stack([result.extra[c] for c in names])
    V = np.column_stack([result.extra[c + "_dot"] for c in names])
    energy = np.array([model.energy(Q[k], V[k]) for k in range(0, Q.shape[0], 120)])
    assert np.ptp(energy) < 1e-8 * np.max(np.abs(energy))
    assert np.max(np.abs(V[:, names.index("net.p3_uy")])) > 0.02          # the net moves


def test_a_large_deformation_is_reported():
    import ctmm
    from ctmm.fem import SmallDeformationWarning
    fe = FiniteElementModel("soft", {"n0": (0.0, 0.0), "n1": (0.5, 0.0), "n2": (1.0, 0.0)},
                            [BeamElement(f"e{k}", f"n{k}", f"n{k + 1}", 0.5, 1e3, 1.0) for k in (0, 1)])
    model = PlanarModel.chain("floppy", [Pinned("base"), fe.subsystem("soft", ("n0", "n2"))])
    with pytest.warns(SmallDeformationWarning, match="soft"):
        ctmm.simulate(model, 0.15, 1e-3, method="newmark")


def test_nodal_coordinates_have_the_units_of_displacements_and_rotations():
    """The planar ports named every internal coordinate of a subsystem dimensionless ('1', rates '1/s'); nodal
    displacements are m and rotations rad (as the spatial subsystem's coordinate_units)."""
    from ctmm.planar.ports import PlanarPorts
    fe = FiniteElementModel("soft", {"n0": (0.0, 0.0), "n1": (0.5, 0.0), "n2": (1.0, 0.0)},
                            [BeamElement(f"e{k}", f"n{k}", f"n{k + 1}", 0.5, 1e3, 1.0) for k in (0, 1)])
    model = PlanarModel.chain("floppy", [Pinned("base"), fe.subsystem("soft", ("n0", "n2"))])
    ports = PlanarPorts(model)
    units = {name: ports.sensor_unit(name) for name in model.coordinates}
    assert units == {name: "rad" if name.endswith(("_rz", ".theta")) else "m" for name in model.coordinates}
    assert {ports.sensor_unit(f"{name}_dot") for name in model.coordinates if name.endswith("_ux")} == {"m/s"}
