"""Trees of spatial beams in the frequency domain: branches condensed onto a main chain.

A :class:`SpatialBeamTree` is a main :class:`~ctmm.Chain` of spatial beam elements
(:mod:`ctmm.spatial_beam_fields`, :mod:`ctmm.spatial_beam_elements`) with **branches**: serial
chains hung at named points of the main chain, each ending in its own boundary.

Condensation.  A branch is a substructure that meets the main chain at one point ``a``; its
dynamic stiffness ``K_b(s)`` (``F_a = K_b d_a``, the force and moment the main chain exerts on
the branch per unit displacement and rotation of ``a``) enters the main chain as a point element
``F_out = F_in - K_b d``.  ``K_b`` comes from an **orthonormal subspace transfer** from the branch's
far end inwards: the states admitted by the far-end boundary span ``Z_n`` (12 x 6); across every
element ``Z_(j-1) = U_j^-1 Z_j R_j^-1`` with ``R_j`` from a QR factorisation (in balanced units), so
the basis stays orthonormal however strongly the fields grow; at the root ``Z_0 = [X; Y]`` and
``K_b = Y X^-1``.  Long fields are cut by their ``subdivide`` hook first.  The branch states
follow from the root displacement by ``c_j = R_j^-1 c_(j-1)``, ``z_j = Z_j c_j``.

Counting (Wittrick-Williams for substructures).  The natural frequencies of the tree below
``omega`` are the Sylvester count of the main chain with every ``K_b`` condensed in, plus for each
branch the number of its natural frequencies with ``a`` clamped (the branch's own ``J0``,
counted by :func:`ctmm.eigenvalue_count` on the branch clamped at ``a``).  ``K_b`` has poles at
those clamped frequencies, so the determinant-sign refinement of :func:`ctmm.natural_frequencies`
(which assumes pole-free element matrices) must not be used: :meth:`SpatialBeamTree.natural_frequencies`
bisects on the certified count alone (to ``rtol``), which cannot be fooled by a pole.

Near a pole of ``K_b`` (relative singular value of the balanced root block below
:data:`POLE_LIMIT`) :meth:`SpatialBeamTree.frequency_response` refuses the frequency (the
condensed stiffness would lose ``eps / ratio``).

Branches of branches.  A branch may carry its own branches (given as ``(elements, {point: ...})``):
they are condensed onto the branch first, recursively, so the branch's subspace transfer crosses
their ``K_b`` as point elements, and the branch's clamped count (its ``J0``) is the count of the
branch with its own branches condensed plus their clamped counts: Wittrick-Williams applied at
every level.  A branch's states at its sub-branch's point give the sub-branch's attachment
displacements.

Not supported (:class:`~ctmm.errors.ModelError`): loads on branches (inputs on the main chain
only), mode shapes, the time domain.  Feedback loops are closed by
:mod:`ctmm.spatial_exact_fields` (a :class:`~ctmm.spatial.model.SpatialModel` tree with ``fields="exact"``)
on the open-loop block :meth:`SpatialBeamTree.open_loop`.
"""
from __future__ import annotations

import time
from typing import Any, Mapping, Sequence

import numpy as np

from . import validation
from .elements.base import Element
from .elements.boundary import Boundary
from .errors import ModelError
from .results import FrequencyResponse
from .spatial_beam_elements import SpatialClamped, SpatialFree, SpatialSupport
from .spatial_beam_fields import SPATIAL_BEAM
from .system import Chain

__all__ = ["SpatialBeamTree", "RIGID_LIMIT", "POLE_LIMIT"]

#: Natural frequencies below this fraction of the search bracket are rigid-body modes, returned as 0 [-].
RIGID_LIMIT = 1e-10
#: Smallest relative singular value of a branch's balanced root block for which frequency_response
#: answers (the condensed stiffness loses about eps / ratio) [-].
POLE_LIMIT = 1e-7


