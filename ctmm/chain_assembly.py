"""Assembly and solution of a 1-D chain in the frequency domain, shared by the frequency verbs.

Every element's ``U(s)`` is evaluated for the whole vector of Laplace variables at once and the
chain is solved by batched Riccati transfer (:mod:`ctmm.assembly`).  Used by
:mod:`ctmm.frequency` (forced response, characteristic function), :mod:`ctmm.natural` (counting
and mode shapes), :mod:`ctmm.sweeps` and the controlled chain's plant (:mod:`ctmm.control.loops`).
A lumped chain asked for some points only (:func:`ctmm.frequency_response`) is solved by the same
recursion in C when a compiler is present (:mod:`ctmm.compiled_chain_frequency`, ``docs/riccati.md`` §7.1).
"""
from __future__ import annotations

from typing import Any, Mapping, Sequence

import numpy as np

from . import validation
from .assembly import SOLVERS, BoundaryEnd, BoundaryStart, ChainSolution
from .elements.axial import AxialBody, AxialJoint
from .errors import ModelError
from .system import Chain


def laplace_variables(omega: Any, name: str = "omega") -> np.ndarray:
    """Laplace variables ``s = j omega`` [1/s] of checked angular frequencies ``omega`` [rad/s].

    Raises :class:`~ctmm.errors.ModelError` naming ``name`` unless ``omega`` is finite and >= 0.
    """
    return 1j * validation.frequencies(name, omega)


def assemble(system: Chain, s: np.ndarray, amplitudes: Mapping[int, Mapping[str, Any]] | None = None, *,
             subdivide: bool = False):
    """Element matrices and boundary relations of ``system`` at Laplace variables ``s``.

    Parameters
    ----------
    system : Chain
    s : ndarray
        1-D array of Laplace variables [1/s].
    amplitudes : mapping, optional
        ``{element position: {input name: phasor}}``.
    subdivide : bool
        Replace every element by the pieces of its :meth:`~ctmm.elements.base.Element.subdivide`
        hook for ``omega_max = max |s|`` (e.g. a long :class:`~ctmm.elements.beams.BeamField`
        by pieces of ``β <= 4``), so that the Riccati transfer stays exact at high frequency.
        The returned lists then hold one entry per *piece*; :func:`subdivided` gives the
        piece index of every connection point.  Ignored for controlled chains.

    Returns
    -------
    Us, us, start, end
        Inputs of :func:`ctmm.assembly.riccati_solve`.
    """
    amplitudes = amplitudes or {}
    if hasattr(system, "assemble_frequency"):  # controlled systems extend the plant's matrices
        return system.assemble_frequency(s, amplitudes)
    s = np.asarray(s)
    if subdivide:
        omega_max = float(np.max(np.abs(s), initial=0.0))
        body, points = subdivided(system, omega_max)
    else:
        body, points = list(system.body), list(range(len(system.body) + 1))
    return assemble_body(system, body, points, s, amplitudes)


def subdivided(system: Chain, omega_max: float) -> tuple[list, list[int]]:
    """Body elements after the :meth:`~ctmm.elements.base.Element.subdivide` hook and, for each
    connection point ``0..N`` of ``system``, its index among the pieces' connection points."""
    body, points = [], [0]
    for element in system.body:
        hook = getattr(element, "subdivide", None)
        pieces = list(hook(omega_max)) if hook is not None and omega_max > 0 else [element]
        body.extend(pieces)
        points.append(len(body))
    return body, points


