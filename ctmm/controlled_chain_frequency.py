"""Controlled 1-D chains in the frequency domain on the compiled chain recursion (issue 13).

A :class:`~ctmm.control.loops.ControlledChain` embeds each loop ``u_k = -C_k(s) e^{-s tau_k} (y_k - r_k)`` in
extended transfer matrices (two components per loop, :meth:`~ctmm.control.loops.ControlledChain.assemble_frequency`)
solved by the general numpy recursion :func:`ctmm.assembly.riccati_solve`.  In that extended recursion the loop
columns of the Riccati matrix ``S`` are the plant's responses to the loop forces and its pivots are the plant's
(``G`` is block triangular with an identity block), so the same answers follow from plant solves alone:

* the plant (a lumped chain) is solved by the compiled scalar recursion (:mod:`ctmm.compiled_chain_frequency`)
  once for the external loads (states ``x_0``, sensed values ``y_0``) and once per loop for a unit loop force
  (states ``x_k``, sensed values ``Y[:, k]``), at the requested and the sensed points only;
* the loops close per frequency by the small system ``(I + Y diag(g)) y = y_0 + Y diag(g) r`` with
  ``g_k = C_k(s) e^{-s tau_k}`` (delays exact), and the states are ``x = x_0 + sum_k u_k x_k``;
* the characteristic log-determinant of the extended chain is ``log det_plant + log det(-(I + Y diag(g)))``
  (the determinant lemma; the sign is the extended chain's constraint rows ``acc - y = 0``).

Certificates.  The superposition can lose digits where the plant alone responds much more than the closed loop
(a lightly damped plant resonance tamed by the loop: ``x_0`` and ``u_k x_k`` nearly cancel).  Every returned state
and sensed value ``q`` carries the amplification ``A = (|q_0| + sum_k |u_k q_k|) / |q|``; where
``A > AMPLIFICATION_LIMIT`` (or a plant solve or the loop system is singular) those frequencies are answered by
the certified means of the closed loop on a small circle around them (:func:`ctmm.entire_values.circle_mean_logs`;
its points lie off the plant's pole, where the superposition holds): the extended numpy recursion divides by the
plant's pivots too and loses as many digits there (at an undamped plant's natural frequency 0.2-40 % off the dense
closed loop); it answers only where no circle mean is certified (a closed-loop pole next to ``s``).  Without a C compiler, for plants that are not lumped chains and for saturated loops the extended
numpy recursion answers everything (:func:`applies` is False); element coefficients that are not floats put the
plant solves on the numpy scalar recursion (the same superposition and certificate, ``kernel = "numpy"``).
"""
from __future__ import annotations

from typing import Any, Mapping, Sequence

import numpy as np

from .assembly import ChainSolution
from .chain_assembly import compiled_log_det_applies, is_lumped, solve
from .entire_values import circle_mean_logs
from .errors import SingularSystemError

__all__ = ["AMPLIFICATION_LIMIT", "applies", "closed_loop_solve", "compiled_log_det", "log_determinant"]

AMPLIFICATION_LIMIT = 1e4
"""Largest accepted ratio (sum of the superposed moduli) / (modulus of the sum); above it that frequency is answered
by certified circle means (the superposition would lose more than about 4 digits; :func:`_repaired`)."""
ROUND_OFF = 1e-13
"""A component of a point's state below this times its largest component on a whole circle of :func:`_repaired` is
round-off of an exact zero (a free end's force), taken as zero: its noise has no certified mean."""


def applies(system: Any) -> bool:
    """True for a controlled chain on a lumped plant with linear loops and a C compiler present: the compiled
    recursion answers its frequency responses and characteristic function (see the module text)."""
    from .compiled_chain_frequency import compiled_library

    plant = getattr(system, "plant", None)
    loops = getattr(system, "loops", None)
    if plant is None or not loops or not hasattr(system, "assemble_frequency"):
        return False
    if hasattr(plant, "assemble_frequency") or not is_lumped(plant) or not plant.body:
        return False
    if any(getattr(loop, "saturation", None) is not None for loop in loops):
        return False
    return compiled_library() is not None