def _balance(Us: Sequence[np.ndarray], sweeps: int = 8) -> np.ndarray:
    """Positive component scaling ``D`` (B, 12) equilibrating rows and columns of ``sum |U - I|``."""
    M = sum(np.abs(U - np.eye(12)) for U in Us) if Us else np.zeros((1, 12, 12))
    logd = np.zeros(M.shape[:-1])
    off = ~np.eye(12, dtype=bool)
    for _ in range(sweeps):
        for i in range(12):
            scaled = M * np.exp(logd[..., :, None] - logd[..., None, :])
            row = np.sum(np.where(off[i], scaled[..., i, :], 0.0), axis=-1)
            col = np.sum(np.where(off[:, i], scaled[..., :, i], 0.0), axis=-1)
            ok = (row > 0) & (col > 0)
            logd[..., i] += np.where(ok, 0.5 * np.log(np.where(ok, col / np.where(ok, row, 1.0), 1.0)), 0.0)
    return np.exp(logd)


def _branch_spec(label: str, spec: Any) -> tuple[list, Mapping[str, Any] | None]:
    """``(elements, branches)`` of a branch given as ``elements`` or ``(elements, {point: ...})``."""
    if isinstance(spec, tuple) and len(spec) == 2 and isinstance(spec[1], Mapping):
        return list(spec[0]), spec[1]
    if isinstance(spec, Mapping) or isinstance(spec, (str, bytes)):
        raise ModelError(f"{label}: give a sequence of elements or (elements, {{point: branch}}), got {spec!r}")
    return list(spec), None


def _all_branches(branches: Mapping[str, "_BranchStiffness"]) -> list["_BranchStiffness"]:
    """Every branch of ``branches`` and, recursively, their branches (parents first)."""
    out = []
    for stiffness in branches.values():
        out += [stiffness, *_all_branches(stiffness.branches)]
    return out


