"""Loop numbers as directions in the parameter column of a generated closed-loop step (time derivatives).

With ``numbers="inputs"`` :class:`ctmm.compiled_loops.ClosedLoops` takes every loop's static gain
(``"<loop>.gain"``) or controller realisation (``"<loop>.A[i,j]"``, ``".B[i]"``, ``".C[i]"``, ``".D"``, the
state-space form of ``control.ss``) as entries of the step's parameter column ``p``
(:func:`ctmm.compiled_parameters.loop_parameter_layout`).  The numbers a user names are directions in
that column (the step's derivative along a direction is the derivative with respect to the number):

=======================  ====================================================================
number                   direction (``p`` entries of the loop and their coefficients)
=======================  ====================================================================
``"<loop>.gain"``        static gain ``g``: ``"<loop>.gain"``, 1.  LTI controller: a factor on
                         ``C(s)`` (current value 1): ``C[j]`` by ``C_j``, ``D`` by ``D``
``"<loop>.<sensor>"``    the weight ``w_i`` of a sensor term (e.g. ``kp``, ``kd`` of a PD)
``"<loop>.A[i,j]"``...   one entry of the realisation
=======================  ====================================================================

Sensor weights are constants of the loop's signal ``y = sum_i w_i y_i``; a loop whose weights are
differentiated is stated as one loop per sensor term, ``u = -sum_i C(s) (w_i y_i)`` -- the same closed
loop (the controller, the delay ring and its cubic Hermite interpolation are linear), with term ``i``'s
controller ``w_i C(s)`` (static ``g w_i``; realisation ``(A, B, w_i C, w_i D)``), so that
``d/dw_i = g d/d(g w_i)`` (LTI: along ``C_j``, ``D`` of term ``i``).  Refused (:class:`~ctmm.errors.ModelError`):
delays (``tau = m dt`` is a whole number of steps of the ring: the RK4 solution at a fixed step is not a
differentiable function of it -- use the frequency-domain, margin and abscissa derivatives), weights of
saturated loops (the split is not equivalent through a clip), unknown numbers.
"""
from __future__ import annotations

from typing import Any, Sequence

import numpy as np

from .errors import ModelError, unknown_name

__all__ = ["SEPARATOR", "is_loop_number", "loop_directions", "split_loops"]

SEPARATOR = "__term"
"""Loop-name infix of the per-term loops of a split loop (``"<loop>__term<i>"``)."""


def is_loop_number(loops: Sequence[Any], name: str) -> bool:
    """Whether ``name`` starts with the name of one of ``loops`` (``"<loop>.<number>"``)."""
    return str(name).partition(".")[0] in {lp.name for lp in loops}


def _realisation_names(loop: Any) -> list[str]:
    from .control.planar_time import controller_realisation

    A = controller_realisation(loop)[0]
    k = A.shape[0]
    if k == 0:
        return ["gain"]
    return ([f"A[{i},{j}]" for i in range(k) for j in range(k)] + [f"B[{i}]" for i in range(k)]
            + [f"C[{i}]" for i in range(k)] + ["D"])


def _check(controlled: Any, names: Sequence[str], what: str) -> dict[str, set]:
    """``{loop: requested numbers}``, refusing delays and unknown or unsupported numbers."""
    wanted: dict[str, set] = {}
    for name in names:
        head, _, tail = str(name).partition(".")
        if not is_loop_number(controlled.loops, name):
            continue
        loop = controlled.loop(head)
        allowed = ["gain"] + [sig for sig, _ in loop.terms] + [n for n in _realisation_names(loop) if n != "gain"]
        if tail == "delay":
            raise ModelError(f"{what}: parameter {name!r}: the delay of a generated step is a whole number of steps "
                             "(tau = m dt, a ring of samples), and the RK4 solution at a fixed step is not a "
                             "differentiable function of it; use ctmm.sensitivity's frequency-domain, margin and "
                             "spectral-abscissa derivatives for delays")
        if tail not in allowed:
            raise unknown_name(f"time-differentiable number of loop {head!r}", tail, allowed + ["(delay: refused)"])
        if tail in dict(loop.terms) and loop.saturation is not None:
            raise ModelError(f"{what}: parameter {name!r}: loop {head!r} saturates; its sensor weights are "
                             "differentiated by splitting the loop per sensor term, which is not the same loop "
                             "through a clip (differentiate its gain instead)")
        wanted.setdefault(head, set()).add(tail)
    return wanted