def _loop_terms(system: Any) -> tuple[list, list]:
    """Per loop: the plant inputs of its unit force ``{position: {input: weight}}`` and its sensed terms
    ``[(point, component, derivative, weight)]`` (public names resolved on the plant)."""
    plant = system.plant
    actuators, sensed = [], []
    for loop in system.loops:
        amplitudes: dict[int, dict[str, float]] = {}
        for name, weight in loop.actuator_terms:
            element_name, _, input_name = name.partition(".")
            resolved = plant.input(f"{element_name}.{input_name or plant.element(element_name).inputs[0]}")
            slot = amplitudes.setdefault(resolved.position, {})
            slot[resolved.input] = slot.get(resolved.input, 0.0) + weight
        actuators.append(amplitudes)
        terms = []
        for name, weight in loop.terms:
            signal = plant.signal(name)
            terms.append((signal.point, signal.component, signal.derivative, float(weight)))
        sensed.append(terms)
    return actuators, sensed


def _plant_solves(system: Any, s: np.ndarray, plant_amplitudes: Mapping, points: Sequence[int],
                  want_log_det: bool) -> tuple[list[ChainSolution | None], list]:
    """Compiled plant solves: external loads (None when there are none) and one per loop's unit force."""
    actuators, sensed = _loop_terms(system)
    plant = system.plant
    external = solve(plant, s, dict(plant_amplitudes), points=points, want_log_det=want_log_det,
                     certify=False) if plant_amplitudes or want_log_det else None
    unit = [solve(plant, s, amplitudes, points=points, certify=False) for amplitudes in actuators]
    return [external, *unit], sensed


def _sensed_values(solution: ChainSolution | None, terms: list, s: np.ndarray) -> np.ndarray:
    if solution is None:
        return np.zeros(s.shape, dtype=complex)
    return sum((weight * solution.at(point)[:, component] * s ** derivative
                for point, component, derivative, weight in terms), np.zeros(s.shape, dtype=complex))


def _loop_matrix(system: Any, s: np.ndarray, unit: list, sensed: list) -> tuple[np.ndarray, np.ndarray]:
    """``Y`` (B, nl, nl): sensed value ``i`` per unit force of loop ``k``, and the loop gains ``g`` (B, nl)."""
    Y = np.stack([np.stack([_sensed_values(solution, terms, s) for solution in unit], axis=-1)
                  for terms in sensed], axis=1)
    gains = np.stack([np.broadcast_to(np.asarray(loop.loop_gain(s), dtype=complex), s.shape)
                      for loop in system.loops], axis=-1)
    return Y, gains


