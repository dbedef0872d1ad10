"""Meshes, boundary conditions and analytic references for the plate-element tests
(tests/test_fem_plate_thick.py, tests/test_fem_plate_triangle.py).

References (derived here from the plate equations, no element code):

* Navier / Kirchhoff, simply supported ``a x b``: ``omega_mn = pi^2 (m^2/a^2 + n^2/b^2) sqrt(D / (rho h))``;
* Mindlin (1951), simply supported (hard: ``w = 0`` and the tangential slope held): with
  ``w = W sin(al x) sin(be y)``, ``psi_x = X cos(al x) sin(be y)``, ``psi_y = Y sin(al x) cos(be y)``
  (``al = m pi / a``, ``be = n pi / b``) the equations
  ``k G h (lap w + div psi) = rho h w''`` and
  ``D/2 [(1 - nu) lap psi + (1 + nu) grad div psi] - k G h (psi + grad w) = rho h^3/12 psi''``
  become the symmetric 3 x 3 eigenproblem of :func:`mindlin_frequency` (lowest root: the flexural mode).
"""
from __future__ import annotations

import numpy as np
import scipy.linalg

from ctmm.fem import SpatialFiniteElementModel, SpatialThickPlateElement, SpatialTrianglePlateElement

STEEL = dict(youngs_modulus=2e11, poisson_ratio=0.3, density=7850.0)


def bending_stiffness(h: float, youngs_modulus: float = 2e11, poisson_ratio: float = 0.3) -> float:
    """``D = E h^3 / (12 (1 - nu^2))`` [N m]."""
    return youngs_modulus * h ** 3 / (12 * (1 - poisson_ratio ** 2))


def navier_frequencies(a: float, b: float, h: float, count: int) -> np.ndarray:
    """Lowest ``count`` Kirchhoff frequencies [rad/s] of the simply supported steel plate."""
    scale = np.pi ** 2 * np.sqrt(bending_stiffness(h) / (STEEL["density"] * h))
    return np.sort([scale * (m * m / a ** 2 + n * n / b ** 2) for m in range(1, 6) for n in range(1, 6)])[:count]


def mindlin_frequency(a: float, b: float, h: float, m: int, n: int, shear_correction: float = 5 / 6) -> float:
    """Flexural frequency [rad/s] of mode ``(m, n)`` of the simply supported Mindlin steel plate (module docstring)."""
    E, nu, rho = STEEL["youngs_modulus"], STEEL["poisson_ratio"], STEEL["density"]
    D, s = bending_stiffness(h), shear_correction * E / (2 * (1 + nu)) * h
    al, be = m * np.pi / a, n * np.pi / b
    k2, twist = al ** 2 + be ** 2, D / 2 * (1 + nu) * al * be
    K = np.array([[s * k2, s * al, s * be],
                  [s * al, D / 2 * ((1 - nu) * k2 + (1 + nu) * al ** 2) + s, twist],
                  [s * be, twist, D / 2 * ((1 - nu) * k2 + (1 + nu) * be ** 2) + s]])
    return float(np.sqrt(scipy.linalg.eigh(K, np.diag([rho * h, rho * h ** 3 / 12, rho * h ** 3 / 12]),
                                           eigvals_only=True)[0]))


def grid_nodes(n: int, a: float, b: float, distortion: float = 0.0, seed: int = 1) -> dict:
    """Nodes ``"i_j"`` of an ``n x n`` grid on ``[0, a] x [0, b]`` (z = 0); interior nodes moved at random by up to
    ``distortion / 2`` of a cell in each direction (an irregular mesh)."""
    rng = np.random.default_rng(seed)
    nodes = {}
    for i in range(n + 1):
        for j in range(n + 1):
            x, y = a * i / n, b * j / n
            if 0 < i < n and 0 < j < n:
                x += distortion * a / n * (rng.random() - 0.5)
                y += distortion * b / n * (rng.random() - 0.5)
            nodes[f"{i}_{j}"] = (x, y, 0.0)
    return nodes


def plate_model(n: int, a: float, b: float, h: float, *, triangles: bool = False, distortion: float = 0.0,
                **options) -> SpatialFiniteElementModel:
    """A steel ``a x b`` plate: ``n x n`` thick quadrilaterals, or each cell cut into two triangles along
    alternating diagonals."""
    elements = []
    for i in range(n):
        for j in range(n):
            q = (f"{i}_{j}", f"{i + 1}_{j}", f"{i + 1}_{j + 1}", f"{i}_{j + 1}")
            if not triangles:
                elements.append(SpatialThickPlateElement(f"p{i}_{j}", q, h, **STEEL, **options))
            elif (i + j) % 2:
                elements += [SpatialTrianglePlateElement(f"t{i}_{j}a", (q[0], q[1], q[2]), h, **STEEL, **options),
                             SpatialTrianglePlateElement(f"t{i}_{j}b", (q[0], q[2], q[3]), h, **STEEL, **options)]
            else:
                elements += [SpatialTrianglePlateElement(f"t{i}_{j}a", (q[0], q[1], q[3]), h, **STEEL, **options),
                             SpatialTrianglePlateElement(f"t{i}_{j}b", (q[1], q[2], q[3]), h, **STEEL, **options)]
    return SpatialFiniteElementModel("plate", grid_nodes(n, a, b, distortion), elements)


