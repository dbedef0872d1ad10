"""Every form of a 1-D (axial, ``d = 1``) element family, derived from its body or joint terms.

A 1-D family states its physics once (issue 12, :mod:`ctmm.protocol`): a point element as a
**body** (:class:`AxialBody`, ``terms(ops, motion, ...) -> BodyTerms`` with ``M``, ``h(x, v, u)``)
or a connector as a **joint** (:class:`AxialJoint`, ``terms(ops, q_rel, v_rel, t, u) -> JointTerms``
with the law ``tau(q_rel, v_rel, u)`` and its tangents ``tau_q``, ``tau_v``, ``tau_a``).  The
lumped families are linear and time invariant: ``h`` and ``tau`` are affine in the kinematics and
inputs.  :func:`body_coefficients` and :func:`joint_coefficients` read that affine form off the
terms (unit complex steps, exact for affine terms; a term that is not affine is refused), and
every other form follows from it here, nowhere else:

* frequency domain (layout :data:`~ctmm.layouts.AXIAL`, ``z = [x, f]``, deviations from rest):
  body ``U = [[1, 0], [-Z(s), 1]]``, ``Z(s) = M s^2 + (dh/dv) s + dh/dx``, ``u = [0, -dh/du a]``;
  joint ``U = [[1, -1/kappa(s)], [0, 1]]``, ``kappa(s) = -(tau_q + s tau_v + s^2 tau_a)``,
  ``u = [dtau/du a / kappa(s), 0]``;
* DT-TMM step (:class:`~ctmm.elements.base.Linearisation` ``x = cx d + dx``, ``v = A d + B``,
  ``a = C d + D``): body ``U21 = -(M C + dh/dv A + dh/dx cx)``,
  ``u1 = -(M D + h(dx, B, u))``; joint ``k_eff = -(tau_q cx + tau_v A + tau_a C)``,
  ``U12 = -1/k_eff``, ``u0 = (tau(dx_out - dx_in, B_out - B_in, u) + tau_a (D_out - D_in)) / k_eff``;
* lumped coefficients (global ``M, C, K``, Sturm counts, the vectorised fast paths):
  body ``(M, dh/dv, dh/dx)``, joint ``(-tau_a, -tau_v, -tau_q)`` and free length
  ``tau(0, 0) / k``.

The chain-level contexts of the same terms (the articulated sweep in frequency and explicit form)
are in :mod:`ctmm.lumped_forms`.
"""
from __future__ import annotations

from abc import abstractmethod
from dataclasses import dataclass, field, replace
from functools import lru_cache
from types import MappingProxyType
from typing import Any, Hashable, Mapping, Sequence

import numpy as np

from ..errors import ModelError
from ..layouts import AXIAL
from ..ops import NUMPY
from ..protocol import BodyTerms, JointTerms, Motion
from .base import DiscreteElement, Element, Linearisation, LumpedCoefficients

__all__ = ["AxialCoefficients", "AxialBody", "AxialJoint", "DiscreteAxialBody", "DiscreteAxialJoint",
           "body_coefficients", "joint_coefficients", "derive_shared"]

_ZERO = np.zeros((1, 1, 1))


@dataclass(frozen=True)
class AxialCoefficients:
    """Affine form of 1-D terms.

    Attributes
    ----------
    inertia : float
        Body ``M`` [kg] or joint ``-tau_a`` (inertance) [kg].
    damping : float
        ``dh/dv`` or ``-tau_v`` [N s/m].
    stiffness : float
        ``dh/dx`` or ``-tau_q`` [N/m].
    rest : float
        ``h`` or ``tau`` at zero kinematics and inputs [N] (a joint's ``k l``).
    inputs : mapping of str to float
        ``dh/du`` or ``dtau/du`` per input (a point force: ``dh/dF = -1``).
    """

    inertia: float
    damping: float
    stiffness: float
    rest: float
    inputs: Mapping[str, float] = field(default_factory=dict)


@lru_cache(maxsize=8)
def _probes(inputs: tuple[str, ...]) -> tuple[np.ndarray, np.ndarray, Mapping[str, np.ndarray]]:
    """The unit complex steps of :func:`_affine` as one batch: rows ``2 p`` and ``2 p + 1`` step probe ``p``
    (``x``, ``v``, then each input) by ``1j`` and ``2j``; every other entry is zero (read-only arrays, shared by
    every element with these inputs)."""
    rows = 2 * (2 + len(inputs))
    x, v = np.zeros((rows, 1, 1), complex), np.zeros((rows, 1, 1), complex)
    u = {key: np.zeros((rows, 1, 1), complex) for key in inputs}
    for p, target in enumerate([x, v] + [u[key] for key in inputs]):
        target[2 * p: 2 * p + 2, 0, 0] = (1j, 2j)
        target.flags.writeable = False
    return x, v, MappingProxyType(u)


