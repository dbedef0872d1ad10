"""The closed-loop characteristic matrix of a lumped controlled chain and its exact derivatives.

A lumped 1-D chain (masses, springs, dampers, grounded springs) closed by embedded loops
``u_l = -K_l(s) (y_l - r_l)`` with ``K_l(s) = C_l(s) e^{-s tau_l}`` is, over its degrees of
freedom ``x`` (:func:`ctmm.interop.assemble_matrices`),

    Delta(s) x = F,     Delta(s) = s^2 M + s C + K + sum_l K_l(s) b_l c_l(s)^T,

with ``b_l`` the actuator's load vector (a force on a point: a unit entry; a force across a
connector: ``+1`` outboard, ``-1`` inboard) and ``c_l(s) = sum_i w_i s^{p_i} e_{dof_i}`` the
sensor row (``p = 0, 1, 2`` for ``.x, .v, .a``).  ``Delta`` is *affine* in every element number
and sensor weight and analytic in the gain and the delay, so its derivatives are exact matrices:

=========================  ==============================================================
parameter                  ``dDelta / dp``
=========================  ==============================================================
``"<point>.mass"``         ``s^2 e_g e_g^T`` (``g`` the point's DOF)
``"<point>.damping"``      ``s e_g e_g^T``;   ``"<point>.stiffness"``: ``e_g e_g^T``
``"<connector>.damping"``  ``s d d^T`` with ``d = e_out - e_in``; ``".stiffness"``: ``d d^T``
``"<loop>.gain"``          ``C_l(s)/g e^{-s tau} b c^T`` (a static gain ``g``; a factor on
                           an LTI controller, current value 1)
``"<loop>.delay"``         ``-s K_l(s) b c^T``
``"<loop>.<signal>"``      ``K_l(s) b (s^p e_dof)^T`` (the weight of that sensor term)
=========================  ==============================================================

and ``dDelta/ds = 2 s M + C + sum_l (K_l c_l^T)' b_l`` exactly.  Every quantity of
:mod:`ctmm.sensitivity` is built from these.  The matrix is an independent derivation from the
element coefficients: it is never the TMM's own sweep, which the tests use as the reference.
"""
from __future__ import annotations

from dataclasses import dataclass
from typing import Any, Sequence

import numpy as np

from .control.loops import ControlledChain, Feedback, actuator_inputs
from .elements.inerter import Inerter
from .errors import ModelError, unknown_name
from .lumped_realisation import assemble_matrices
from .system import Chain

__all__ = ["LoopCharacteristicMatrix", "ParameterDerivative", "controller_polynomials", "loop_parameter"]

_POWERS = {"x": 0, "v": 1, "a": 2}
_ELEMENT_KINDS = ("mass", "damping", "stiffness")


@dataclass(frozen=True)
class ParameterDerivative:
    """How one named parameter enters ``Delta(s)`` (see the module table).

    Attributes
    ----------
    name : str
        ``"m3.mass"``, ``"pd.gain"``, ``"pd.m6.v"``, ...
    kind : str
        ``"mass"`` (an inerter's inertance too: ``s^2`` times its pattern), ``"damping"``, ``"stiffness"``,
        ``"gain"``, ``"delay"`` or ``"weight"``.
    pattern : ndarray or None
        ``(n, n)`` constant matrix of an element number.
    loop : int
        Loop index (loop parameters), else -1.
    term : int
        Sensor-term index (``"weight"``), else -1.
    value : float
        Current value of the parameter.
    """

    name: str
    kind: str
    pattern: np.ndarray | None
    loop: int
    term: int
    value: float


def controller_polynomials(lp: Any) -> tuple[np.ndarray, np.ndarray]:
    """Numerator and denominator polynomial coefficients of ``C_l(s)`` of a loop (highest power first)."""
    if not lp.is_lti:
        return np.array([float(lp.gain)]), np.array([1.0])
    import control

    tf = control.tf(lp.gain)
    return np.asarray(tf.num[0][0], dtype=float), np.asarray(tf.den[0][0], dtype=float)


def loop_parameter(loops: Sequence[Any], name: str) -> ParameterDerivative | None:
    """``"<loop>.gain"``, ``"<loop>.delay"`` or ``"<loop>.<sensed signal>"`` of one of ``loops``; None when
    ``name`` does not start with a loop's name (an element number), an unknown loop number refused."""
    head, _, tail = name.partition(".")
    for i, lp in enumerate(loops):
        if lp.name != head:
            continue
        if tail == "gain":
            return ParameterDerivative(name, "gain", None, i, -1, 1.0 if lp.is_lti else float(lp.gain))
        if tail == "delay":
            return ParameterDerivative(name, "delay", None, i, -1, float(lp.delay))
        for k, (sig, w) in enumerate(lp.terms):
            if sig == tail:
                return ParameterDerivative(name, "weight", None, i, k, float(w))
        raise unknown_name(f"parameter of loop {head!r}", tail, ["gain", "delay"] + [s for s, _ in lp.terms])
    return None