def bending_frequencies(fe: SpatialFiniteElementModel, a: float, b: float, count: int, edges: str) -> np.ndarray:
    """Lowest bending frequencies [rad/s] of a flat x-y rectangle ``[0, a] x [0, b]`` from its ``(u_z, r_x, r_y)``
    DOFs; ``edges``: ``"simply supported"`` (``u_z`` and the rotation about the edge held) or ``"clamped"``."""
    keep = []
    for node, dofs in fe.dofs.items():
        x, y, _ = fe.positions[node]
        on_x, on_y = min(x, a - x) < 1e-12, min(y, b - y) < 1e-12       # on an edge x = const / y = const
        if edges == "clamped":
            keep += [] if on_x or on_y else [dofs[2], dofs[3], dofs[4]]
        else:
            keep += ([] if on_x or on_y else [dofs[2]]) + ([] if on_x else [dofs[3]]) + ([] if on_y else [dofs[4]])
    sub = np.ix_(keep, keep)
    values = scipy.linalg.eigh(fe.stiffness[sub], fe.mass[sub], eigvals_only=True, subset_by_index=[0, count - 1])
    return np.sqrt(values)


def rigid_motion_energies(fe: SpatialFiniteElementModel) -> list[float]:
    """``u^T K u`` of the six rigid motions of a model (translations, then small rotations about the origin)."""
    energies = []
    for k in range(6):
        u = np.zeros(fe.n_dofs)
        for node, dofs in fe.dofs.items():
            u[list(dofs[:3])] = np.cross(np.eye(3)[k - 3], fe.positions[node]) if k >= 3 else np.eye(3)[k]
            if k >= 3:
                u[list(dofs[3:])] = np.eye(3)[k - 3]
        energies.append(float(u @ fe.stiffness @ u))
    return energies


def bending_patch_error(fe: SpatialFiniteElementModel, curvature: tuple[float, float, float],
                        boundary: set) -> tuple[float, float]:
    """Impose ``w = -(k_x x^2 + k_y y^2 + k_xy x y)/2 + x/10 - y/20`` (constant curvatures
    ``psi_x,x = k_x``, ``psi_y,y = k_y``, ``psi_x,y + psi_y,x = k_xy``; ``r_x = w_y``, ``r_y = -w_x``) at the
    ``boundary`` nodes, solve the unloaded interior, and return the largest interior DOF error relative to the
    largest value, and the strain energy ``u^T K u / 2`` [J]."""
    kx, ky, kxy = curvature
    exact = np.zeros(fe.n_dofs)
    for node, dofs in fe.dofs.items():
        x, y, _ = fe.positions[node]
        exact[dofs[2]] = -(kx * x * x + ky * y * y + kxy * x * y) / 2 + x / 10 - y / 20
        exact[dofs[3]] = -(ky * y + kxy * x / 2) - 1 / 20                 # w_y
        exact[dofs[4]] = kx * x + kxy * y / 2 - 1 / 10                    # -w_x
    bending = [dofs[k] for dofs in fe.dofs.values() for k in (2, 3, 4)]
    held = [dofs[k] for node, dofs in fe.dofs.items() if node in boundary for k in (2, 3, 4)]
    free = [i for i in bending if i not in held]
    u = exact.copy()
    u[free] = np.linalg.solve(fe.stiffness[np.ix_(free, free)], -fe.stiffness[np.ix_(free, held)] @ exact[held])
    return float(np.max(np.abs(u[free] - exact[free])) / np.max(np.abs(exact))), float(u @ fe.stiffness @ u / 2)


def hinged_frequencies(fe: SpatialFiniteElementModel, node: str, axis: int, count: int) -> tuple[np.ndarray, np.ndarray]:
    """The elastic frequencies [rad/s] of ``fe`` pinned at ``node`` on a free hinge about model axis ``axis``
    (0, 1, 2), no gravity, twice: ``ctmm.natural_frequencies`` of the subsystem (floating frame at ``node``) on a
    ``Revolute``, and ``eigh`` of the assembled matrices with the node's translations and other rotations held
    (its rotation about ``axis`` free).  The rigid hinge mode (0) is dropped from both."""
    import ctmm
    import ctmm.spatial as sp

    model = sp.SpatialModel("hinged", [fe.subsystem("plate", boundary=(node,)),
                                       sp.Revolute(name="hinge", parent=None, child="plate",
                                                   axis=tuple(np.eye(3)[axis]))], gravity=(0.0, 0.0, 0.0))
    omega = ctmm.natural_frequencies(model, n_modes=count + 1)
    held = [i for k, i in enumerate(fe.dofs[node]) if k != 3 + axis]
    keep = [i for i in range(fe.n_dofs) if i not in held]
    values = scipy.linalg.eigh(fe.stiffness[np.ix_(keep, keep)], fe.mass[np.ix_(keep, keep)], eigvals_only=True,
                               subset_by_index=[0, count])
    return np.asarray(omega[1:]), np.sqrt(np.abs(values[1:]))