class MatrixCache:
    """``U(s)`` per element object, evaluated once (subdivided pieces are one repeated object), and
    its load vector without inputs (:meth:`unloaded`, shared by the load cases of :func:`solve_load_cases`)."""

    def __init__(self, s: np.ndarray) -> None:
        self.s = s
        self._cache: dict[int, tuple[Any, np.ndarray]] = {}
        self._unloaded: dict[int, tuple[Any, np.ndarray]] = {}

    def unloaded(self, element) -> np.ndarray:
        """``element.load_vector(s, {})``, evaluated once per element object."""
        hit = self._unloaded.get(id(element))
        if hit is None or hit[0] is not element:
            hit = (element, np.asarray(element.load_vector(self.s, {}), dtype=complex))
            self._unloaded[id(element)] = hit
        return hit[1]

    def __call__(self, element) -> np.ndarray:
        hit = self._cache.get(id(element))
        if hit is None or hit[0] is not element:
            hit = (element, np.asarray(element.transfer_matrix(self.s), dtype=complex))
            self._cache[id(element)] = hit
        return hit[1]


def assemble_body(system: Chain, body: Sequence, points: Sequence[int], s: np.ndarray,
                  amplitudes: Mapping[int, Mapping[str, Any]], matrices: MatrixCache | None = None):
    """Element matrices and boundary relations of the pieces ``body`` of ``system`` (see :func:`assemble`).

    ``points[p]`` is the index among the pieces' connection points of the system's connection
    point ``p`` (from :func:`subdivided`); loads ``amplitudes`` are refused on subdivided elements.
    ``matrices``: a :class:`MatrixCache` over the same ``s`` shared by several load cases (default: a new one).
    """
    layout = system.layout
    owner = {}  # piece index -> position of the system element it belongs to
    for pos in range(1, len(points)):
        for j in range(points[pos - 1], points[pos]):
            owner[j] = pos
    Us, us = [], []
    matrices = MatrixCache(s) if matrices is None else matrices
    for j, element in enumerate(body):
        pos = owner[j]
        amps = amplitudes.get(pos, {})
        if amps and points[pos] - points[pos - 1] > 1:
            raise ModelError(f"element {system.elements[pos].name!r} is subdivided and cannot take loads")
        Us.append(matrices(element))
        us.append(np.asarray(element.load_vector(s, amps), dtype=complex) if amps else matrices.unloaded(element))
    e_idx, S0, P0 = system.start.start(layout, s, amplitudes.get(0, {}))
    Bm, b = system.end.end(layout, s, amplitudes.get(len(system.elements) - 1, {}))
    return Us, us, BoundaryStart(e_idx, S0, P0), BoundaryEnd(Bm, b)


def solve(system: Chain, s: np.ndarray, amplitudes=None, *, solver: str = "riccati",
          want_log_det: bool = False, points: Sequence[int] | None = None,
          compiled: bool | None = None, certify: bool = True) -> ChainSolution:
    """States at every connection point for harmonic loads (phasors), batched over ``s``
    (with ``want_log_det``, the Riccati solvers also return the characteristic log-determinant).
    The Riccati solve of a chain cuts elements with a ``subdivide`` hook (long beams) into exact
    pieces for ``max |s|`` (:func:`subdivided`) and returns the states at the chain's own points.

    ``points``: the connection points whose states are needed.  Lumped chains then return only
    those (:attr:`~ctmm.assembly.ChainSolution.points`; the numpy recursion still keeps ``G_j, r_j``
    of every element, memory ``O(N B)``); other chains return every point.  Read the result with :meth:`~ctmm.assembly.ChainSolution.at`.

    ``compiled``: for lumped chains with ``points``, the recursion in C (:mod:`ctmm.compiled_chain_frequency`,
    memory ``O(N + len(points) B)``, with the log-determinant when wanted): None (default) when a C
    compiler is present, True always (:class:`~ctmm.errors.ModelError` without a compiler), False never.
    Controlled chains on a lumped plant with ``points`` are answered on the same kernel
    (:mod:`ctmm.controlled_chain_frequency`: the loops closed over the plant's responses).
    ``certify=False``: where the compiled recursion answers, non-finite states (a singular end equation) are
    returned instead of refused (the other recursions raise :class:`~ctmm.errors.SingularSystemError` there).
    """
    solver = validation.option("solver", solver, SOLVERS)
    compiled = validation.flag("compiled", compiled, optional=True)
    if solver == "riccati" and not hasattr(system, "assemble_frequency") and is_lumped(system):
        index = getattr(system, "state_index", None)
        sol = _solve_lumped(system, np.asarray(s, dtype=complex), amplitudes or {}, want_log_det,
                            points if index is None else None, compiled, certify)
    elif solver == "riccati" and not hasattr(system, "assemble_frequency"):
        # long fields (BeamField: entries ~ cosh(beta)) lose every digit in one piece at high
        # frequency; their pieces of the subdivide hook keep the transfer exact (states are read
        # back at the system's connection points; log det is a product over pieces, unchanged)
        s = np.asarray(s, dtype=complex)
        body, pieces = subdivided(system, float(np.max(np.abs(s), initial=0.0)))
        Us, us, start, end = assemble_body(system, body, pieces, s, amplitudes or {})
        sol = SOLVERS[solver](Us, us, start, end, want_log_det=want_log_det)
        if len(body) != len(system.body):
            sol.states = sol.states[np.asarray(pieces)]
    else:
        Us, us, start, end = assemble(system, s, amplitudes)
        sol = SOLVERS[solver](Us, us, start, end, want_log_det=want_log_det) if solver == "riccati" else \
            SOLVERS[solver](Us, us, start, end)
    index = getattr(system, "state_index", None)
    if index is not None:  # controlled chains interleave sensing matrices: keep the points only
        sol.states = sol.states[np.asarray(index)]
    return sol