def _affine(name: str, rest: complex, evaluate, inputs: tuple[str, ...]) -> tuple[float, float, float, dict]:
    """Rest value, ``d/dx``, ``d/dv`` and ``d/du`` of an affine scalar function by unit complex steps.

    ``rest`` is the function at zero kinematics without inputs; ``evaluate(x, v, u)`` returns its values on a
    batch (``(B, 1, 1)`` arrays, one call for every step: :func:`_probes`) as a list.  Each step is taken at
    sizes 1 and 2: the terms are affine only if the second change is exactly twice the first and the real part
    stays."""
    x, v, u = _probes(inputs)
    values = evaluate(x, v, dict(u))
    slopes = []
    for first, second in zip(values[0::2], values[1::2]):
        if second - rest != 2.0 * (first - rest) or first.real != rest.real:
            raise ModelError(f"{name}: its 1-D terms are not affine in the kinematics and inputs; the lumped forms "
                             "(U(s), DT-TMM step, lumped coefficients) need linear time-invariant terms")
        slopes.append(first.imag)
    return rest.real, slopes[0], slopes[1], dict(zip(inputs, slopes[2:]))


def _batch(name: str, value: Any, rows: int) -> list[complex]:
    """The first entry of a 1-D term per row of a probe batch (a term that does not vary broadcasts)."""
    value = np.asarray(value)
    if value.ndim == 3 and value.shape[0] == rows:
        return [complex(entry) for entry in value[:, 0, 0].tolist()]
    try:
        return [complex(entry) for entry in np.broadcast_to(value, (rows,) + value.shape[1:]).reshape(rows, -1)[:, 0]]
    except ValueError:
        raise ModelError(f"{name}: its 1-D terms have shape {value.shape} on a batch of {rows} motions; the terms "
                         "must broadcast against the batch axis (ctmm.ops)") from None


def body_coefficients(body: "AxialBody") -> AxialCoefficients:
    """Affine form ``M a + h(x, v, u)`` of a 1-D body's terms (module docstring)."""
    terms = body.terms(NUMPY, Motion((_ZERO,), (_ZERO,)), u={})
    mass = float(np.asarray(terms.M).reshape(-1)[0])

    def h(x, v, u):
        terms = body.terms(NUMPY, Motion((x,), (v,)), u=u)
        if any(entry != mass for entry in np.asarray(terms.M).reshape(-1).tolist()):
            raise ModelError(f"{body.name}: its mass term depends on the motion; the lumped forms need a constant M")
        return _batch(body.name, terms.h, len(x))

    rest = complex(np.asarray(terms.h).reshape(-1)[0])
    rest, stiffness, damping, inputs = _affine(body.name, rest, h, tuple(body.inputs))
    return AxialCoefficients(mass, damping, stiffness, rest, inputs)


def joint_coefficients(joint: "AxialJoint") -> AxialCoefficients:
    """Affine form of a 1-D joint's law ``tau(q_rel, v_rel, u) - tau_a a_rel`` (module docstring)."""
    terms = joint.terms(NUMPY, _ZERO, _ZERO, 0.0, {})
    if terms.free != 1 or terms.tau is None:
        raise ModelError(f"{joint.name}: a 1-D connector has one free direction and a law, got {terms.free} free "
                         "directions")

    def tau(q, v, u):
        return _batch(joint.name, joint.terms(NUMPY, q, v, 0.0, u).tau, len(q))

    rest = complex(np.asarray(terms.tau).reshape(-1)[0])
    rest, stiffness, damping, inputs = _affine(joint.name, rest, tau, tuple(joint.inputs))
    tangent = lambda value: 0.0 if value is None else float(np.asarray(value).reshape(-1)[0])  # noqa: E731
    if (tangent(terms.tau_q), tangent(terms.tau_v)) != (stiffness, damping):
        raise ModelError(f"{joint.name}: the law's stated tangents tau_q={tangent(terms.tau_q)}, "
                         f"tau_v={tangent(terms.tau_v)} differ from its slopes {stiffness}, {damping}")
    return AxialCoefficients(0.0 - tangent(terms.tau_a), 0.0 - damping, 0.0 - stiffness, rest, inputs)


