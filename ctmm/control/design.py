"""Control design on a cached plant: closed loops for new gains without re-running the TMM.

A :class:`PlantCache` evaluates the *open-loop* plant of a
:class:`~ctmm.control.loops.ControlledChain` once on a frequency grid with the TMM (one
Riccati sweep per input over all frequencies) and keeps four blocks of frequency-response data:

=========  ===========================================================================
``P_yu``   sensed value of every loop per unit force at every loop's actuator
``P_yw``   sensed values per unit exogenous input (``"m4.force"``, ...)
``P_zu``   requested outputs per unit actuator force
``P_zw``   requested outputs per unit exogenous input
=========  ===========================================================================

With ``K(i w) = diag(C_l(i w) e^{-i w tau_l})`` and ``u = -K (y - r)``, the closed loop follows
by per-frequency linear algebra on ``n_loops x n_loops`` matrices:

    u = (I + K P_yu)^{-1} K (r - P_yw w)
    H_zw = P_zw - P_zu (I + K P_yu)^{-1} K P_yw,     H_zr = P_zu (I + K P_yu)^{-1} K,

(``(I + K P_yu)^{-1} K = K (I + P_yu K)^{-1}``), and the loop transfer function of loop ``l``
with the others closed is ``L_l = K_l [P_yu - P_yu,:o K_o (I + P_yu,oo K_o)^{-1} P_yu,o:]_ll``.
Nothing of the plant is rebuilt or re-factored: one evaluation costs a batched ``solve`` of
``n_loops x n_loops`` systems -- microseconds per frequency instead of a TMM sweep.  This is the
inner loop of gain tuning (``scenarios/pd_tuning.py``).
"""
from __future__ import annotations

from typing import Any, Mapping, Sequence

import numpy as np

from .. import validation
from ..errors import ModelError, unknown_name
from ..frequency import frequency_response
from ..results import FrequencyResponse
from .analysis import actuator_inputs
from .loops import ControlledChain, Feedback

__all__ = ["PlantCache"]


AMPLIFICATION_LIMIT = 1e8
"""Largest accepted ratio (sum of the superposed moduli) / (modulus of the sum) in :meth:`PlantCache.closed_loop`:
beyond it more than half of the digits would be lost (refused)."""


def _refuse_lost_digits(call: str, omega: np.ndarray, lost: np.ndarray, what: str) -> None:
    """Refuse the frequencies where ``lost`` (sum of the superposed moduli / modulus of the sum) exceeds
    :data:`AMPLIFICATION_LIMIT`, naming them."""
    if np.any(lost > AMPLIFICATION_LIMIT):
        bad = omega[lost > AMPLIFICATION_LIMIT]
        raise ModelError(f"{call}: at omega = {np.round(bad[:5], 6).tolist()} rad/s the {what} is a difference of "
                         f"plant responses up to {np.max(lost):.3g} times larger than it (a plant resonance the loops "
                         "tame) and would lose as many digits; there use ctmm.frequency_response or "
                         "ctmm.control.loop_transfer_function of the controlled chain with these gains, or leave "
                         "those frequencies out of the grid")