class _BranchStiffness(Element):
    """A branch condensed onto its attachment point (built by :class:`SpatialBeamTree` only).

    Private on purpose: its matrix has poles at the branch's clamped frequencies, which the
    determinant-sign refinement of :func:`ctmm.natural_frequencies` does not expect.

    ``transfer_matrix``: ``F_out = F_in - K_b(s) d`` (module docstring); ``clamped_frequency_count``:
    the branch's natural frequencies with the attachment clamped.

    Parameters
    ----------
    name : str
    elements : sequence of Element
        The branch from the attachment outwards, ending in a boundary.
    branches : mapping, optional
        The branch's own branches, ``{point: elements or (elements, branches)}`` as for
        :class:`SpatialBeamTree` (``point``: an element of this branch, not its end boundary).
    parent : _BranchStiffness, optional
        The branch this one hangs on (None: the main chain).
    """

    layout = SPATIAL_BEAM
    is_point = True

    def __init__(self, name: str, elements: Sequence[Element], branches: Mapping[str, Any] | None = None,
                 parent: "_BranchStiffness | None" = None) -> None:
        super().__init__(name)
        self.parent = parent
        elements = list(elements)
        if not elements or not isinstance(elements[-1], Boundary):
            raise ModelError(f"branch {name!r}: give its elements from the attachment outwards and end it with a "
                             f"boundary (SpatialFree, SpatialClamped, SpatialSupport), got {elements!r}")
        if not isinstance(elements[-1], (SpatialClamped, SpatialFree, SpatialSupport)):
            raise ModelError(f"branch {name!r} must end in SpatialFree, SpatialClamped or SpatialSupport, got "
                             f"{type(elements[-1]).__name__} (an elastic end: SpatialFree after a SpatialGroundSpring)")
        self.branches: dict[str, _BranchStiffness] = {}
        for point, spec in (branches or {}).items():
            names = [getattr(e, "name", None) for e in elements]
            if point not in names[:-1]:
                raise ModelError(f"branch {name!r}: its branch point {point!r} is not one of its elements (before "
                                 f"the end boundary); available: {names[:-1]}")
            own, nested = _branch_spec(f"{name}: branch {point!r}", spec)
            stiffness = _BranchStiffness(f"{point}__branch", own, nested, parent=self)
            elements.insert(names.index(point) + 1, stiffness)
            self.branches[point] = stiffness
        self.clamped = Chain(name, [SpatialClamped(f"{name}__attachment"), *elements])
        if self.clamped.layout is not SPATIAL_BEAM:
            raise ModelError(f"branch {name!r} must be made of spatial beam elements (layout {SPATIAL_BEAM.name!r}), "
                             f"got layout {self.clamped.layout.name!r}")

    @property
    def is_conservative(self) -> bool:
        """False when a branch element is damped."""
        return all(getattr(e, "is_conservative", True) and not np.any(getattr(e, "damping", 0.0))
                   for e in self.clamped.body)

    def parameters(self) -> dict[str, Any]:
        return {"elements": [e.name for e in self.clamped.elements[1:]]}

    def subspaces(self, s: np.ndarray) -> tuple[list[np.ndarray], list[np.ndarray], np.ndarray]:
        """Admissible bases ``Z_p`` (B, 12, 6) at the branch's connection points ``p = 0..n`` (unscaled
        units; orthonormal in balanced units), the triangular factors ``R`` between consecutive points
        (module docstring) and the smallest over largest singular value of the balanced root
        displacement block ``X`` (B,): ~0 at the branch's attachment-clamped frequencies."""
        s = np.atleast_1d(np.asarray(s, dtype=complex))
        omega_max = float(np.max(np.abs(s), initial=0.0))
        pieces, owner = [], []
        for p, element in enumerate(self.clamped.body, start=1):
            hook = getattr(element, "subdivide", None)
            parts = list(hook(omega_max)) if hook is not None and omega_max > 0 else [element]
            pieces += parts
            owner += [p] * len(parts)
        cache: dict[int, np.ndarray] = {}
        Us = []
        for piece in pieces:
            if id(piece) not in cache:
                cache[id(piece)] = np.asarray(piece.transfer_matrix(s), dtype=complex)
            Us.append(cache[id(piece)])
        D = _balance(Us)[:, :, None]                                      # z_scaled = D z
        end = self.clamped.end
        Z = np.zeros((s.size, 12, 6), dtype=complex)
        for column, index in enumerate(end.unknown_indices(SPATIAL_BEAM)):
            Z[:, index, column] = 1.0
        Z, _ = np.linalg.qr(D * Z)
        bases = {len(self.clamped.body): Z}
        factors: dict[int, list[np.ndarray]] = {}
        for j in range(len(pieces) - 1, -1, -1):
            scaled = D * np.linalg.solve(Us[j], Z / D)                    # D U^-1 D^-1 Z
            Z, R = np.linalg.qr(scaled)
            factors.setdefault(owner[j], []).append(R)
            if j == 0 or owner[j - 1] != owner[j]:
                bases[owner[j] - 1] = Z
        n = len(self.clamped.body)
        singular = np.linalg.svd(bases[0][:, :6, :], compute_uv=False)
        ratio = singular[:, -1] / np.maximum(singular[:, 0], np.finfo(float).tiny)
        Zs = [bases[p] / D for p in range(n + 1)]
        Rs = []
        for p in range(1, n + 1):              # c_p = R^-1 c_(p-1) over the pieces of element p (inboard first)
            total = np.broadcast_to(np.eye(6, dtype=complex), (s.size, 6, 6))
            for R in factors[p]:               # appended outboard-first: total = R_inner ... R_outer
                total = R @ total
            Rs.append(total)
        return Zs, Rs, ratio

    def dynamic_stiffness(self, s: Any) -> np.ndarray:
        """``K_b(s)`` (B, 6, 6): force and moment on the branch per unit displacement / rotation of the
        attachment; ``nan`` where the attachment-clamped branch resonates exactly (a pole)."""
        s = np.atleast_1d(np.asarray(s, dtype=complex))
        Z = self.subspaces(s)[0][0]
        X, Y = Z[:, :6, :], Z[:, 6:, :]
        K = np.full((s.size, 6, 6), np.nan, dtype=complex)
        for k in range(s.size):
            try:
                K[k] = np.linalg.solve(X[k].T, Y[k].T).T
            except np.linalg.LinAlgError:
                pass
        return K

    def transfer_matrix(self, s: Any) -> np.ndarray:
        shape = np.shape(s)
        s = np.atleast_1d(np.asarray(s, dtype=complex)).reshape(-1)
        U = np.broadcast_to(np.eye(12, dtype=complex), (s.size, 12, 12)).copy()
        U[:, 6:, :6] = -self.dynamic_stiffness(s)
        return U.reshape(shape + (12, 12))

    def clamped_frequency_count(self, omega: Any) -> np.ndarray:
        """Natural frequencies of the branch with its attachment clamped, strictly below ``omega``."""
        from .natural import eigenvalue_count

        omega = np.asarray(omega, dtype=float)
        return eigenvalue_count(self.clamped, omega.reshape(-1)).reshape(omega.shape)

    def pole_ratio(self, s: np.ndarray) -> np.ndarray:
        """Relative singularity of the root block ``X`` (B,) (:meth:`subspaces`)."""
        return self.subspaces(s)[2]

    def states(self, s: np.ndarray, root: np.ndarray) -> np.ndarray:
        """Branch states (B, n + 1, 12) at its connection points for attachment displacements ``root`` (B, 6)."""
        Zs, Rs, _ = self.subspaces(s)
        c = np.linalg.solve(Zs[0][:, :6, :], root[..., None])
        out = [Zs[0] @ c]
        for p in range(1, len(Zs)):
            c = np.linalg.solve(Rs[p - 1], c)
            out.append(Zs[p] @ c)
        return np.stack([z[..., 0] for z in out], axis=1)