def closed_loop_solve(system: Any, s: np.ndarray, amplitudes: Mapping[Any, Mapping[str, Any]],
                      points: Sequence[int], *, repair: bool = True) -> ChainSolution:
    """States of ``system`` (a controlled chain, :func:`applies`) at plant connection ``points`` with the loops
    closed, in the extended layout of :meth:`~ctmm.control.loops.ControlledChain.assemble_frequency`
    (plant components, then ``y_k``, accumulator of loop ``k``).

    Parameters
    ----------
    system : ControlledChain
    s : ndarray, shape (B,)
        Laplace variables [1/s].
    amplitudes : mapping
        ``{plant element position: {input name: phasor}, loop name: {"reference": phasor}}``.
    points : sequence of int
        Plant connection points to return, in that order.
    repair : bool
        Answer the frequencies that fail the certificate by :func:`_repaired` (certified circle means); False:
        by the extended numpy recursion directly (the evaluations on the circles).

    Returns
    -------
    ChainSolution
        ``states`` ``(len(points), B, d + 2 nl)``; ``kernel = "compiled"`` (``"compiled/numpy"`` when some
        frequencies failed the certificate and were answered by :func:`_repaired`).

    Raises
    ------
    SingularSystemError
        The closed loop is singular at some frequencies (from the extended numpy recursion).
    """
    s = np.asarray(s, dtype=complex)
    plant_amplitudes = {key: value for key, value in amplitudes.items() if not isinstance(key, str)}
    references = np.array([amplitudes.get(loop.name, {}).get("reference", 0.0) for loop in system.loops],
                          dtype=complex)
    rows = [int(j) for j in points]
    actuators, sensed = _loop_terms(system)
    sensed_points = sorted({point for terms in sensed for point, *_ in terms})
    wanted = sorted(set(rows) | set(sensed_points))
    try:                      # coefficients that are not floats: the numpy scalar recursion refuses singular plants
        solutions, sensed = _plant_solves(system, s, plant_amplitudes, wanted, False)
    except SingularSystemError:
        return ChainSolution(_extended_numpy(system, s, amplitudes, rows), np.zeros(s.size, dtype=complex),
                             tuple(rows), kernel="numpy")
    external, unit = solutions[0], solutions[1:]
    Y, gains = _loop_matrix(system, s, unit, sensed)
    nl, B = len(system.loops), s.size
    y0 = np.stack([_sensed_values(external, terms, s) for terms in sensed], axis=-1)
    with np.errstate(all="ignore"):
        matrix = np.eye(nl) + Y * gains[:, None, :]
        rhs = y0 + np.einsum("bik,bk->bi", Y, gains * references)
        try:
            y = np.linalg.solve(matrix, rhs[..., None])[..., 0]
        except np.linalg.LinAlgError:
            y = np.full((B, nl), np.nan, dtype=complex)
        forces = -gains * (y - references)
        d0 = system.plant.layout.size
        plant_states = np.zeros((len(wanted), B, d0), dtype=complex)
        magnitude = np.zeros((len(wanted), B, d0))
        for index, point in enumerate(wanted):
            if external is not None:
                plant_states[index] = external.at(point)
                magnitude[index] = np.abs(external.at(point))
            for k, solution in enumerate(unit):
                term = forces[:, k, None] * solution.at(point)
                plant_states[index] += term
                magnitude[index] += np.abs(term)
        amplification = np.where(magnitude > 0, magnitude / np.abs(plant_states), 1.0)
        terms = Y * forces[:, None, :]                   # the sensed values: y = y_0 + Y u, the same check
        sensed_magnitude = np.abs(y0) + np.sum(np.abs(terms), axis=2)
        sensed_amplification = np.where(sensed_magnitude > 0, sensed_magnitude / np.abs(y), 1.0)
    good = np.all(np.isfinite(plant_states), axis=(0, 2)) & np.all(np.isfinite(y), axis=1)
    good &= np.all(amplification <= AMPLIFICATION_LIMIT, axis=(0, 2))
    good &= np.all(sensed_amplification <= AMPLIFICATION_LIMIT, axis=1)
    n = d0 + 2 * nl
    states = np.empty((len(rows), B, n), dtype=complex)
    position = {point: index for index, point in enumerate(wanted)}
    for index, point in enumerate(rows):
        states[index, :, :d0] = plant_states[position[point]]
        states[index, :, d0::2] = y
        for k, terms in enumerate(sensed):      # the accumulator: sensed terms up to and at this point
            states[index, :, d0 + 2 * k + 1] = sum(
                (weight * plant_states[position[p]][:, c] * s ** deriv for p, c, deriv, weight in terms if p <= point),
                np.zeros(B, dtype=complex))
    kernel = "compiled" if all(solution is None or solution.kernel == "compiled" for solution in solutions) \
        else "numpy"
    if not good.all():
        bad = np.flatnonzero(~good)
        states[:, bad] = (_repaired if repair else _extended_numpy)(system, s[bad], amplitudes, rows)
        kernel = f"{kernel}/numpy" if good.any() and kernel != "numpy" else "numpy"
    return ChainSolution(states, np.zeros(B, dtype=complex), tuple(rows), kernel=kernel)


