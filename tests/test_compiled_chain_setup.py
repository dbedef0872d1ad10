"""The set-up of a generated chain kernel grows like the chain, not like its square (structural, no timing).

The set-up of ``ctmm.simulate(chain, ..., compiled=True)`` (:class:`ctmm.compiled_chain.CompiledChain`,
:class:`ctmm.compiled_chain_schemes.CompiledChainScheme`) reads the chain's affine rates from the articulated sweep
and the loops' sensor rows from the ports.  Counted here, with the C generation stopped before it starts: the
entries of every probe batch handed to the sweep (rows times nodes) and the sensor evaluations.  Both must grow
linearly with the number of masses (they grew like its square with one unit probe per state).  The affine form
itself is checked against the global ``M, C, K`` written here (tridiagonal, sparse).
"""
from __future__ import annotations

import numpy as np
import pytest
import scipy.sparse

import ctmm
from ctmm import compiled_chain, compiled_chain_schemes
from ctmm.chain_ode import ChainDynamics
from ctmm.compiled_chain import affine_form, sensor_row
from ctmm.compiled_chain_kernel import step_matrix, tridiagonal_factors, woodbury_parts
from ctmm.control import ControlledChain, Feedback
from ctmm.control.chain_plant import ChainPlant, ChainPorts
from ctmm.elements import Fixed, Free, Mass, PrescribedDisplacement, SpringDamper
from ctmm.signals import Harmonic

pytest.importorskip("casadi")
STIFFNESS, DAMPING = 1.0e4, 2.0


def _masses(n: int) -> np.ndarray:
    return 1.0 + 0.5 * np.sin(np.arange(n))


def _chain(n: int, base: bool = False) -> ctmm.Chain:
    """Fixed - [k, c] - m_0 - ... - m_{n-1} - Free; ``base``: a harmonic start and end motion instead and a
    harmonic force on ``m_1``."""
    elements = [PrescribedDisplacement("start", Harmonic(0.01, 5.0)) if base else Fixed("start")]
    for i, mass in enumerate(_masses(n)):
        force = Harmonic(2.0, 3.0) if base and i == 1 else 0.0
        elements += [SpringDamper(f"k{i}", STIFFNESS * (1.0 + 0.1 * i), DAMPING),
                     Mass(f"m{i}", float(mass), force=force)]
    end = [SpringDamper("k_end", STIFFNESS, DAMPING), PrescribedDisplacement("end", Harmonic(0.02, 7.0, 0.5))]
    return ctmm.Chain(f"chain{n}", elements + (end if base else [Free("end")]))


def _global(n: int) -> tuple[np.ndarray, np.ndarray]:
    """``-M^-1 K`` and ``-M^-1 C`` of the fixed-free chain, by hand (connector ``i`` between ``m_{i-1}``, ``m_i``)."""
    K, C = np.zeros((n, n)), np.zeros((n, n))
    for i in range(n):
        k, c = STIFFNESS * (1.0 + 0.1 * i), DAMPING
        for matrix, value in ((K, k), (C, c)):
            matrix[i, i] += value
            if i > 0:
                matrix[i - 1, i - 1] += value
                matrix[i - 1, i] -= value
                matrix[i, i - 1] -= value
    inverse = np.diag(1.0 / _masses(n))
    return -inverse @ K, -inverse @ C


def test_affine_form_is_tridiagonal_sparse_and_equal_to_the_global_matrices():
    n = 40
    dynamics = ChainDynamics(_chain(n))
    Kx, Cv = _global(n)
    sparse = affine_form(dynamics, sparse=True)
    dense = affine_form(dynamics)
    assert scipy.sparse.issparse(sparse.Ax) and scipy.sparse.issparse(sparse.Av)
    assert sparse.Ax.nnz <= 3 * n and sparse.Av.nnz <= 3 * n
    for form in (sparse, dense):
        for matrix, expected in ((form.Ax, Kx), (form.Av, Cv)):
            value = matrix.toarray() if scipy.sparse.issparse(matrix) else matrix
            assert np.max(np.abs(value - expected)) <= 1e-12 * np.max(np.abs(expected))
        assert np.max(np.abs(form.a0)) == 0.0