class SpatialBeamTree:
    """A main chain of spatial beam elements with branches (module docstring).

    Parameters
    ----------
    name : str
    elements : sequence of Element
        The main chain ``[start boundary, ..., end boundary]`` (as for :class:`ctmm.Chain`).
    branches : mapping of str to sequence of Element
        ``{point: [element, ..., end boundary]}``: each branch hangs at the outboard point of the
        main-chain element named ``point`` (typically a ``SpatialPointLoad`` marker), listed from
        the attachment outwards; a branch with branches of its own is ``(elements, {point: ...})``
        (its points are its own elements; any depth).  Branch element names must be unique in the
        whole tree.

    Notes
    -----
    The verbs are methods (``ctmm.natural_frequencies`` etc. answer chains, not trees):
    :meth:`natural_frequencies`, :meth:`eigenvalue_count`, :meth:`frequency_response`;
    :meth:`mode_shapes` is refused.
    """

    def __init__(self, name: str, elements: Sequence[Element], branches: Mapping[str, Sequence[Element]]) -> None:
        self.name = validation.name("tree", name)
        main = list(elements)
        names = [getattr(e, "name", None) for e in main]
        if not isinstance(branches, Mapping) or not branches:
            raise ModelError(f"tree {name!r}: branches must be a non-empty mapping {{point: [elements]}}, got "
                             f"{branches!r} (without branches use ctmm.Chain)")
        self._branches: dict[str, _BranchStiffness] = {}
        for point, branch in branches.items():
            if point not in names[1:-1]:
                raise ModelError(f"tree {name!r}: branch point {point!r} is not an element of the main chain; "
                                 f"available: {names[1:-1]}")
            own, nested = _branch_spec(f"tree {name!r}: branch {point!r}", branch)
            stiffness = _BranchStiffness(f"{point}__branch", own, nested)
            main.insert(main.index(next(e for e in main if getattr(e, "name", None) == point)) + 1, stiffness)
            self._branches[point] = stiffness
        self._main = Chain(name, main)
        if self._main.layout is not SPATIAL_BEAM:
            raise ModelError(f"tree {name!r}: the main chain must be made of spatial beam elements")
        seen = {e.name for e in self._main.elements}
        self._owner: dict[str, _BranchStiffness] = {}          # element name -> the branch holding it
        self._every = _all_branches(self._branches)
        for stiffness in self._every:
            for element in stiffness.clamped.elements[1:]:
                if element.name in seen:
                    raise ModelError(f"tree {name!r}: element name {element.name!r} is used twice")
                seen.add(element.name)
                self._owner[element.name] = stiffness

    def eigenvalue_count(self, omega: Any) -> np.ndarray:
        """Number of undamped natural frequencies strictly below each ``omega`` [rad/s] (module docstring)."""
        from .natural import eigenvalue_count

        return eigenvalue_count(self._main, omega)

    def natural_frequencies(self, *, n_modes: int | None = None, omega_max: float | None = None,
                            rtol: float = 1e-14) -> np.ndarray:
        """Lowest ``n_modes`` undamped natural frequencies, or all below ``omega_max`` [rad/s], ascending,
        by bisection on :meth:`eigenvalue_count` to relative width ``rtol`` (rigid-body modes, brackets
        below ``RIGID_LIMIT`` times the search range, as 0)."""
        from .roots1d import bisect_count, count_upper_bound

        if (n_modes is None) == (omega_max is None):
            raise ModelError("give exactly one of n_modes (int >= 1) or omega_max (rad/s > 0)")
        rtol = validation.positive("rtol", rtol)
        if n_modes is not None:
            n_modes = validation.integer("n_modes", n_modes, minimum=1)
            hi = count_upper_bound(self.eigenvalue_count, n_modes, limit=1e15, what=f"tree {self.name!r}")
        else:
            hi = validation.positive("omega_max", omega_max)
            n_modes = int(self.eigenvalue_count([hi])[0])
            if n_modes == 0:
                return np.zeros(0)
        k = np.arange(1, n_modes + 1)
        # no count near omega = 0 is trusted (the fields' O(omega^2) terms drown in round-off there):
        # every bracket starts at [0, hi]; a rigid-body mode's bracket shrinks to 0 and is returned as 0
        lo, up = np.zeros(n_modes), np.full(n_modes, float(hi))
        c_lo = np.zeros(n_modes, dtype=np.int64)
        c_up = np.asarray(self.eigenvalue_count(up[:1]), dtype=np.int64).repeat(n_modes)
        bisect_count(self.eigenvalue_count, k, lo, up, c_lo, c_up, rtol, max_iterations=200)
        roots = 0.5 * (lo + up)
        return np.where(up < RIGID_LIMIT * hi, 0.0, roots)

    def on_branch(self, name: str) -> bool:
        """True when the signal or input ``name`` (``"<element>.<component>"``) belongs to a branch element."""
        return name.split(".")[0] in self._owner

    def open_loop(self, s: np.ndarray, inputs: Sequence[str], outputs: Sequence[str]) -> np.ndarray:
        """``G[k, i_out, i_in]`` at ``s = i omega`` (omega >= 0): signals per unit main-chain input (the
        open-loop block :func:`ctmm.exact_fields.form_response` closes loops on)."""
        s = np.asarray(s)
        if np.any(np.real(s) != 0.0):
            raise ModelError(f"tree {self.name!r}: the open-loop response is on the imaginary axis only, got s = {s!r}")
        response = self.frequency_response(np.imag(s), input=list(inputs), output=list(outputs)).response
        return np.moveaxis(response, -1, 0)

    def mode_shapes(self, **options: Any):
        """Refused: mode shapes of trees are not implemented (use frequency_response near a resonance)."""
        raise ModelError(f"mode_shapes of the spatial beam tree {self.name!r} is not implemented; give the path of "
                         "interest as a ctmm.Chain, or use frequency_response")

    def frequency_response(self, omega: Any, *, input: str | Sequence[str],  # noqa: A002
                           output: str | Sequence[str]) -> FrequencyResponse:
        """FRFs from main-chain inputs (``"<load>.fx"`` ...) to signals anywhere in the tree
        (``"<element>.<component>"``, branch elements included), Riccati transfer on the main chain and
        subspace back-substitution in the branches.

        Returns
        -------
        FrequencyResponse
            ``response[i_out, i_in, k]``.
        """
        from .chain_assembly import solve

        started = time.perf_counter()
        inputs = list(validation.names("input", input))
        outputs = list(validation.names("output", output))
        omega = validation.frequencies("omega", omega)
        for name in inputs:
            if name.split(".")[0] in self._owner:
                raise ModelError(f"tree {self.name!r}: input {name!r} is on a branch; loads on branches are not "
                                 "supported (give the loaded path as the main chain)")
        s = 1j * omega
        for branch in self._every:
            near = np.flatnonzero(branch.pole_ratio(s) < POLE_LIMIT)
            if near.size:
                point = branch.name[:-len("__branch")]
                raise ModelError(f"tree {self.name!r}: omega = {omega[near].tolist()} rad/s lies within ~"
                                 f"{POLE_LIMIT:g} of a natural frequency of the branch at {point!r} with its "
                                 "attachment clamped, where the condensed branch stiffness is singular (the "
                                 "response would lose its digits); evaluate beside it, e.g. omega (1 +- 1e-6)")
        main = [name for name in outputs if name.split(".")[0] not in self._owner]
        needed = set()
        for name in outputs:                   # the branches read and every branch they hang on
            branch = self._owner.get(name.split(".")[0])
            while branch is not None:
                needed.add(branch)
                branch = branch.parent
        root_names = {b: [f"{b.name}.{c}" for c in SPATIAL_BEAM.displacements] for b in needed}
        top = [b for b in needed if b.parent is None]
        asked = list(dict.fromkeys(main + [n for b in top for n in root_names[b]]))
        base = np.empty((len(asked), len(inputs), omega.size), dtype=complex)     # the main chain's responses
        signals = [self._main.signal(name) for name in asked]
        points = sorted({signal.point for signal in signals})
        for i, name in enumerate(inputs):
            entry = self._main.input(name)
            solution = solve(self._main, s, {entry.position: {entry.input: 1.0}}, points=points)
            for o, signal in enumerate(signals):
                base[o, i] = solution.at(signal.point)[:, signal.component] * s ** signal.derivative
        response = np.empty((len(outputs), len(inputs), omega.size), dtype=complex)
        states = {}
        for branch in [b for b in self._every if b in needed]:          # parents before their branches
            for i in range(len(inputs)):
                if branch.parent is None:
                    rows = [asked.index(n) for n in root_names[branch]]
                    root = np.moveaxis(base[rows, i, :], 0, -1)
                else:                          # the parent branch's displacements at this branch's point
                    signals = [branch.parent.clamped.signal(n) for n in root_names[branch]]
                    parent = states[(branch.parent, i)]
                    root = np.stack([parent[:, g.point, g.component] for g in signals], axis=-1)
                states[(branch, i)] = branch.states(s, root)
        for o, name in enumerate(outputs):
            head = name.split(".")[0]
            if head not in self._owner:
                response[o] = base[asked.index(name)]
                continue
            branch = self._owner[head]
            signal = branch.clamped.signal(name)
            for i in range(len(inputs)):
                response[o, i] = states[(branch, i)][:, signal.point, signal.component] * s ** signal.derivative
        info = {"method": "spatial beam tree: Riccati on the main chain, branches condensed (orthonormal subspace "
                          "transfer)", "wall_time_s": time.perf_counter() - started}
        return FrequencyResponse(omega, response, tuple(inputs), tuple(outputs), self.name, info=info)