def split_loops(controlled: Any, names: Sequence[str], what: str = "simulation_sensitivity") -> Any:
    """The same closed loop with every loop whose sensor weights are in ``names`` stated per sensor term
    (module docstring): a ``ControlledModel`` (``controlled`` itself when nothing is split)."""
    import control

    from .control.planar_time import controller_realisation
    from .control.loops import Feedback

    wanted = _check(controlled, names, what)
    split = {loop for loop, numbers in wanted.items() if numbers & set(dict(controlled.loop(loop).terms))}
    if not split:
        return controlled
    taken = {lp.name for lp in controlled.loops}
    out = []
    for loop in controlled.loops:
        if loop.name not in split:
            out.append(loop)
            continue
        A, B, C, D = controller_realisation(loop)
        for i, (signal, weight) in enumerate(loop.terms):
            name = f"{loop.name}{SEPARATOR}{i}"
            if name in taken:
                raise ModelError(f"{what}: loop name {name!r} (a term of loop {loop.name!r} split to differentiate its "
                                 "weights) is taken; rename that loop")
            gain = weight * float(loop.gain) if A.shape[0] == 0 else \
                control.ss(A, B.reshape(-1, 1), weight * C.reshape(1, -1), weight * D)
            out.append(Feedback(name, [(signal, 1.0)], loop.actuator, gain=gain, delay=loop.delay,
                                saturation=loop.saturation))
    return controlled.with_loops(out)


def loop_directions(controlled: Any, split: Any, layout: Sequence[tuple[str, str, float]], names: Sequence[str],
                    offset: int, size: int) -> np.ndarray:
    """Directions ``(size, len(names))`` in the parameter column of the step of ``split``
    (:func:`split_loops` of ``controlled``) for the loop numbers among ``names`` (zero columns for the others);
    ``layout`` the step's :attr:`~ctmm.compiled_loops.ClosedLoops.parameter_layout`, placed from ``offset``."""
    from .control.planar_time import controller_realisation

    position = {entry: offset + k for k, (entry, _, _) in enumerate(layout)}
    directions = np.zeros((size, len(names)))
    kept = {lp.name for lp in split.loops}
    for column, name in enumerate(names):
        if not is_loop_number(controlled.loops, name):
            continue
        head, _, tail = str(name).partition(".")
        loop = controlled.loop(head)
        A, B, C, D = controller_realisation(loop)
        k = A.shape[0]
        parts = [(head, 1.0, None)] if head in kept else \
            [(f"{head}{SEPARATOR}{i}", w, i) for i, (_, w) in enumerate(loop.terms)]
        entries: dict[str, float] = {}
        for part, weight, term in parts:
            scale = 1.0 if term is None else weight          # this part's controller is w_i C(s)
            if tail == "gain" or (term is not None and tail == loop.terms[term][0]):
                # gain: d(scale C)/dg along this part's C, D (a static gain g: scale); weight w_i: C, D (static: g)
                factor = scale if tail == "gain" else 1.0
                if k == 0:
                    entries[f"{part}.gain"] = factor * (1.0 if tail == "gain" else float(loop.gain))
                else:
                    entries.update({f"{part}.C[{j}]": factor * C[j] for j in range(k)})
                    entries[f"{part}.D"] = factor * D
            elif tail.startswith(("A[", "B[")):
                entries[f"{part}.{tail}"] = 1.0
            elif tail.startswith(("C[", "D")):
                entries[f"{part}.{tail}"] = scale
        for entry, coefficient in entries.items():
            directions[position[entry], column] += coefficient
    return directions