def _repaired(system: Any, s: np.ndarray, amplitudes: Mapping, rows: Sequence[int]) -> np.ndarray:
    """States at ``rows`` where the superposition is not certified: at or next to a pole of the plant, where the
    plant's Riccati pivot vanishes.  The extended numpy recursion divides by the same pivots (they are the plant's)
    and loses as many digits there (at an undamped plant's natural frequency, closed by a loop: 0.2-40 % off the
    dense closed loop), but the closed loop is analytic around such an ``s``: its states are the certified means
    on a small circle around it (:func:`ctmm.entire_values.circle_mean_logs`, whose points lie off the pole).  The
    extended numpy recursion answers where no circle mean is certified (a closed-loop pole next to ``s``)."""
    n = system.plant.layout.size + 2 * len(system.loops)
    states = np.empty((len(rows), s.size, n), dtype=complex)
    for k, point in enumerate(s):
        def logs(circle: np.ndarray) -> np.ndarray:
            values = closed_loop_solve(system, circle, amplitudes, rows, repair=False).states
            size = np.abs(values).max(axis=1, keepdims=True)       # a component that is round-off of its
            values = np.where(size > ROUND_OFF * size.max(axis=2, keepdims=True), values, 0.0)   # point: zero
            with np.errstate(divide="ignore"):
                return np.log(np.moveaxis(values, 1, -1).reshape(-1, circle.size))
        try:
            states[:, k] = np.exp(circle_mean_logs(logs, point, label="the closed loop's states")).reshape(
                len(rows), n)
        except SingularSystemError:
            states[:, k] = _extended_numpy(system, s[k:k + 1], amplitudes, rows)[:, 0]
    return states


def _extended_numpy(system: Any, s: np.ndarray, amplitudes: Mapping, rows: Sequence[int]) -> np.ndarray:
    """States at ``rows`` by the extended numpy recursion (the named fallback)."""
    solution = solve(system, s, amplitudes)
    return solution.states[np.asarray(rows, dtype=int)]


def log_determinant(system: Any, s: np.ndarray) -> np.ndarray:
    """Characteristic log-determinant of the extended chain of ``system`` (:func:`applies`) at ``s``, equal to the
    numpy recursion's (:func:`ctmm.assembly.riccati_solve`) modulo ``2 pi i``; NaN where a plant solve is singular
    and the extended numpy recursion fails too (the callers repair those by circle means)."""
    s = np.asarray(s, dtype=complex)
    _, sensed = _loop_terms(system)
    sensed_points = sorted({point for terms in sensed for point, *_ in terms})
    try:
        solutions, sensed = _plant_solves(system, s, {}, sensed_points, True)
        Y, gains = _loop_matrix(system, s, solutions[1:], sensed)
        with np.errstate(all="ignore"):
            matrix = -(np.eye(len(system.loops)) + Y * gains[:, None, :])
            finite = np.all(np.isfinite(matrix), axis=(1, 2))
            matrix[~finite] = 1.0
            sign, logabs = np.linalg.slogdet(matrix)
            log_det = np.where(finite, solutions[0].log_det + np.log(sign.astype(complex)) + logabs, np.nan)
    except SingularSystemError:
        log_det = np.full(s.shape, np.nan, dtype=complex)
    bad = ~np.isfinite(log_det)
    if bad.any():
        from .chain_assembly import assemble
        from .assembly import riccati_solve

        with np.errstate(all="ignore"):
            try:
                Us, us, start, end = assemble(system, s[bad])
                log_det[bad] = riccati_solve(Us, us, start, end, want_states=False).log_det
            except (np.linalg.LinAlgError, SingularSystemError):
                log_det[bad] = np.nan
    return log_det


def compiled_log_det(system: Any, s: np.ndarray) -> np.ndarray | None:
    """The characteristic log-determinant of a lumped chain or of a controlled chain on a lumped plant by the
    compiled recursion (NaN where its sweep fails; the callers repair those by circle means), or None when the
    compiled recursion does not answer ``system`` (beams, no C compiler: the callers' numpy recursion then)."""
    s = np.asarray(s, dtype=complex)
    if applies(system):
        return log_determinant(system, s)
    if compiled_log_det_applies(system):
        try:        # coefficients that are not floats: the numpy scalar recursion, which refuses singular ends
            return solve(system, s, points=(), want_log_det=True, certify=False).log_det
        except SingularSystemError:
            return None
    return None