def solve_load_cases(system: Chain, s: np.ndarray, load_cases: Sequence[Mapping[int, Mapping[str, Any]]]
                     ) -> np.ndarray:
    """States ``(len(load_cases), N + 1, B, n)`` of :func:`solve` (Riccati) for several load cases at once.

    A chain with long fields is subdivided and its element matrices ``U(s)`` evaluated once for every
    case; the Riccati sweep (``S_j``, ``G_j``: load-free) runs once with the cases' affine parts
    stacked on a leading axis (:func:`ctmm.assembly.riccati_solve` broadcasts it), so ``k`` cases cost
    about one solve.  The numbers equal ``k`` separate :func:`solve` calls (the same operations entry
    by entry; ``tests/test_manipulator_exact.py`` compares).  Two-component chains (lumped: the scalar
    and compiled recursions) and controlled chains are answered case by case by :func:`solve`.

    Parameters
    ----------
    system : Chain
    s : ndarray
        1-D array of Laplace variables [1/s].
    load_cases : sequence of mapping
        ``{element position: {input name: phasor}}`` per case.
    """
    cases = [case or {} for case in load_cases]
    if len(cases) < 2 or hasattr(system, "assemble_frequency") or system.layout.size == 2:
        return np.stack([solve(system, s, case).states for case in cases]) if cases else np.empty((0,))
    s = np.asarray(s, dtype=complex)
    body, pieces = subdivided(system, float(np.max(np.abs(s), initial=0.0)))
    matrices = MatrixCache(s)
    parts = [assemble_body(system, body, pieces, s, case, matrices) for case in cases]
    Us, _, start, _ = parts[0]

    def shared(arrays: list[np.ndarray]) -> np.ndarray:
        # a load-free part equal in every case stays unstacked, so the sweep of S_j runs once
        return arrays[0] if all(np.array_equal(a, arrays[0]) for a in arrays[1:]) else np.stack(arrays)

    stacked_start = BoundaryStart(start.e_indices, shared([p[2].S0 for p in parts]), np.stack([p[2].P0 for p in parts]))
    stacked_end = BoundaryEnd(shared([p[3].Bm for p in parts]), np.stack([p[3].b for p in parts]))
    us = [np.stack([p[1][j] for p in parts]) for j in range(len(body))]
    states = SOLVERS["riccati"]([U[None] for U in Us], us, stacked_start, stacked_end, want_log_det=False).states
    return np.moveaxis(states[np.asarray(pieces)], 1, 0)


