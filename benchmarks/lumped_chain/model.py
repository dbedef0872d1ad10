"""The benchmark chain of ``foundation_scaling`` and ``chain_frf``: model, frequency grid, 30-digit reference.

Chain: fixed-free, wall -- (K || c) -- m -- (K || c) -- m ... m (free end), K = 1000 N/m, m = 0.1 kg, light
stiffness-proportional damping c = 2e-4 s * K = 0.2 N s/m (modal damping ratio 1e-4 s * omega_j, at most 2 % at the
band edge 2 sqrt(K/m) = 200 rad/s).  Frequencies: 1000 log-spaced omega from omega_1/2 to 0.95 * 200 rad/s
(omega_1 = 200 sin(pi / (2 (2n + 1))) rad/s).  The same chain as a ctmm model (:func:`ctmm_chain`) and as the
independent global ``M, C, K`` model (:func:`global_chain`), and its receptances solved with mpmath
(:func:`high_precision_frf`, the accuracy reference of both benchmarks).
"""
from __future__ import annotations

import sys
from pathlib import Path

import numpy as np

ROOT = Path(__file__).resolve().parents[2]
if str(ROOT) not in sys.path:
    sys.path.insert(0, str(ROOT))

import ctmm  # noqa: E402
from ctmm.elements.boundary import Fixed, Free  # noqa: E402
from ctmm.elements.lumped import Mass, SpringDamper  # noqa: E402
from ctmm.reference import chain as reference  # noqa: E402  (benchmarks may use the validation models)

STIFFNESS, MASS, DAMPING = 1000.0, 0.1, 0.2    # [N/m], [kg], [N s/m]
FORCE = 100.0                                  # [N] on m1 in the time-stepping runs
N_OMEGA = 1000
PROBE = 10                 # probe frequencies (also the high-precision subset)


def ctmm_chain(n: int) -> ctmm.Chain:
    """The chain of ``n`` masses as a ctmm model (``m1`` carries the constant force ``FORCE`` [N] in time)."""
    elements = [Fixed("wall")]
    for i in range(1, n + 1):
        elements.append(SpringDamper(f"k{i}", STIFFNESS, DAMPING))
        elements.append(Mass(f"m{i}", MASS, force=FORCE if i == 1 else 0.0))
    elements.append(Free("end"))
    return ctmm.Chain(f"chain{n}", elements)


def global_chain(n: int) -> reference.GlobalChain:
    """The same chain as the independent global ``M, C, K`` model of :mod:`ctmm.reference.chain`."""
    return reference.GlobalChain.uniform(n, MASS, STIFFNESS, DAMPING, start="fixed", end="free")


def omega_grid(n: int) -> np.ndarray:
    """``N_OMEGA`` log-spaced angular frequencies [rad/s] from omega_1 / 2 to 0.95 times the band edge."""
    band_edge = 2.0 * np.sqrt(STIFFNESS / MASS)
    omega_1 = band_edge * np.sin(np.pi / (2 * (2 * n + 1)))
    return np.logspace(np.log10(0.5 * omega_1), np.log10(0.95 * band_edge), N_OMEGA)


def probe_indices() -> np.ndarray:
    """Indices of the ``PROBE`` evenly spread probe frequencies in :func:`omega_grid`."""
    return np.unique(np.round(np.linspace(0, N_OMEGA - 1, PROBE)).astype(int))


def relative_difference(value: np.ndarray, ref: np.ndarray) -> dict:
    """Max pointwise |value - ref| / |ref| where |ref| is representable (> 1e-280)."""
    ok = np.abs(ref) > 1e-280
    rel = np.abs(value[ok] - ref[ok]) / np.abs(ref[ok])
    return {"max": float(np.max(rel)) if rel.size else float("nan"),
            "frequencies_compared": int(ok.sum()), "frequencies_underflowing": int((~ok).sum())}


def high_precision_frf(n: int, omega: np.ndarray, digits: int = 30) -> np.ndarray:
    """Driving-point and tip receptance [m/N] per unit force on mass 0 with mpmath (Thomas algorithm).

    Returns complex array (2, len(omega)): row 0 = x_0, row 1 = x_{n-1}.
    """
    import mpmath as mp

    mp.mp.dps = digits
    out = np.empty((2, omega.size), dtype=complex)
    k, c, m = mp.mpf(STIFFNESS), mp.mpf(DAMPING), mp.mpf(MASS)
    for idx, w in enumerate(omega):
        w = mp.mpf(float(w))
        conn = k + mp.mpc(0, 1) * w * c                  # connector dynamic stiffness
        off = -conn
        # diag: interior 2 conn - w^2 m, last (free end) conn - w^2 m
        diag = [2 * conn - w * w * m] * (n - 1) + [conn - w * w * m]
        # forward elimination (rhs = e_0), then back substitution
        cp = [mp.mpc(0)] * n
        dp = [mp.mpc(0)] * n
        cp[0] = off / diag[0]
        dp[0] = mp.mpc(1) / diag[0]
        for i in range(1, n):
            denom = diag[i] - off * cp[i - 1]
            cp[i] = off / denom if i < n - 1 else mp.mpc(0)
            dp[i] = (-off * dp[i - 1]) / denom
        x = dp[n - 1]
        x_tip = x
        for i in range(n - 2, -1, -1):
            x = dp[i] - cp[i] * x
        out[0, idx] = complex(x)
        out[1, idx] = complex(x_tip)
    return out