def _derive(element: "AxialBody | AxialJoint", shared: dict | None = None, key: Hashable | None = None) -> None:
    """Store the affine form of ``element``'s terms and its lumped coefficients on it; with ``shared`` (one
    build's probes, by kind and :meth:`~AxialBody.coefficient_key` ``key``) it reuses the probe of an equal element."""
    connector = isinstance(element, AxialJoint)
    derive = joint_coefficients if connector else body_coefficients
    if shared is None or key is None:
        co = derive(element)
    else:
        co = shared.get((connector, key))
        if co is None:
            co = shared[connector, key] = derive(element)
        co = replace(co, inputs=dict(co.inputs))                # each element owns its mapping
    element._axial = co
    element._lumped = _lumped(co, connector)


def derive_shared(elements: Sequence[Element]) -> None:
    """Derive the forms of the 1-D elements among ``elements`` that have a :meth:`~AxialBody.coefficient_key` and no
    forms yet, probing the terms once per key (one memo for this call, e.g. one :class:`~ctmm.system.Chain` build:
    a uniform chain of N masses probes one mass and one connector)."""
    shared: dict = {}
    for element in elements:
        if isinstance(element, (AxialBody, AxialJoint)) and element.__dict__.get("_axial") is None:
            key = element.coefficient_key()
            if key is not None:
                _derive(element, shared, key)


def _lumped(co: AxialCoefficients, connector: bool) -> LumpedCoefficients:
    if not connector:
        return LumpedCoefficients(False, co.inertia, co.damping, co.stiffness)
    return LumpedCoefficients(True, co.inertia, co.damping, co.stiffness, co.rest / co.stiffness if co.stiffness else 0.0)


class AxialBody(Element):
    """A 1-D point family: only :meth:`terms` (and validation) is its own; every form is derived."""

    layout = AXIAL
    is_point = True
    points = ("in", "out")
    coordinates: tuple[str, ...] = ()
    dimensions = frozenset({1})

    @abstractmethod
    def terms(self, ops, motion: Motion, eta: Any = None, eta_dot: Any = None, t: float = 0.0,
              u: Mapping[str, Any] | None = None) -> BodyTerms:
        """The physics (``d = 1``; ``Kin = RF = [1]`` and ``c = 0`` at ``"out"``)."""

    def own_load(self, t: float) -> float:
        """The value of the element's own (first) input at time ``t`` [s]; 0 by default."""
        return 0.0

    def coefficient_key(self) -> Hashable | None:
        """A hashable value that determines :meth:`terms` completely, or None (the default).  Elements with equal
        keys share one probe of their terms (:meth:`derive_forms`): a family keys its own :meth:`terms` and the
        data it reads, and returns None where a subclass replaces them."""
        return None

    def derive_forms(self) -> None:
        """Derive the affine form; call it last in ``__init__`` (the verbs only read it) and again after changing
        the data.  An element with a :meth:`coefficient_key` (the library's own laws on its numbers) is probed by the
        :class:`~ctmm.system.Chain` build that takes it (:func:`derive_shared`: one probe per key and build; outside
        a chain on every call), any other at once (terms that are not affine are refused here)."""
        self.__dict__.pop("_axial", None)
        self.__dict__.pop("_lumped", None)
        if self.coefficient_key() is None:
            _derive(self)

    def axial_coefficients(self) -> AxialCoefficients:
        """The affine form of :meth:`terms` (derived by :meth:`derive_forms` or the chain build, else on every call:
        a verb never writes to an element)."""
        cached = self.__dict__.get("_axial")
        return cached if cached is not None else body_coefficients(self)

    def impedance(self, s: np.ndarray) -> np.ndarray:
        """Dynamic stiffness ``Z(s) = M s^2 + (dh/dv) s + dh/dx`` [N/m]."""
        co = self.axial_coefficients()
        s = np.asarray(s, dtype=complex)
        return co.inertia * s * s + co.damping * s + co.stiffness

    def transfer_matrix(self, s: np.ndarray) -> np.ndarray:
        s = np.asarray(s, dtype=complex)
        U = np.zeros(s.shape + (2, 2), dtype=complex)
        U[..., 0, 0] = U[..., 1, 1] = 1.0
        U[..., 1, 0] = -self.impedance(s)
        return U

    def load_vector(self, s: np.ndarray, amplitudes: Mapping[str, Any]) -> np.ndarray:
        self.check_inputs(amplitudes)
        co = self.axial_coefficients()
        u = np.zeros(np.shape(s) + (2,), dtype=complex)
        for key, value in amplitudes.items():
            u[..., 1] -= co.inputs[key] * value
        return u

    def discretize(self, scheme: Any) -> "DiscreteAxialBody":
        return DiscreteAxialBody(self)

    def lumped_coefficients(self) -> LumpedCoefficients:
        cached = self.__dict__.get("_lumped")          # read every step by the fast paths
        return cached if cached is not None else _lumped(self.axial_coefficients(), connector=False)