def is_lumped(system: Any) -> bool:
    """True for a chain of lumped axial elements only (springs, dampers, masses, ...): the scalar recursion
    (and the compiled one, :mod:`ctmm.compiled_chain_frequency`) answers it."""
    return system.layout.size == 2 and all(issubclass(kind, (AxialBody, AxialJoint))
                                           for kind in {type(e) for e in system.body})


class _PolynomialCache:
    """``a2 s^2 + a1 s + a0`` (or its reciprocal) over the frequency batch, computed once per distinct
    coefficient triple of one solve (a chain of equal elements evaluates one array, not one per element)."""

    def __init__(self, s: np.ndarray) -> None:
        self.s = s
        self.s2 = s * s
        self.values: dict[tuple, np.ndarray] = {}

    def __call__(self, a2: Any, a1: Any, a0: Any, reciprocal: bool = False) -> np.ndarray:
        key = (a2, a1, a0, reciprocal)
        try:
            cached = self.values.get(key)
        except TypeError:                         # array coefficients: not hashable, not cached
            cached, key = None, None
        if cached is not None:
            return cached
        value = a0 + a1 * self.s + a2 * self.s2 if (a2 or a1) else np.full(self.s.shape, a0, dtype=complex)
        if reciprocal:
            value = 1.0 / value
        if key is not None:
            self.values[key] = value
        return value


def _solve_lumped(system: Chain, s: np.ndarray, amplitudes: Mapping, want_log_det: bool = False,
                  points: Sequence[int] | None = None, compiled: bool | None = None,
                  certify: bool = True) -> ChainSolution:
    """Riccati solve of a 1-D lumped chain from element scalars (impedance, compliance).

    Same recursion as :func:`ctmm.assembly.riccati_solve`; the unit and zero entries of the
    element matrices stay Python scalars instead of ``(B, 2, 2)`` arrays.  With ``points`` given, the
    compiled recursion of :mod:`ctmm.compiled_chain_frequency` answers when ``compiled`` is True, or None
    and a C compiler is present (memory ``O(N + points B)``; the log-determinant too when wanted).
    ``certify=False`` (the compiled recursion only): non-finite states are returned instead of refused.
    """
    from .assembly import riccati_scalar_entries

    e_idx, S0, P0 = system.start.start(system.layout, s, amplitudes.get(0, {}))
    Bm, b = system.end.end(system.layout, s, amplitudes.get(len(system.elements) - 1, {}))
    e = e_idx[0]
    f = 1 - e
    start, end = BoundaryStart(e_idx, S0, P0), BoundaryEnd(Bm, b)
    library = _compiled_library(compiled, points, len(system.body))
    table = None if library is None else _compiled_table(system, amplitudes, f)
    if table is not None:
        from .compiled_chain_frequency import solve_entries

        return solve_entries(library, s, *table, start, end, f, e, points, want_log_det=want_log_det,
                             certify=certify)
    if compiled and library is not None:
        raise ModelError(f"compiled=True: the compiled chain recursion takes float element coefficients; "
                         f"{system.name!r} has others (use compiled=None or False)")
    terms = _lumped_terms(system, amplitudes)
    entries = []
    polynomial = _PolynomialCache(s)
    for joint, (a2, a1, a0), load in terms:
        if joint:   # x_out = x_in - F/k_c (+ F_act/k_c)
            compliance = polynomial(a2, a1, a0, reciprocal=True)
            minus_compliance = polynomial(-a2, -a1, -a0, reciprocal=True)
            ux, uF = (load * compliance if load else 0.0), 0.0
            Uxx, UxF, UFx, UFF = 1.0, minus_compliance, 0.0, 1.0
        else:                                # F_out = F_in - Z x + F
            Uxx, UxF, UFx, UFF = 1.0, 0.0, polynomial(-a2, -a1, -a0), 1.0
            ux, uF = 0.0, -load
        if f == 0:   # partition f = x (displacement known at the start), e = force
            entries.append((Uxx, UxF, UFx, UFF, ux, uF))
        else:        # f = force, e = x
            entries.append((UFF, UFx, UxF, Uxx, uF, ux))
    return riccati_scalar_entries(entries, start, end, f, e, want_log_det, points)