def test_step_matrix_and_woodbury_columns_stay_banded():
    """The scheme's step matrix of sparse rates is sparse, and the loops' columns through it solve with its
    tridiagonal factors (compared with a dense solve of the same matrix)."""
    n = 30
    Kx, Cv = _global(n)
    Ax, Av = scipy.sparse.csr_matrix(Kx), scipy.sparse.csr_matrix(Cv)
    S = step_matrix(4.0e8, 1.0, 2.0e4, Ax, Av)
    assert scipy.sparse.issparse(S) and S.nnz <= 3 * n
    factors = tridiagonal_factors(S, Ax, Av)
    assert factors is not None
    rng = np.random.default_rng(2)
    columns, rows = rng.standard_normal((n, 2)), rng.standard_normal((2, n))
    W, Q = woodbury_parts(["a", "b"], columns, rows, S, 1e-4, factors)
    dense = 4.0e8 * np.eye(n) - Kx - 2.0e4 * Cv
    assert np.allclose(W, np.linalg.solve(dense, columns), rtol=1e-12, atol=0.0)
    assert np.allclose(Q, np.linalg.solve(np.eye(2) + rows @ W, rows), rtol=1e-12, atol=0.0)


class _Stop(Exception):
    pass


def _counted_setup(monkeypatch, n: int, kind: str) -> tuple[int, int]:
    """``(probe entries, sensor evaluations)`` of one set-up of a chain of ``n`` masses with a real-time loop
    (``"base"``: the base-excited chain without loops on the generated RK4)."""
    counts = {"entries": 0, "sensors": 0}
    forces, values = ChainDynamics.forces, ChainPorts.values

    def counted_forces(self, x, v, *args, **kwargs):
        counts["entries"] += int(np.atleast_2d(x).size)
        return forces(self, x, v, *args, **kwargs)

    def counted_values(self, *args, **kwargs):
        counts["sensors"] += 1
        return values(self, *args, **kwargs)

    def stop(*args, **kwargs):
        raise _Stop

    monkeypatch.setattr(ChainDynamics, "forces", counted_forces)
    monkeypatch.setattr(ChainPorts, "values", counted_values)
    system = ControlledChain(_chain(n), [Feedback("tip", f"m{n - 1}.x", "m0", gain=500.0)])
    if kind == "base":
        system, kind = _chain(n, base=True), "rk4"
    if kind == "rk4":
        monkeypatch.setattr(compiled_chain, "compiled_time_loop", stop)
        build = lambda: compiled_chain.CompiledChain(system, dt=1e-4)               # noqa: E731
    else:
        monkeypatch.setattr(compiled_chain_schemes, "compiled_time_loop", stop)
        build = lambda: compiled_chain_schemes.CompiledChainScheme(system, 1e-4)    # noqa: E731
    with pytest.raises(_Stop):
        build()
    return counts["entries"], counts["sensors"]


@pytest.mark.parametrize("kind", ["rk4", "newmark", "base"])
def test_setup_probes_grow_linearly_with_the_chain(monkeypatch, kind):
    """Doubling the chain doubles the probe entries (one unit probe per state: four times) and keeps the number
    of sensor evaluations (one per state before: twice as many)."""
    small, large = (_counted_setup(monkeypatch, n, kind) for n in (24, 48))
    assert large[0] <= 2.2 * small[0], (small, large)
    assert large[1] == small[1], (small, large)


def test_sensor_row_equals_all_unit_probes():
    """The row read from the sensed nodes' states equals the row of every unit probe (a position, a velocity
    and a connector force, weighted)."""
    plant = ChainPlant(_chain(12))
    terms = [("m3.x", 2.0), ("m7.v", -1.5), ("k5.f", 0.25)]
    for name, _ in terms:
        plant.ports.check_sensor(name)
    row, offset = sensor_row(plant.ports, terms, 24)
    sensors = plant.ports.resolve([name for name, _ in terms])
    weights = np.array([w for _, w in terms])
    zero = np.zeros(24)
    base = float(weights @ plant.ports.values(sensors, zero[:12], zero[12:], 0.0))
    expected = np.array([float(weights @ plant.ports.values(sensors, unit[:12], unit[12:], 0.0)) - base
                         for unit in np.eye(24)])
    assert offset == base
    assert np.array_equal(row, expected)
    assert np.count_nonzero(row) == 6
