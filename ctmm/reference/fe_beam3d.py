"""Independent reference: a 3-D finite-element model of chains of spatial beams, bodies and springs.

Shares no code with ctmm's transfer-matrix solvers (only numpy / scipy).  Global assembly of

* **beams**: 2-node, 12-DOF elements (per node ``ux, uy, uz, theta_x, theta_y, theta_z``): linear
  axial and torsional shape functions, cubic Hermite bending in both planes (``theta_z = v'``,
  ``theta_y = -w'``), consistent mass, the consistent geometric stiffness of a constant tension
  ``T`` (``T / (30 l) [[36, 3l, -36, 3l], [3l, 4l^2, -3l, -l^2], ...]`` per plane), turned to the chain
  axes by ``rotation``; structural loss factor ``eta``: ``K (1 + i eta)``; Kelvin-Voigt ``tau``:
  ``C = tau K``;
* **rigid bodies**: a lumped 6 x 6 mass at a node, ``[[m I, -m S], [m S, I_c - m S^2]]`` with
  ``S = skew(c)``; an outboard point at offset ``r`` is a new node slaved rigidly to the inboard one
  (``u_b = u_a - skew(r) theta_a``, ``theta_b = theta_a``);
* **springs** between coincident nodes (``[[K, -K], [-K, K]]``), **ground springs** at a node;
* **boundaries** at the first and last node: any subset of the six displacements held;
* **branches** (``FEBranch``): side chains hung at a node, each with its own end condition.

Every node's six DOFs are a linear map ``T_node`` of the reduced unknowns; constraints are removed
by a null-space basis.  Convergence: bending frequencies ``O(h^4)``, axial and torsional
``O(h^2)`` (linear elements).
"""
from __future__ import annotations

from dataclasses import dataclass, field
from typing import Any, Sequence

import numpy as np
import scipy.linalg

__all__ = ["FEBeam", "FEBody", "FESpring", "FEGround", "FEMarker", "FEBranch", "FEChain", "COMPONENTS"]

COMPONENTS = ("ux", "uy", "uz", "theta_x", "theta_y", "theta_z")


def _skew(r) -> np.ndarray:
    x, y, z = np.asarray(r, dtype=float)
    return np.array([[0.0, -z, y], [z, 0.0, -x], [-y, x, 0.0]])


@dataclass
class FEBeam:
    """Uniform beam (parameters as in the module docstring) meshed into ``elements`` equal elements."""

    length: float
    EA: float
    GJ: float
    EIy: float
    EIz: float
    rhoA: float
    rhoIp: float
    tension: float = 0.0
    loss_factor: float = 0.0
    kelvin_voigt_time: float = 0.0
    rotation: Any = None
    elements: int = 10


@dataclass
class FEBody:
    """Rigid body: mass [kg], inertia (3 x 3 about the centre of mass) [kg m^2], centre and outboard
    offset from the inboard node [m]."""

    mass: float
    inertia: Any
    center: Any = (0.0, 0.0, 0.0)
    offset: Any = (0.0, 0.0, 0.0)


@dataclass
class FESpring:
    """6 x 6 spring / damper between the current node and a new coincident node."""

    stiffness: Any
    damping: Any = None


@dataclass
class FEGround:
    """6 x 6 spring / damper from the current node to the ground."""

    stiffness: Any
    damping: Any = None


@dataclass
class FEBranch:
    """A side chain of parts hung at the current node, its last node holding ``end_held``; the main
    chain continues from the attachment node."""

    parts: Sequence[Any]
    end_held: Sequence[str] = ()


@dataclass
class FEMarker:
    """Names the current node (for loads and outputs)."""

    name: str