def _lumped_terms(system: Chain, amplitudes: Mapping) -> list[tuple[bool, tuple[Any, Any, Any], Any]]:
    """Per body element: is it a joint, its ``(inertia, damping, stiffness)`` and its load
    (``d tau / d u`` of a joint, ``d h / d u`` of a body, times the amplitudes)."""
    terms = []
    joints: dict[type, bool] = {}
    for pos, element in enumerate(system.body, start=1):
        co = element.axial_coefficients()
        amps = amplitudes.get(pos)
        load = sum((co.inputs[key] * value for key, value in amps.items()), 0.0) if amps else 0.0
        joint = joints.get(type(element))
        if joint is None:
            joint = joints[type(element)] = isinstance(element, AxialJoint)
        terms.append((joint, (co.inertia, co.damping, co.stiffness), load))
    return terms


def _compiled_table(system: Chain, amplitudes: Mapping, f: int):
    """``(unique_of, rows, loads)`` of :func:`ctmm.compiled_chain_frequency.solve_entries` for a lumped chain
    (one pass over the elements), or None when a coefficient is not a float (numpy answers then)."""
    from .compiled_chain_frequency import FIELD, POINT, RECIPROCAL

    field_kind, point_kind = FIELD | RECIPROCAL, POINT     # of a joint, a body in the x-partition (f = 0)
    if f == 1:                                            # the force-partition swaps the two types
        field_kind, point_kind = POINT | RECIPROCAL, FIELD
    rows: dict[tuple, int] = {}                           # distinct elements (kind, -a2, -a1, -a0)
    unique_of, loads = [], {}
    joints: dict[type, bool] = {}
    for j, element in enumerate(system.body):
        co = element.axial_coefficients()
        joint = joints.get(type(element))
        if joint is None:
            joint = joints[type(element)] = isinstance(element, AxialJoint)
        key = (field_kind if joint else point_kind, -co.inertia, -co.damping, -co.stiffness)
        row = rows.get(key)
        if row is None:
            if not all(type(value) is float for value in key[1:]):
                return None
            row = rows[key] = len(rows)
        unique_of.append(row)
        amps = amplitudes.get(j + 1)
        load = sum((co.inputs[name] * value for name, value in amps.items()), 0.0) if amps else 0.0
        if load:                         # joint: u_x = -load v; body: u_F = -load
            x_part, force_part = ((0.0, -load), (0.0, 0.0)) if joint else ((0.0, 0.0), (-load, 0.0))
            loads[j] = (*x_part, *force_part) if f == 0 else (*force_part, *x_part)
    return unique_of, list(rows), loads


def compiled_log_det_applies(system: Any) -> bool:
    """True when the compiled recursion computes the characteristic log-determinant of ``system`` (a lumped chain
    without loops, a C compiler present): :func:`solve` with ``points=()`` and ``want_log_det``."""
    from .compiled_chain_frequency import compiled_library

    return (not hasattr(system, "assemble_frequency") and is_lumped(system) and bool(system.body)
            and compiled_library() is not None)


def _compiled_library(compiled: bool | None, points: Sequence[int] | None, size: int):
    """The compiled recursion's library when it may answer this solve (see :func:`_solve_lumped`), else None."""
    if compiled is False or points is None or not size:
        return None
    from .compiled_chain_frequency import compiled_library

    library = compiled_library()
    if library is None and compiled:
        raise ModelError("compiled=True: the compiled chain recursion needs a C compiler ('gcc' or 'cc' on PATH)")
    return library