class PlantCache:
    """Open-loop plant data of a controlled chain on a frequency grid, for fast loop design.

    Parameters
    ----------
    system : ControlledChain
        Defines the loops (sensors, actuators) and their current gains/delays.  Only the
        loop *structure* is cached; gains, controllers and delays are free afterwards.
    omega : array_like
        Angular frequencies [rad/s].
    inputs : str or sequence of str
        Exogenous inputs: plant inputs (``"m4.force"``) and loop references
        (``"<loop>.reference"``).
    outputs : str or sequence of str
        Outputs: plant signals (``"m2.x"``, ``"k3.f"``) and loop signals (``"<loop>.y"``,
        ``"<loop>.u"``).

    Examples
    --------
    >>> import numpy as np, ctmm
    >>> from ctmm.elements import Fixed, SpringDamper, Mass, Free
    >>> from ctmm.control import Feedback, ControlledChain
    >>> plant = ctmm.Chain("two", [Fixed("g"), SpringDamper("k1", 100.0, 0.5), Mass("m1", 1.0),
    ...                            SpringDamper("k2", 100.0, 0.5), Mass("m2", 1.0), Free("e")])
    >>> system = ControlledChain(plant, [Feedback("pd", "m2.v", "m1", gain=1.0)])
    >>> cache = PlantCache(system, np.linspace(1, 30, 200), inputs="m2.force", outputs="m2.x")
    >>> frf = cache.closed_loop(gains={"pd": 4.0})          # no TMM sweep here
    >>> direct = ctmm.frequency_response(system.with_loops([system.loop("pd").with_parameters(gain=4.0)]),
    ...                                  cache.omega, input="m2.force", output="m2.x")
    >>> bool(np.allclose(frf.response, direct.response, rtol=1e-10, atol=0))
    True
    """

    def __init__(self, system: ControlledChain, omega: Any, *, inputs: str | Sequence[str],
                 outputs: str | Sequence[str]) -> None:
        if not isinstance(system, ControlledChain):
            raise ModelError(f"PlantCache needs a ControlledChain (the loops define sensors and actuators), "
                             f"got {system!r}")
        if not system.loops:
            raise ModelError("PlantCache needs at least one Feedback loop")
        self.system = system
        self.omega = validation.frequencies("omega", omega)
        self.inputs = validation.names("inputs", inputs)
        self.outputs = validation.names("outputs", outputs)
        self.loops: tuple[Feedback, ...] = tuple(system.loops)
        self._loop_index = {lp.name: i for i, lp in enumerate(self.loops)}
        plant = system.plant
        nl = len(self.loops)
        # classify names
        self._w_kind = []    # ("plant", name) or ("reference", loop index)
        for name in self.inputs:
            head, _, tail = name.partition(".")
            if head in self._loop_index:
                if tail != "reference":
                    raise unknown_name("input", name, system.input_names())
                self._w_kind.append(("reference", self._loop_index[head]))
            else:
                plant.input(name)
                self._w_kind.append(("plant", name))
        self._z_kind = []    # ("plant", name) or ("y"/"u", loop index)
        for name in self.outputs:
            head, _, tail = name.partition(".")
            if head in self._loop_index:
                if tail not in ("y", "u"):
                    raise unknown_name("signal", name, system.signal_names())
                self._z_kind.append((tail, self._loop_index[head]))
            else:
                system.signal(name)
                self._z_kind.append(("plant", name))
        actuators = [actuator_inputs(system, lp.name) for lp in self.loops]   # [(input, weight), ...] per loop
        plant_inputs = list(dict.fromkeys([a for terms in actuators for a, _ in terms]
                                          + [n for k, n in self._w_kind if k == "plant"]))
        sensed = [sig for lp in self.loops for sig, _ in lp.terms]
        plant_outputs = list(dict.fromkeys(sensed + [n for k, n in self._z_kind if k == "plant"]))
        frf = frequency_response(plant, self.omega, input=plant_inputs, output=plant_outputs)
        self.plant_response = frf
        nw = self.omega.size

        def y_row(lp: Feedback, inp: str) -> np.ndarray:
            total = np.zeros(nw, dtype=complex)
            for sig, weight in lp.terms:
                total = total + weight * frf(sig, inp)
            return total

        def to_actuator(response, terms) -> np.ndarray:   # response(input) summed over the loop's inputs
            return sum(weight * response(inp) for inp, weight in terms)

        # arrays with the frequency axis first: (nw, rows, cols)
        self.P_yu = np.stack([np.stack([to_actuator(lambda inp, lp=lp: y_row(lp, inp), terms) for terms in actuators],
                                       -1) for lp in self.loops], -2)
        nwx = len(self.inputs)
        self.P_yw = np.zeros((nw, nl, nwx), dtype=complex)
        self.P_zu = np.zeros((nw, len(self.outputs), nl), dtype=complex)
        self.P_zw = np.zeros((nw, len(self.outputs), nwx), dtype=complex)
        for j, (kind, name) in enumerate(self._w_kind):
            if kind == "plant":
                for i, lp in enumerate(self.loops):
                    self.P_yw[:, i, j] = y_row(lp, name)
        for o, (kind, name) in enumerate(self._z_kind):
            if kind != "plant":
                continue
            for i, terms in enumerate(actuators):
                self.P_zu[:, o, i] = to_actuator(lambda inp, name=name: frf(name, inp), terms)
            for j, (wkind, wname) in enumerate(self._w_kind):
                if wkind == "plant":
                    self.P_zw[:, o, j] = frf(name, wname)

    # -- controller data ----------------------------------------------------------------
    def loop_gains(self, gains: Mapping[str, Any] | None = None,
                   delays: Mapping[str, float] | None = None) -> np.ndarray:
        """``K_l(i w) = C_l(i w) e^{-i w tau_l}`` for every loop, shape ``(n_omega, n_loops)``.

        Parameters
        ----------
        gains : mapping, optional
            ``{loop name: gain}``: a float, a python-control SISO LTI ``C(s)``, or a complex array of
            ``C(i w)`` on :attr:`omega`.  Loops not named keep the system's controller.
        delays : mapping, optional
            ``{loop name: delay [s]}``; loops not named keep their delay.
        """
        for label, given in (("gains", gains), ("delays", delays)):
            if given is not None and not isinstance(given, Mapping):
                raise ModelError(f"{label} must be a mapping {{loop name: value}} or None, got {given!r}")
        gains = dict(gains or {})
        delays = dict(delays or {})
        for name in list(gains) + list(delays):
            if name not in self._loop_index:
                raise unknown_name("loop", name, list(self._loop_index))
        s = 1j * self.omega
        K = np.empty((self.omega.size, len(self.loops)), dtype=complex)
        for i, lp in enumerate(self.loops):
            g = gains.get(lp.name, None)
            if isinstance(g, np.ndarray) and g.ndim == 1 and g.size == self.omega.size:
                if not np.all(np.isfinite(g)):
                    raise ModelError(f"loop {lp.name!r}: controller response must be finite")
                tau = lp.with_parameters(delay=delays.get(lp.name, None)).delay
                K[:, i] = g.astype(complex) * np.exp(-s * tau)
            else:
                K[:, i] = lp.with_parameters(gain=g, delay=delays.get(lp.name, None)).loop_gain(s)
        return K

    # -- closed loop --------------------------------------------------------------------
    def closed_loop(self, *, gains: Mapping[str, Any] | None = None,
                    delays: Mapping[str, float] | None = None) -> FrequencyResponse:
        """Closed-loop responses from :attr:`inputs` to :attr:`outputs` for new gains/delays.

        Parameters
        ----------
        gains, delays : mapping, optional
            See :meth:`loop_gains`.

        Returns
        -------
        FrequencyResponse
            Same convention as :func:`ctmm.frequency_response` on the controlled chain.

        Raises
        ------
        ModelError
            If ``I + K P_yu`` is singular at a grid frequency (a closed-loop pole on the axis), or where an output
            is the difference of plant responses more than ``AMPLIFICATION_LIMIT`` (1e8) times larger than it (at
            or next to a resonance of a lightly damped plant that the loops tame: the algebra would lose those
            digits).
        """
        K = self.loop_gains(gains, delays)
        nw, nl = K.shape
        KP = K[:, :, None] * self.P_yu                          # diag(K) @ P_yu
        Ieye = np.broadcast_to(np.eye(nl), (nw, nl, nl))
        # excitation of the loops: u = T (r - y_w), T = (I + K P_yu)^{-1} K
        rhs = np.zeros((nw, nl, len(self.inputs)), dtype=complex)
        for j, (kind, value) in enumerate(self._w_kind):
            if kind == "reference":
                rhs[:, value, j] = K[:, value]
            else:
                rhs[:, :, j] = -K * self.P_yw[:, :, j]
        try:
            U = np.linalg.solve(Ieye + KP, rhs)                # (nw, nl, n_in): actuator forces
        except np.linalg.LinAlgError:
            raise ModelError("I + K P_yu is singular at a grid frequency: the closed loop has a pole on "
                             "the imaginary axis there") from None
        Y = self.P_yw + self.P_yu @ U                          # sensed values
        Z = self.P_zw + self.P_zu @ U
        with np.errstate(all="ignore"):                       # digits lost by the superposition (amplification)
            terms = (np.abs(self.P_zw) + np.abs(self.P_zu) @ np.abs(U),
                     np.abs(self.P_yw) + np.abs(self.P_yu) @ np.abs(U))
            lost = [np.where(size > 0, size / np.abs(value), 1.0).max(axis=(1, 2))
                    for size, value in zip(terms, (Z, Y))]
        lost = np.maximum(*lost) if any(kind == "y" for kind, _ in self._z_kind) else lost[0]
        _refuse_lost_digits("PlantCache.closed_loop", self.omega, lost, "closed loop")
        out = np.empty((len(self.outputs), len(self.inputs), nw), dtype=complex)
        for o, (kind, value) in enumerate(self._z_kind):
            if kind == "plant":
                out[o] = Z[:, o, :].T
            elif kind == "y":
                out[o] = Y[:, value, :].T
            else:
                out[o] = U[:, value, :].T
        return FrequencyResponse(self.omega, out, self.inputs, self.outputs, self.system.name)

    def loop_transfer(self, loop: str, *, gains: Mapping[str, Any] | None = None,
                      delays: Mapping[str, float] | None = None) -> FrequencyResponse:
        """Loop transfer function ``L`` of ``loop`` with the other loops closed (see
        :func:`ctmm.control.analysis.loop_transfer_function` for the convention)."""
        if loop not in self._loop_index:
            raise unknown_name("loop", loop, list(self._loop_index))
        K = self.loop_gains(gains, delays)
        i = self._loop_index[loop]
        others = [k for k in range(len(self.loops)) if k != i]
        P = self.P_yu[:, i, i].copy()
        if others:
            o = np.asarray(others)
            Ko = K[:, o]
            Poo = self.P_yu[:, o[:, None], o[None, :]]
            Pio = self.P_yu[:, i, o]
            Poi = self.P_yu[:, o, i]
            M = np.eye(o.size)[None] + Ko[:, :, None] * Poo
            closed = np.linalg.solve(M, (Ko * Poi)[:, :, None])[:, :, 0]
            with np.errstate(all="ignore"):
                size = np.abs(P) + np.einsum("wk,wk->w", np.abs(Pio), np.abs(closed))
                P = P - np.einsum("wk,wk->w", Pio, closed)
                _refuse_lost_digits(f"PlantCache.loop_transfer({loop!r})", self.omega,
                                    np.where(size > 0, size / np.abs(P), 1.0), "loop transfer function")
        L = K[:, i] * P
        name = self.loops[i].name
        return FrequencyResponse(self.omega, L[None, None], (f"{name}.u",), (f"{name}.L",), f"L_{name}")
