"""ctmm.fem.MembraneElement (plane-stress Q4): analytic membrane frequencies, inertia integrals, refusals."""
from __future__ import annotations

import numpy as np
import pytest
import scipy.linalg

from ctmm.errors import ModelError
from ctmm.fem import FiniteElementModel, MembraneElement

E, NU, RHO, T = 7.0e10, 0.3, 2700.0, 0.002
A, B = 0.4, 0.2


def sheet(nx: int, ny: int, a: float = A, b: float = B, **kwargs) -> FiniteElementModel:
    nodes = {f"n{i}_{j}": (a * i / nx, b * j / ny) for i in range(nx + 1) for j in range(ny + 1)}
    quads = [MembraneElement(f"q{i}_{j}", (f"n{i}_{j}", f"n{i + 1}_{j}", f"n{i + 1}_{j + 1}", f"n{i}_{j + 1}"),
                             T, E, NU, RHO) for i in range(nx) for j in range(ny)]
    return FiniteElementModel("sheet", nodes, quads, **kwargs)


def roller_frequencies(fe: FiniteElementModel, a: float, b: float) -> np.ndarray:
    """Every edge on rollers: the normal displacement held, the tangential one free."""
    held = set()
    for node, (x, y) in fe.positions.items():
        if np.isclose(x, 0.0) or np.isclose(x, a):
            held.add(fe.dofs[node][0])
        if np.isclose(y, 0.0) or np.isclose(y, b):
            held.add(fe.dofs[node][1])
    keep = [i for i in range(fe.n_dofs) if i not in held]
    sub = np.ix_(keep, keep)
    return np.sqrt(scipy.linalg.eigh(fe.stiffness[sub], fe.mass[sub], eigvals_only=True))


def analytic_roller_frequencies(a: float, b: float, count: int) -> np.ndarray:
    """Rectangle with every edge on rollers: u_x = sin(m pi x/a) cos(n pi y/b), u_y = cos(m pi x/a) sin(n pi y/b)
    separates Navier's equations into dilatational (rho w^2 = E/(1 - nu^2) k^2) and shear (rho w^2 = G k^2) waves,
    k^2 = (m pi/a)^2 + (n pi/b)^2; (m, 0) and (0, n) carry only the dilatational one."""
    p_speed = np.sqrt(E / ((1 - NU ** 2) * RHO))
    s_speed = np.sqrt(E / (2 * (1 + NU) * RHO))
    out = []
    for m in range(8):
        for n in range(8):
            if m == n == 0:
                continue
            k = np.pi * np.hypot(m / a, n / b)
            out.append(p_speed * k)
            if m and n:
                out.append(s_speed * k)
    return np.sort(out)[:count]


def test_roller_rectangle_frequencies_converge_at_second_order():
    exact = analytic_roller_frequencies(A, B, 5)
    errors = []
    for nx in (4, 8, 16):
        errors.append(roller_frequencies(sheet(nx, nx // 2), A, B)[:5] / exact - 1)
    errors = np.array(errors)
    assert np.all(errors > 0)                                     # consistent mass, conforming: from above
    assert np.max(errors[-1]) < 1.5e-2                            # 16 x 8: 1.6e-3 ... 1.25e-2
    rates = np.log2(errors[:-1] / errors[1:])
    assert np.all(np.abs(rates[-1] - 2.0) < 0.1)                  # Q4: O(h^2) (observed 2.00-2.04)


def test_free_sheet_has_three_rigid_modes_and_the_right_mass():
    fe = sheet(3, 2)
    omega = fe.natural_frequencies()
    assert np.all(omega[:3] < 1e-3 * omega[3])
    assert np.sum(fe.mass) / 2 == pytest.approx(RHO * T * A * B, rel=1e-13)


def test_inertia_integrals_of_a_skewed_sheet_match_its_consistent_mass():
    nodes = {"a": (0.0, 0.0), "b": (0.3, 0.05), "c": (0.35, 0.25), "d": (-0.02, 0.2), "e": (0.6, 0.1), "f": (0.62, 0.3)}
    fe = FiniteElementModel("skew", nodes, [MembraneElement("q1", ("a", "b", "c", "d"), T, E, NU, RHO),
                                            MembraneElement("q2", ("b", "e", "f", "c"), T, E, NU, 2 * RHO)])
    inertia = fe.floating_inertia("a")
    assert np.allclose(inertia.translational_mass, fe.mass, rtol=0, atol=1e-14 * np.max(fe.mass))
    # rigid translation of every node: S1 columns sum to the total mass; first moment by the area centroids
    assert inertia.mass == pytest.approx(np.sum(fe.mass) / 2, rel=1e-13)

    def polygon(points):
        x, y = np.array(points).T
        cross = x * np.roll(y, -1) - np.roll(x, -1) * y
        area = cross.sum() / 2
        return area, np.array([((x + np.roll(x, -1)) * cross).sum(), ((y + np.roll(y, -1)) * cross).sum()]) / (6 * area)
    a1, c1 = polygon([nodes[k] for k in "abcd"])
    a2, c2 = polygon([nodes[k] for k in "befc"])
    first = RHO * T * (a1 * c1 + 2 * a2 * c2)
    assert np.allclose(inertia.first_moment, first, rtol=1e-12)


def test_bad_membranes_are_refused():
    with pytest.raises(ModelError, match="poisson_ratio"):
        MembraneElement("q", ("a", "b", "c", "d"), T, E, 0.5, RHO)
    with pytest.raises(ModelError, match="four distinct"):
        MembraneElement("q", ("a", "b", "c", "a"), T, E, NU, RHO)
    with pytest.raises(ModelError, match="thickness"):
        MembraneElement("q", ("a", "b", "c", "d"), 0.0, E, NU, RHO)
    with pytest.raises(ModelError, match="clockwise"):
        FiniteElementModel("cw", {"a": (0, 0), "b": (0, 1), "c": (1, 1), "d": (1, 0)},
                           [MembraneElement("q", ("a", "b", "c", "d"), T, E, NU, RHO)])