def _beam_matrices(b: FEBeam, l: float) -> tuple[np.ndarray, np.ndarray, np.ndarray]:
    """Local 12 x 12 elastic stiffness, geometric stiffness and consistent mass of one element."""
    K, Kg, M = np.zeros((12, 12)), np.zeros((12, 12)), np.zeros((12, 12))
    bar_k = np.array([[1.0, -1.0], [-1.0, 1.0]]) / l
    bar_m = np.array([[2.0, 1.0], [1.0, 2.0]]) * l / 6
    for idx, stiff, dens in (((0, 6), b.EA, b.rhoA), ((3, 9), b.GJ, b.rhoIp)):
        K[np.ix_(idx, idx)] += stiff * bar_k
        M[np.ix_(idx, idx)] += dens * bar_m
    hk = np.array([[12, 6 * l, -12, 6 * l], [6 * l, 4 * l * l, -6 * l, 2 * l * l],
                   [-12, -6 * l, 12, -6 * l], [6 * l, 2 * l * l, -6 * l, 4 * l * l]]) / l ** 3
    hm = np.array([[156, 22 * l, 54, -13 * l], [22 * l, 4 * l * l, 13 * l, -3 * l * l],
                   [54, 13 * l, 156, -22 * l], [-13 * l, -3 * l * l, -22 * l, 4 * l * l]]) * l / 420
    hg = np.array([[36, 3 * l, -36, 3 * l], [3 * l, 4 * l * l, -3 * l, -l * l],
                   [-36, -3 * l, 36, -3 * l], [3 * l, -l * l, -3 * l, 4 * l * l]]) / (30 * l)
    for idx, EI, sign in (((1, 5, 7, 11), b.EIz, 1.0), ((2, 4, 8, 10), b.EIy, -1.0)):
        D = np.diag([1.0, sign, 1.0, sign])        # theta_y = -w'
        K[np.ix_(idx, idx)] += EI * D @ hk @ D
        M[np.ix_(idx, idx)] += b.rhoA * D @ hm @ D
        Kg[np.ix_(idx, idx)] += b.tension * D @ hg @ D
    R = np.eye(3) if b.rotation is None else np.asarray(b.rotation, dtype=float)
    R4 = scipy.linalg.block_diag(R, R, R, R)
    return R4 @ K @ R4.T, R4 @ Kg @ R4.T, R4 @ M @ R4.T


