"""The modal beam on the element protocol for :class:`ctmm.planar.body_forms.PlanarScene`: an adapter over
:meth:`ctmm.flexible.beam.BeamData.terms` (a numpy routine that writes in place into its work arrays -- a debt of
the one-core migration, plan §2.2, "ModalBeam"; under casadi it runs on object arrays of symbols, ``B = 1``, and
its results are assembled into casadi matrices, :func:`symbolic_beam_terms`)."""
from __future__ import annotations

from typing import Any, Sequence

import numpy as np

from ..ops import Ops
from ..protocol import BodyTerms

__all__ = ["beam_terms", "symbolic_beam_terms"]


def beam_terms(data: Any, points: Sequence[str], theta: np.ndarray, omega: np.ndarray, eta: np.ndarray,
               eta_dot: np.ndarray, t: float, gravity: Sequence[float],
               modal_force: np.ndarray | None = None) -> tuple[BodyTerms, list[tuple[Any, Any]]]:
    """Adapter: :meth:`ctmm.flexible.beam.BeamData.terms` as :class:`BodyTerms` (numpy only).

    ``theta, omega`` (B,), ``eta, eta_dot`` (B, n); ``modal_force`` (n,) an actuator force on the modal
    equations.  Returns the terms and, per point, the end's ``(angle, rate)`` (B,).
    """
    M, h, ends = data.terms(theta, omega, eta, eta_dot, t, gravity)
    h = h[:, :, None]
    if modal_force is not None:
        h = h - np.concatenate([np.zeros((1, 3, 1)), np.asarray(modal_force, float).reshape(1, -1, 1)], axis=1)
    Kin = {name: e[0] for name, e in zip(points, ends)}
    cc = {name: e[1][:, :, None] for name, e in zip(points, ends)}
    RF = {name: e[2] for name, e in zip(points, ends)}
    return BodyTerms(M, h, Kin, cc, RF), [(e[3], e[4]) for e in ends]


def symbolic_beam_terms(ops: Ops, data: Any, points: Sequence[str], theta: Any, omega: Any, eta: np.ndarray,
                        eta_dot: np.ndarray, t: float, gravity: Sequence[float], modal_force: Any = None
                        ) -> tuple[BodyTerms, dict]:
    """:func:`beam_terms` on symbols (casadi): the numpy routine run on object arrays of scalars
    (``B = 1``), its results assembled into ops matrices.  ``eta, eta_dot``: object arrays ``(1, n)``."""
    def scalars(x: Any) -> np.ndarray:
        out = np.empty(1, dtype=object)
        out[0] = ops.block([[x]]) if isinstance(x, (int, float)) else x   # a welded/driven angle: a number (no .cos)
        return out

    def matrix(a: np.ndarray) -> Any:
        a = np.asarray(a, dtype=object)
        a = a.reshape(a.shape[0], -1) if a.ndim == 2 else a
        return ops.block([[a[r, c] for c in range(a.shape[1])] for r in range(a.shape[0])])

    body, ends = beam_terms(data, points, scalars(theta), scalars(omega), eta, eta_dot, t, gravity, None)
    h = body.h[0]
    if modal_force is not None:
        h = h.copy()
        h[3:, 0] = h[3:, 0] - np.asarray(modal_force, dtype=object).reshape(-1)
    terms = BodyTerms(matrix(body.M[0]), matrix(h), {e: matrix(v[0]) for e, v in body.Kin.items()},
                      {e: matrix(v[0]) for e, v in body.c.items()}, {e: matrix(v[0]) for e, v in body.RF.items()})
    return terms, {name: (a[0], r[0]) for name, (a, r) in zip(points, ends)}