class LoopCharacteristicMatrix:
    """``Delta(s)`` of a lumped (controlled) chain with its derivatives (module docstring).

    Parameters
    ----------
    system : Chain or ControlledChain
        1-D lumped chain; loops with static gains or SISO LTI controllers, any delays.
    parameters : sequence of str
        Names of the parameters to differentiate with respect to (module table).

    Raises
    ------
    ModelError
        A non-lumped element, an unknown or unsupported parameter, sensor, actuator or output
        (named, with what is allowed).
    """

    def __init__(self, system: Any, parameters: Sequence[str] = ()) -> None:
        if isinstance(system, Chain):
            chain, loops = system, ()
        elif isinstance(system, ControlledChain):
            chain, loops = system.plant, tuple(system.loops)
        else:
            raise ModelError(f"ctmm.sensitivity: system must be a ctmm.Chain or ctmm.control.ControlledChain of "
                             f"lumped elements, or a planar or spatial model (controlled or not), for the exact "
                             f"derivative matrices; got {type(system).__name__} ({system!r:.80})")
        self.system = system
        self.chain = chain
        self.M, self.C, self.K, self.point_dof = assemble_matrices(chain)
        self.n = self.M.shape[0]
        self.loops: tuple[Feedback, ...] = loops
        self.controller_coefficients = [controller_polynomials(lp) for lp in loops]
        self.actuator_vectors = [sum(w * self.input_vector(name) for name, w in actuator_inputs(system, lp.name))
                   for lp in loops]
        self.sensor_terms = [[(self._dof_vector(sig, f"loop {lp.name!r} sensor"), self._power(sig), w)
                          for sig, w in lp.terms] for lp in loops]
        self.parameters = tuple(self._parameter(name) for name in parameters)

    # -- the chain's geometry -----------------------------------------------------------------
    def _element(self, name: str, role: str):
        """The body element called ``name`` and its index ``j`` (points ``j - 1``, ``j`` around it)."""
        body = [e.name for e in self.chain.body]
        if name not in body:
            raise unknown_name(f"element ({role})", name, body)
        j = self.chain.position(name)
        element = self.chain.elements[j]
        if element.lumped_coefficients() is None:
            raise ModelError(f"ctmm.sensitivity: {role} {name!r} is a {type(element).__name__}; only lumped "
                             "elements (masses, springs, dampers, grounded springs) are differentiated")
        return element, j

    def _unit(self, dof: int) -> np.ndarray:
        e = np.zeros(self.n)
        if dof >= 0:
            e[dof] = 1.0
        return e

    def _dof_vector(self, signal: str, role: str) -> np.ndarray:
        head, _, tail = signal.rpartition(".")
        if tail not in _POWERS:
            raise ModelError(f"ctmm.sensitivity: {role} {signal!r} is not supported; allowed are the "
                             f"displacement, velocity and acceleration of a point element "
                             f"('<point>.x', '<point>.v', '<point>.a')")
        element, j = self._element(head, role)
        if not element.is_point:
            raise ModelError(f"ctmm.sensitivity: {role} {signal!r}: {head!r} is a connector; allowed are "
                             "signals of point elements (masses, grounded springs)")
        return self._unit(int(self.point_dof[j]))

    @staticmethod
    def _power(signal: str) -> int:
        return _POWERS[signal.rpartition(".")[2]]

    def input_vector(self, name: str) -> np.ndarray:
        """Load vector ``b`` of a force input ``"<element>.force"`` over the DOFs."""
        head, _, tail = name.partition(".")
        if tail != "force":
            raise ModelError(f"ctmm.sensitivity: input {name!r} is not supported; allowed are element forces "
                             "'<point>.force' and '<connector>.force'")
        element, j = self._element(head, "input")
        if element.is_point:
            return self._unit(int(self.point_dof[j]))
        return self._unit(int(self.point_dof[j])) - self._unit(int(self.point_dof[j - 1]))

    def output_row(self, name: str, s: complex) -> np.ndarray:
        """``c(s)`` of an output ``"<point>.x|v|a"``: ``s^p e_dof``."""
        return self._dof_vector(name, "output") * s ** self._power(name)

    # -- parameters ---------------------------------------------------------------------------
    def _parameter(self, name: str) -> ParameterDerivative:
        if not isinstance(name, str) or "." not in name:
            raise ModelError(f"ctmm.sensitivity: parameter {name!r} must be '<element>.<number>' or "
                             "'<loop>.gain' / '<loop>.delay' / '<loop>.<sensed signal>'")
        head, _, tail = name.partition(".")
        loop = loop_parameter(self.loops, name)
        if loop is not None:
            return loop
        element, j = self._element(head, "parameter")
        allowed = ("mass", "damping", "stiffness") if element.is_point else \
            ("damping", "inertance", "stiffness") if isinstance(element, Inerter) else ("damping", "stiffness")
        if tail not in allowed:
            raise unknown_name(f"differentiable number (parameter {name!r}) of {type(element).__name__} {head!r}", tail,
                               list(allowed))
        if element.is_point:
            d = self._unit(int(self.point_dof[j]))
        else:
            d = self._unit(int(self.point_dof[j])) - self._unit(int(self.point_dof[j - 1]))
        kind = "mass" if tail == "inertance" else tail      # an inertance b enters as s^2 b d d^T, as a mass
        return ParameterDerivative(name, kind, np.outer(d, d), -1, -1, float(getattr(element, tail)))

    # -- loop pieces ---------------------------------------------------------------------------
    def controller(self, i: int, s: complex) -> tuple[complex, complex]:
        """``C_l(s)`` and ``dC_l/ds``."""
        num, den = self.controller_coefficients[i]
        n, d = np.polyval(num, s), np.polyval(den, s)
        dn, dd = np.polyval(np.polyder(num), s) if num.size > 1 else 0.0, \
            np.polyval(np.polyder(den), s) if den.size > 1 else 0.0
        return complex(n / d), complex((dn * d - n * dd) / (d * d))

    def loop_gain(self, i: int, s: complex) -> tuple[complex, complex]:
        """``K_l(s) = C_l(s) e^{-s tau}`` and ``dK_l/ds``."""
        c, dc = self.controller(i, s)
        e = np.exp(-s * self.loops[i].delay)
        return complex(c * e), complex((dc - self.loops[i].delay * c) * e)

    def sensor(self, i: int, s: complex) -> tuple[np.ndarray, np.ndarray]:
        """``c_l(s)`` and ``dc_l/ds``."""
        c = np.zeros(self.n, dtype=complex)
        dc = np.zeros(self.n, dtype=complex)
        for vec, p, w in self.sensor_terms[i]:
            c += w * s ** p * vec
            if p:
                dc += w * p * s ** (p - 1) * vec
        return c, dc

    def actuator(self, i: int) -> np.ndarray:
        """``b_l``."""
        return self.actuator_vectors[i]

    # -- Delta ---------------------------------------------------------------------------------
    def delta(self, s: complex, *, skip: int = -1) -> np.ndarray:
        """``Delta(s)`` (with loop ``skip`` left open)."""
        D = s * s * self.M + s * self.C + self.K + 0j
        for i in range(len(self.loops)):
            if i != skip:
                D += self.loop_gain(i, s)[0] * np.outer(self.actuator_vectors[i], self.sensor(i, s)[0])
        return D

    def loop_transfer(self, loop: int, s: np.ndarray) -> np.ndarray:
        """``L_l(s) = K_l(s) c_l(s)^T Delta_{-l}(s)^{-1} b_l`` over an array of ``s`` (batched solve)."""
        s = np.asarray(s, dtype=complex).ravel()
        D = (s[:, None, None] ** 2 * self.M + s[:, None, None] * self.C + self.K).astype(complex)
        for i in range(len(self.loops)):
            if i != loop:
                k, c = self._loop_gains(i, s), self._sensors(i, s)
                D += k[:, None, None] * self.actuator_vectors[i][None, :, None] * c[:, None, :]
        x = np.linalg.solve(D, np.broadcast_to(self.actuator_vectors[loop], (s.size, self.n))[..., None])[..., 0]
        return self._loop_gains(loop, s) * np.einsum("wn,wn->w", self._sensors(loop, s), x)

    def _loop_gains(self, i: int, s: np.ndarray) -> np.ndarray:
        """``K_l(s)`` of :meth:`loop_gain` over an array of ``s`` (the same operations, element by element)."""
        num, den = self.controller_coefficients[i]
        return np.polyval(num, s) / np.polyval(den, s) * np.exp(-s * self.loops[i].delay)

    def _sensors(self, i: int, s: np.ndarray) -> np.ndarray:
        """``c_l(s)`` of :meth:`sensor` over an array of ``s``: shape ``(len(s), n)``."""
        c = np.zeros((s.size, self.n), dtype=complex)
        for vec, p, w in self.sensor_terms[i]:
            c += (w * s ** p)[:, None] * vec
        return c

    def scale(self, s: complex) -> float:
        """Size of the terms of ``Delta(s)``: ``|s|^2 |M| + |s| |C| + |K| + sum |K_l| |b_l| |c_l|``
        (2-norms), the yardstick of "singular" (a root) at ``s``."""
        total = abs(s) ** 2 * np.linalg.norm(self.M, 2) + abs(s) * np.linalg.norm(self.C, 2) \
            + np.linalg.norm(self.K, 2)
        for i in range(len(self.loops)):
            total += abs(self.loop_gain(i, s)[0]) * np.linalg.norm(self.actuator_vectors[i]) * np.linalg.norm(self.sensor(i, s)[0])
        return float(total)

    def delta_s(self, s: complex, *, skip: int = -1) -> np.ndarray:
        """``dDelta/ds`` (with loop ``skip`` left open)."""
        D = 2.0 * s * self.M + self.C + 0j
        for i in range(len(self.loops)):
            if i != skip:
                k, dk = self.loop_gain(i, s)
                c, dc = self.sensor(i, s)
                D += np.outer(self.actuator_vectors[i], dk * c + k * dc)
        return D

    def delta_p(self, s: complex, index: int, *, skip: int = -1) -> np.ndarray:
        """``dDelta/dp`` of parameter ``index`` (zero for a parameter of loop ``skip``)."""
        p = self.parameters[index]
        if p.kind in _ELEMENT_KINDS:
            return {"mass": s * s, "damping": s, "stiffness": 1.0}[p.kind] * p.pattern + 0j
        if p.loop == skip:
            return np.zeros((self.n, self.n), dtype=complex)
        return np.outer(self.actuator_vectors[p.loop], self.loop_row_p(s, index))

    def loop_row_p(self, s: complex, index: int) -> np.ndarray:
        """``d(K_l c_l^T)/dp`` of a loop parameter (the row multiplying ``b_l``)."""
        p = self.parameters[index]
        i = p.loop
        k = self.loop_gain(i, s)[0]
        c = self.sensor(i, s)[0]
        if p.kind in ("gain", "delay"):
            return self.loop_gain_p(s, index, i) * c
        vec, power, _ = self.sensor_terms[i][p.term]
        return k * s ** power * vec

    def loop_gain_p(self, s: complex, index: int, loop: int) -> complex:
        """``dK_l/dp`` of ``loop`` (nonzero for its gain and delay only)."""
        p = self.parameters[index]
        if p.loop != loop or p.kind == "weight":
            return 0j
        k = self.loop_gain(loop, s)[0]
        if p.kind == "delay":
            return -s * k
        if p.value != 0.0:
            return k / p.value
        return complex(np.exp(-s * self.loops[loop].delay))

    def sensor_p(self, index: int, loop: int, s: complex) -> np.ndarray:
        """``dc_l/dp`` of ``loop`` (nonzero for its sensor weights only)."""
        p = self.parameters[index]
        if p.loop != loop or p.kind != "weight":
            return np.zeros(self.n, dtype=complex)
        vec, power, _ = self.sensor_terms[loop][p.term]
        return vec * s ** power + 0j

    # -- plant-number dependence of the ports (none for a chain: b and c are geometry) ----------
    def actuator_p(self, index: int, loop: int) -> np.ndarray:
        """``db_l/dp`` (zero here: a chain's load vectors do not depend on its numbers)."""
        return np.zeros(self.n, dtype=complex)

    def input_vector_p(self, name: str, index: int) -> np.ndarray:
        """``db/dp`` of an input (zero here)."""
        return np.zeros(self.n, dtype=complex)

    def output_row_p(self, name: str, s: complex, index: int) -> np.ndarray:
        """``dc(s)/dp`` of an output (zero here)."""
        return np.zeros(self.n, dtype=complex)

    def delay_free_roots(self) -> np.ndarray:
        """Finite roots of ``det Delta(s)`` for static gains without delay (companion pencil of the
        quadratic ``s^2 M + s C + K`` with the loops folded into ``K``, ``C``, ``M`` by their sensor
        powers; QZ)."""
        from scipy.linalg import eig

        M2, C2, K2 = (np.asarray(X, dtype=float).copy() for X in (self.M, self.C, self.K))
        for i, lp in enumerate(self.loops):
            b = self.actuator_vectors[i]
            for vec, power, weight in self.sensor_terms[i]:
                (K2, C2, M2)[power][...] += float(lp.gain) * weight * np.outer(b, vec)
        n = self.n
        A = np.block([[np.zeros((n, n)), np.eye(n)], [-K2, -C2]])
        B = np.block([[np.eye(n), np.zeros((n, n))], [np.zeros((n, n)), M2]])
        alpha, beta = eig(A, B, right=False, homogeneous_eigvals=True)
        # infinite eigenvalues of the massless DOFs come out with beta at round-off (0 or ~eps |B|)
        finite = np.abs(beta) > 1e-10 * np.linalg.norm(B, 1)
        return alpha[finite] / beta[finite]