class AxialJoint(Element):
    """A 1-D connector family: only :meth:`terms` (and validation) is its own; every form is derived."""

    layout = AXIAL
    is_point = False
    coordinates = ("dx",)
    dimensions = frozenset({1})

    @abstractmethod
    def terms(self, ops, q_rel: Any, v_rel: Any, t: float = 0.0,
              u: Mapping[str, Any] | None = None) -> JointTerms:
        """The law (``S = [1]``)."""

    def coefficient_key(self) -> Hashable | None:
        """As :meth:`AxialBody.coefficient_key`: None (the default) probes every element on its own."""
        return None

    def derive_forms(self) -> None:
        """As :meth:`AxialBody.derive_forms`."""
        self.__dict__.pop("_axial", None)
        self.__dict__.pop("_lumped", None)
        if self.coefficient_key() is None:
            _derive(self)

    def axial_coefficients(self) -> AxialCoefficients:
        """The affine form of :meth:`terms` (derived by :meth:`derive_forms` or the chain build, else on every call:
        a verb never writes to an element)."""
        cached = self.__dict__.get("_axial")
        return cached if cached is not None else joint_coefficients(self)

    def connector_stiffness(self, s: np.ndarray) -> np.ndarray:
        """``kappa(s) = -(tau_q + s tau_v + s^2 tau_a) = k + c s + b s^2`` [N/m] (it clears the poles of ``U``)."""
        co = self.axial_coefficients()
        s = np.asarray(s, dtype=complex)
        if co.inertia:
            return co.inertia * s * s + co.damping * s + co.stiffness
        return co.stiffness + co.damping * s

    def transfer_matrix(self, s: np.ndarray) -> np.ndarray:
        s = np.asarray(s, dtype=complex)
        U = np.zeros(s.shape + (2, 2), dtype=complex)
        U[..., 0, 0] = U[..., 1, 1] = 1.0
        with np.errstate(divide="ignore", invalid="ignore"):
            U[..., 0, 1] = -1.0 / self.connector_stiffness(s)
        return U

    def load_vector(self, s: np.ndarray, amplitudes: Mapping[str, Any]) -> np.ndarray:
        self.check_inputs(amplitudes)
        co = self.axial_coefficients()
        u = np.zeros(np.shape(s) + (2,), dtype=complex)
        if amplitudes:
            kappa = self.connector_stiffness(s)
            for key, value in amplitudes.items():
                u[..., 0] += co.inputs[key] * value / kappa
        return u

    def discretize(self, scheme: Any) -> "DiscreteAxialJoint":
        return DiscreteAxialJoint(self)

    def lumped_coefficients(self) -> LumpedCoefficients:
        cached = self.__dict__.get("_lumped")          # read every step by the fast paths
        return cached if cached is not None else _lumped(self.axial_coefficients(), connector=True)


class DiscreteAxialBody(DiscreteElement):
    """DT-TMM form of an :class:`AxialBody` (module docstring)."""

    def __init__(self, element: AxialBody) -> None:
        self.element = element
        co = element.axial_coefficients()
        self._m, self._c, self._k, self._rest = co.inertia, co.damping, co.stiffness, co.rest
        self._load = -co.inputs[element.inputs[0]] if element.inputs else 0.0

    def load(self, t: float) -> float:
        """The element's own load at time ``t`` [s] (its first input)."""
        return self.element.own_load(t)

    def step_matrices(self, t: float, inboard: Linearisation, outboard: Linearisation, force: float = 0.0):
        lin = inboard
        U = np.eye(2)
        U[1, 0] = -(self._m * lin.C + self._c * lin.A + self._k * lin.cx)
        u = np.array([0.0, -(self._m * lin.D + self._c * lin.B + self._k * lin.dx + self._rest) + self._load * force])
        return U, u


class DiscreteAxialJoint(DiscreteElement):
    """DT-TMM form of an :class:`AxialJoint` (module docstring)."""

    def __init__(self, element: AxialJoint) -> None:
        self.element = element
        co = element.axial_coefficients()
        self._b, self._c, self._k, self._rest = co.inertia, co.damping, co.stiffness, co.rest
        self._across = co.inputs[element.inputs[0]] if element.inputs else 0.0

    def step_matrices(self, t: float, inboard: Linearisation, outboard: Linearisation, force: float = 0.0):
        k_eff = self._k * inboard.cx + self._c * inboard.A + self._b * inboard.C
        U = np.eye(2)
        U[0, 1] = -1.0 / k_eff
        u = np.array([(self._rest - self._k * (outboard.dx - inboard.dx) - self._c * (outboard.B - inboard.B)
                       - self._b * (outboard.D - inboard.D) + self._across * force) / k_eff, 0.0])
        return U, u
