"""Closing feedback loops on open-loop frequency responses (phasor algebra, exact delays).

Given the open-loop responses of a linear plant from its plain inputs ``w`` and loop forces
``u`` to its plain outputs ``z`` and loop measurements ``y`` (``G_zw, G_zu, G_yw, G_yu`` per
frequency) and the loop gains ``K = diag(C_l(s) e^{-s tau_l})`` of loops ``u = -K (y - r)``:

``(I + K G_yu) u = K (r - G_yw w)``,  ``z = G_zw w + G_zu u``,  ``y = G_yw w + G_yu u``.

Used by the planar frequency verbs (on the linearisation, :mod:`ctmm.planar_frequency`) and by
the exact-field form (on the bending chain, :mod:`ctmm.exact_fields`).
"""
from __future__ import annotations

from typing import Sequence

import numpy as np

__all__ = ["close_loops", "loop_signal"]


def loop_signal(name: str, index: dict[str, int], parts: tuple[str, ...]) -> tuple[int, str] | None:
    """``(loop index, part)`` when ``name`` is ``"<loop>.<part>"`` of a loop in ``index`` (loop name -> index) with
    ``part`` in ``parts`` (e.g. ``("reference",)`` or ``("y", "u")``); ``None`` for any other name (a plant port)."""
    head, _, tail = name.partition(".")
    return (index[head], tail) if head in index and tail in parts else None


def close_loops(blocks: tuple, K: np.ndarray, inputs: Sequence[str], outputs: Sequence[str],
                plain_inputs: Sequence[str], plain_outputs: Sequence[str], index: dict[str, int]) -> np.ndarray:
    """Closed-loop responses ``response[i_out, i_in, k]`` (module docstring).

    Parameters
    ----------
    blocks : (G_zw, G_zu, G_yw, G_yu)
        Open-loop responses, each ``(n_frequencies, rows, columns)``: rows ``plain_outputs``
        / loops, columns ``plain_inputs`` / loops.
    K : ndarray, shape (n_frequencies, n_loops, n_loops)
        Loop gains ``C_l(s) e^{-s tau_l}`` on the diagonal.
    inputs, outputs : sequence of str
        Requested names: plain ones, ``"<loop>.reference"`` inputs and ``"<loop>.y"`` /
        ``"<loop>.u"`` outputs.
    plain_inputs, plain_outputs : sequence of str
        The plain names, in the order of the blocks' columns / rows.
    index : dict
        Loop name -> loop index (the order of ``K``); names are read by :func:`loop_signal`.
    """
    Gzw, Gzu, Gyw, Gyu = blocks
    n_frequencies, n_loops = K.shape[0], K.shape[1]
    E_w = np.zeros((len(plain_inputs), len(inputs)))
    E_r = np.zeros((n_loops, len(inputs)))
    for k, name in enumerate(inputs):
        loop = loop_signal(name, index, ("reference",))
        if loop is None:
            E_w[list(plain_inputs).index(name), k] = 1.0
        else:
            E_r[loop[0], k] = 1.0
    u = (np.linalg.solve(np.eye(n_loops) + K @ Gyu, K @ (E_r - Gyw @ E_w)) if n_loops
         else np.zeros((n_frequencies, 0, len(inputs))))
    z = Gzw @ E_w + Gzu @ u
    y = Gyw @ E_w + Gyu @ u
    response = np.empty((len(outputs), len(inputs), n_frequencies), dtype=complex)
    for k, name in enumerate(outputs):
        loop = loop_signal(name, index, ("y", "u"))
        rows = z[:, list(plain_outputs).index(name)] if loop is None else (y if loop[1] == "y" else u)[:, loop[0]]
        response[k] = rows.T
    return response
