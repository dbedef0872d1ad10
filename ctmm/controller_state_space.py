"""The one state-space realisation of a feedback loop's controller ``C(s)``.

Every path that needs the controller as states (the time drivers and their generated kernels, the
trapezoidal DT-TMM form, the LFT closing of ``ctmm.linearize`` / ``to_state_space``, the state-space
characteristic of a delayed loop, the certificate's state-space bound) realises it here, so they share
one set of checks and one message:

* a static gain (a number) is ``D`` alone (no states);
* an LTI ``C(s)`` is ``control.ss(C)``: it must be SISO, proper (an improper ``kp + kd s`` has no
  finite-dimensional realisation; the frequency-domain verbs take it as it is) and have finite
  coefficients (a NaN pole would otherwise run on as NaN states in one path and stop another).

The controller law is ``z' = A z + B e``, ``u = C z + D e`` with ``e`` the sensed signal; the sign the
loop applies (``u = -(...)`` in the time drivers) stays with the caller.
"""
from __future__ import annotations

from typing import Any

import numpy as np

from .errors import ModelError

__all__ = ["controller_state_space"]

IMPROPER_ADVICE = ("an improper PD kp + kd s is the sensor terms [(signal, kp), (its rate, kd)] with gain=1, or add "
                   "a derivative filter; the frequency-domain verbs (frequency_response, margins, to_frd) take it "
                   "as it is")
"""What the refusal of an improper ``C(s)`` suggests."""


def controller_state_space(name: str, gain: Any, purpose: str = "in time"
                           ) -> tuple[np.ndarray, np.ndarray, np.ndarray, float]:
    """``(A, B, C, D)`` of a loop's controller ``z' = A z + B e``, ``u = C z + D e``.

    Parameters
    ----------
    name : str
        The loop's name (for the messages).
    gain : float or control.LTI
        A static gain [actuator unit per sensed unit] or a SISO continuous-time python-control system.
    purpose : str
        What needs the realisation, completing "the controller C(s) cannot be realised ..." (e.g.
        ``"in time"``, ``"by to_state_space"``).

    Returns
    -------
    A : ndarray, shape (k, k)
        State matrix [1/s].
    B, C : ndarray, shape (k,)
        Input and output vectors (``k = 0`` for a static gain).
    D : float
        Feedthrough [actuator unit per sensed unit].

    Raises
    ------
    ModelError
        An improper, non-SISO or non-finite ``C(s)``, naming the loop.
    """
    import control

    if not isinstance(gain, control.LTI):
        return np.zeros((0, 0)), np.zeros(0), np.zeros(0), float(gain)
    if gain.ninputs != 1 or gain.noutputs != 1:
        raise ModelError(f"loop {name!r}: the controller must be SISO, got {gain.ninputs} inputs and "
                         f"{gain.noutputs} outputs")
    try:
        ss = control.ss(gain)
    except (ValueError, TypeError) as exc:     # improper: no finite-dimensional realisation
        raise ModelError(f"loop {name!r}: the controller C(s) cannot be realised {purpose} ({exc}); "
                         f"{IMPROPER_ADVICE}") from None
    k = int(ss.nstates)
    A, B, C = (np.asarray(m, dtype=float) for m in (ss.A, ss.B, ss.C))
    D = float(np.asarray(ss.D, dtype=float).reshape(-1)[0])
    for label, matrix in zip("ABCD", (A, B, C, np.array([D]))):
        if not np.all(np.isfinite(matrix)):
            raise ModelError(f"loop {name!r}: the controller C(s) has a non-finite coefficient (state-space "
                             f"{label} = {matrix.tolist()!r}); every coefficient must be finite")
    return A.reshape(k, k), B.reshape(k), C.reshape(k), D