@dataclass
class FEChain:
    """A serial chain of parts from a start node to an end node.

    Parameters
    ----------
    parts : sequence
        ``FEBeam``, ``FEBody``, ``FESpring``, ``FEGround``, ``FEMarker`` in order from the start.
    start_held, end_held : sequence of str
        Displacement components held at zero at the first / last node (``COMPONENTS``: all six
        clamped, none free).
    """

    parts: Sequence[Any]
    start_held: Sequence[str] = COMPONENTS
    end_held: Sequence[str] = ()
    _built: dict = field(default_factory=dict, repr=False)

    def _build(self) -> dict:
        if self._built:
            return self._built
        maps: list[np.ndarray] = []              # per node: 6 x n_free map (columns appended lazily)
        n_free = 0
        blocks: list[tuple[list[int], np.ndarray, np.ndarray, np.ndarray, np.ndarray]] = []

        def new_node() -> int:
            nonlocal n_free
            T = np.zeros((6, n_free + 6))
            T[:, n_free:] = np.eye(6)
            n_free += 6
            maps.append(T)
            return len(maps) - 1

        markers: dict[str, int] = {}
        held: list[tuple[int, Sequence[str]]] = []

        def walk(parts: Sequence[Any], node: int) -> int:
            for part in parts:
                node = add(part, node)
            return node

        def add(part: Any, node: int) -> int:
            if isinstance(part, FEBranch):
                held.append((walk(part.parts, node), part.end_held))
            elif isinstance(part, FEBeam):
                l = part.length / part.elements
                K, Kg, M = _beam_matrices(part, l)
                for _ in range(part.elements):
                    nxt = new_node()
                    blocks.append(([node, nxt], K, Kg, M, part.loss_factor, part.kelvin_voigt_time))
                    node = nxt
            elif isinstance(part, FEBody):
                S = _skew(part.center)
                I_c = np.asarray(part.inertia, dtype=float)
                I_c = np.diag(I_c) if I_c.shape == (3,) else I_c
                Mb = np.block([[part.mass * np.eye(3), -part.mass * S], [part.mass * S, I_c - part.mass * S @ S]])
                blocks.append(([node], np.zeros((6, 6)), np.zeros((6, 6)), Mb, 0.0, 0.0))
                if np.any(part.offset):
                    rigid = np.block([[np.eye(3), -_skew(part.offset)], [np.zeros((3, 3)), np.eye(3)]])
                    maps.append(("slave", node, rigid))
                    node = len(maps) - 1
            elif isinstance(part, (FESpring, FEGround)):
                Ks = np.asarray(part.stiffness, dtype=float)
                Ks = np.diag(Ks) if Ks.shape == (6,) else Ks
                Cs = np.zeros((6, 6)) if part.damping is None else np.asarray(part.damping, dtype=float)
                Cs = np.diag(Cs) if Cs.shape == (6,) else Cs
                if isinstance(part, FEGround):
                    blocks.append(([node], Ks, np.zeros((6, 6)), np.zeros((6, 6)), 0.0, 0.0, Cs))
                else:
                    nxt = new_node()
                    pair = np.array([[1.0, -1.0], [-1.0, 1.0]])
                    blocks.append(([node, nxt], np.kron(pair, Ks), np.zeros((12, 12)),
                                   np.zeros((12, 12)), 0.0, 0.0, np.kron(pair, Cs)))
                    node = nxt
            elif isinstance(part, FEMarker):
                markers[part.name] = node
            else:
                raise TypeError(f"unknown part {part!r}")
            return node

        start = new_node()
        node = walk(self.parts, start)
        held += [(start, self.start_held), (node, self.end_held)]
        # resolve node maps to n_free columns
        resolved: list[np.ndarray] = []
        for entry in maps:
            if isinstance(entry, tuple):
                _, master, rigid = entry
                resolved.append(rigid @ resolved[master])
            else:
                T = np.zeros((6, n_free))
                T[:, :entry.shape[1]] = entry
                resolved.append(T)
        n = n_free
        K, Kg, M, C = (np.zeros((n, n), dtype=complex) for _ in range(4))
        for block in blocks:
            nodes, Ke, Kge, Me, eta, tau = block[:6]
            Ce = block[6] if len(block) > 6 else np.zeros_like(Ke)
            T = np.vstack([resolved[k] for k in nodes])
            cols = np.flatnonzero(np.any(T != 0.0, axis=0))          # the few unknowns the block touches
            T, at = T[:, cols], np.ix_(cols, cols)
            K[at] += T.T @ (Ke * (1 + 1j * eta)) @ T
            Kg[at] += T.T @ Kge @ T
            M[at] += T.T @ Me @ T
            C[at] += T.T @ (Ce + tau * Ke) @ T
        rows = [resolved[k][COMPONENTS.index(c)] for k, names in held for c in names]
        N = scipy.linalg.null_space(np.array(rows)) if rows else np.eye(n)
        self._built = {"K": N.T @ (K + Kg) @ N, "M": (N.T @ M @ N).real, "C": N.T @ C @ N,
                       "maps": [T @ N for T in resolved], "markers": markers}
        return self._built

    def frequencies(self, n_modes: int) -> np.ndarray:
        """Lowest ``n_modes`` undamped natural frequencies [rad/s] (real part of ``K``)."""
        b = self._build()
        K, M = b["K"].real, b["M"]
        K = 0.5 * (K + K.T)
        shift = 1e-6 * np.trace(K) / max(np.trace(M), 1e-300)
        mu = scipy.linalg.eigh(M, K + shift * M, eigvals_only=True)     # mu = 1 / (omega^2 + shift)
        mu = np.sort(mu)[::-1][:n_modes]
        return np.sqrt(np.maximum(1.0 / mu - shift, 0.0))

    def frf(self, omega: Any, load: tuple[str, str], output: tuple[str, str]) -> np.ndarray:
        """Displacement phasor ``output = (marker, component)`` per unit harmonic force / moment
        ``load = (marker, component)`` (component ``ux`` loads ``fx``, ``theta_x`` loads ``mx``, ...)."""
        b = self._build()
        Tl = b["maps"][b["markers"][load[0]]][COMPONENTS.index(load[1])]
        To = b["maps"][b["markers"][output[0]]][COMPONENTS.index(output[1])]
        out = []
        for w in np.atleast_1d(np.asarray(omega, dtype=float)):
            x = np.linalg.solve(b["K"] + 1j * w * b["C"] - w * w * b["M"], Tl.astype(complex))
            out.append(To @ x)
        return np.array(out)

    def mode_displacements(self, n_modes: int, points: Sequence[tuple[str, str]]) -> np.ndarray:
        """``(n_modes, len(points))``: the lowest undamped modes at ``points = [(marker, component), ...]``,
        each mode scaled so that its largest listed entry is +1."""
        b = self._build()
        K, M = b["K"].real, b["M"]
        K = 0.5 * (K + K.T)
        shift = 1e-6 * np.trace(K) / max(np.trace(M), 1e-300)
        mu, X = scipy.linalg.eigh(M, K + shift * M)
        order = np.argsort(mu)[::-1][:n_modes]
        rows = np.array([b["maps"][b["markers"][m]][COMPONENTS.index(c)] for m, c in points])
        out = (rows @ X[:, order]).T
        peak = out[np.arange(n_modes), np.argmax(np.abs(out), axis=1)]
        return out / peak[:, None]
