"""State-space realisation of a lumped, delay-free (controlled) 1-D chain, assembled from the element
parameters (:func:`chain_state_space`, the chain branch of :func:`ctmm.interop.to_state_space` and of
:func:`ctmm.linearize`), and the chain's global ``M, C, K`` (:func:`assemble_matrices`).

Realisation (derivation)
------------------------
Connection points joined by point elements (masses, grounded springs) move together and form one
degree of freedom (DOF); points tied to a ``Fixed`` boundary are dropped.  Each element scatters
its lumped coefficients (:meth:`~ctmm.elements.base.Element.lumped_coefficients`) like a finite
element: a point element adds ``m, c, k`` on the diagonal of its DOF, a connector
``k [[1, -1], [-1, 1]]`` (and ``c``, and its inertance ``b`` into ``M``) on its two DOFs, an
``Elastic`` boundary its spring/damper on the diagonal, giving ``M q'' + C q' + K q = B_f w``.  Force inputs:
``"m.force"`` = ``+e_m``; ``"k.force"`` across a connector = ``+e_out - e_in``;
``"end.force"`` of a :class:`~ctmm.elements.boundary.PrescribedForce` = ``+e``.

DOFs are split into massive (``a``, a nonzero row of the positive semidefinite ``M``),
massless-damped (``b``) and massless-undamped (``c``) ones; ``M`` has no entries outside the
``a`` block.  The ``c`` DOFs carry no inertia or damping, so they are condensed statically and exactly:
``q_c = K_cc^{-1} (f_c - K_ca q_a - K_cb q_b)``.  The ``b`` DOFs are first order,
``q_b' = C_bb^{-1} (f_b - C_ba q_a' - K'_b. q)``.  The state is ``[q_a, q_a', q_b]``.

Outputs (the signal names of :meth:`ctmm.system.Chain.signal`): displacement, velocity and
acceleration of any point (velocity of a condensed point and acceleration of a massless point
only if they do not need an input derivative), and the internal force ``"e.f"`` (force by the
inboard on the outboard part), taken from the nearest connector law plus the d'Alembert forces
of the point elements in between.

Loops of a :class:`~ctmm.control.loops.ControlledChain` are closed by a linear fractional
transformation with the block-diagonal controller ``K(s) = diag(C_l(s))`` (``u = -K (y - r)``);
a singular ``I + D_K D_yu`` (algebraic loop without a solution) is reported.  Loops with a
delay have no finite-dimensional realisation: use :func:`to_frd`, which is exact, or apply
``control.pade`` yourself.
"""
from __future__ import annotations

from typing import Any, Sequence

import numpy as np

from . import validation
from .control.loops import actuator_inputs
from .elements.boundary import Elastic, PrescribedForce
from .errors import ModelError, unknown_name
from .linearized import control_name
from .loop_closure import block_controller
from .system import Chain, require_system



__all__ = ["chain_state_space", "assemble_matrices", "default_signal_names"]


# ------------------------------------------------------------------------------ assembly
def _is_point(element) -> bool:
    """True for a 1-D lumped point element (mass, grounded spring)."""
    lumped = element.lumped_coefficients()
    return lumped is not None and not lumped.connector


def _is_connector(element) -> bool:
    """True for a 1-D lumped connector (spring, damper, inerter)."""
    lumped = element.lumped_coefficients()
    return lumped is not None and lumped.connector


def _is_mass(element) -> bool:
    """True for a point element with mass (its force input and displacement are default signals)."""
    return _is_point(element) and element.lumped_coefficients().mass > 0


class _Dofs:
    """Degrees of freedom of a lumped chain: point -> DOF index (or -1 when grounded)."""

    def __init__(self, chain: Chain) -> None:
        if chain.layout.size != 2:
            raise ModelError(f"to_state_space supports 1-D lumped chains (layout 'axial'), got layout "
                             f"{chain.layout.name!r}")
        for e in chain.body:
            if e.lumped_coefficients() is None:
                raise ModelError(f"to_state_space supports lumped elements (masses, springs, dampers, "
                                 f"grounded springs, inerters) only; {e.name!r} is a {type(e).__name__}")
        n_points = chain.n_points
        group = list(range(n_points))
        for j, e in enumerate(chain.body, start=1):
            if e.is_point:
                group[j] = group[j - 1]
        grounded = set()
        if chain.start.known == "displacement":
            grounded.add(group[0])
        if chain.end.known == "displacement":
            grounded.add(group[-1])
        labels = sorted(set(group) - grounded)
        index = {g: i for i, g in enumerate(labels)}
        self.point_dof = np.array([index.get(g, -1) for g in group])
        self.n = len(labels)


def assemble_matrices(system: Chain) -> tuple[np.ndarray, np.ndarray, np.ndarray, np.ndarray]:
    """Mass, damping and stiffness matrices of a lumped chain over its DOFs.

    Returns
    -------
    M, C, K : ndarray, shape (n, n)
        [kg], [N s/m], [N/m].
    point_dof : ndarray of int, shape (n_points,)
        DOF of every connection point (``-1`` for points held by a ``Fixed`` boundary).
    """
    system = require_system(system, controlled=False)
    dofs = _Dofs(system)
    n = dofs.n
    M, C, K = np.zeros((n, n)), np.zeros((n, n)), np.zeros((n, n))
    pd = dofs.point_dof

    def add(mat, i, j, value):
        if i >= 0 and j >= 0:
            mat[i, j] += value

    for j, e in enumerate(system.body, start=1):
        lumped = e.lumped_coefficients()
        if not lumped.connector:
            g = pd[j]
            add(M, g, g, lumped.mass)
            add(C, g, g, lumped.damping)
            add(K, g, g, lumped.stiffness)
        else:
            a, b = pd[j - 1], pd[j]
            for mat, value in ((K, lumped.stiffness), (C, lumped.damping), (M, lumped.mass)):
                add(mat, a, a, value)
                add(mat, b, b, value)
                add(mat, a, b, -value)
                add(mat, b, a, -value)
    for boundary, point in ((system.start, 0), (system.end, system.n_points - 1)):
        if isinstance(boundary, Elastic):
            g = pd[point]
            add(K, g, g, boundary.stiffness)
            add(C, g, g, boundary.damping)
    return M, C, K, pd


class _Quantity:
    """A linear quantity ``Z @ state + U @ inputs`` (``dU``: coefficient of the input derivative)."""

    __slots__ = ("Z", "U", "dU")

    def __init__(self, Z: np.ndarray, U: np.ndarray, dU: np.ndarray | None = None) -> None:
        self.Z, self.U, self.dU = Z, U, dU

    def __add__(self, other: "_Quantity") -> "_Quantity":
        dU = None
        if self.dU is not None or other.dU is not None:
            dU = (0.0 if self.dU is None else self.dU) + (0.0 if other.dU is None else other.dU)
        return _Quantity(self.Z + other.Z, self.U + other.U, dU)

    def __mul__(self, factor: float) -> "_Quantity":
        return _Quantity(factor * self.Z, factor * self.U, None if self.dU is None else factor * self.dU)

    __rmul__ = __mul__


class _LumpedModel:
    """First-order realisation of ``M q'' + C q' + K q = B_f u`` with maps to every chain signal.

    State ``z = [q_a, q_a', q_b]`` (see the module docstring for the ``a, b, c`` split).
    """

    def __init__(self, chain: Chain, inputs: Sequence[str]) -> None:
        self.chain = chain
        M, C, K, pd = assemble_matrices(chain)
        self.M, self.C, self.K, self.point_dof = M, C, K, pd
        n = M.shape[0]
        self.inputs = tuple(inputs)
        self.n_inputs = len(self.inputs)
        Bf = np.zeros((n, self.n_inputs))
        for k, name in enumerate(self.inputs):
            Bf[:, k] = self._force_vector(name)
        massive = np.diag(M) > 0.0
        damped = np.array([bool(np.any(C[i] != 0.0) or np.any(C[:, i] != 0.0)) for i in range(n)], dtype=bool)
        a = np.flatnonzero(massive)
        b = np.flatnonzero(~massive & damped)
        c = np.flatnonzero(~massive & ~damped)
        na, nb = a.size, b.size
        ns = 2 * na + nb
        self.n_states = ns
        self.state_names = self._state_names(a, b)
        kept = np.concatenate([a, b]).astype(int)
        Fk = Bf[kept]                                   # forces on the kept DOFs per input
        K_kept = K[np.ix_(kept, kept)]
        if c.size:
            Kcc = K[np.ix_(c, c)]
            if np.linalg.cond(Kcc) > 1e12:
                raise ModelError("to_state_space: a massless, undamped part of the chain has no stiffness "
                                 "path to the rest (singular condensed stiffness)")
            Kcc_inv = np.linalg.inv(Kcc)
            Kkc, Kck = K[np.ix_(kept, c)], K[np.ix_(c, kept)]
            K_kept = K_kept - Kkc @ Kcc_inv @ Kck
            Fk = Fk - Kkc @ Kcc_inv @ Bf[c]
        ia, ib = np.arange(na), na + np.arange(nb)
        eye = np.eye(ns)
        Sqa, Sva, Sqb = eye[:na], eye[na:2 * na], eye[2 * na:]
        Sq = np.vstack([Sqa, Sqb])                      # kept displacements from z
        zero_u = np.zeros((0, self.n_inputs))
        if nb:
            Cbb = C[np.ix_(b, b)]
            if np.linalg.cond(Cbb) > 1e12:
                raise ModelError("to_state_space: massless points joined only by dampers give a singular "
                                 "first-order block; add a small mass or a spring")
            Cbb_inv = np.linalg.inv(Cbb)
            vb = _Quantity(Cbb_inv @ (-C[np.ix_(b, a)] @ Sva - K_kept[ib] @ Sq), Cbb_inv @ Fk[ib])
        else:
            vb = _Quantity(np.zeros((0, ns)), zero_u)
        Minv = np.linalg.inv(M[np.ix_(a, a)]) if na else np.zeros((0, 0))
        Cab = C[np.ix_(a, b)]
        aa = _Quantity(Minv @ (-C[np.ix_(a, a)] @ Sva - Cab @ vb.Z - K_kept[ia] @ Sq),
                       Minv @ (Fk[ia] - Cab @ vb.U))
        self.A = np.vstack([Sva, aa.Z, vb.Z])
        self.B = np.vstack([np.zeros((na, self.n_inputs)), aa.U, vb.U])
        zu = np.zeros((1, self.n_inputs))
        self._q: list = [None] * n
        self._v: list = [None] * n
        self._a: list = [None] * n
        for k, i in enumerate(a):
            self._q[i] = _Quantity(Sqa[k:k + 1], zu)
            self._v[i] = _Quantity(Sva[k:k + 1], zu)
            self._a[i] = _Quantity(aa.Z[k:k + 1], aa.U[k:k + 1])
        for k, i in enumerate(b):
            self._q[i] = _Quantity(Sqb[k:k + 1], zu)
            self._v[i] = _Quantity(vb.Z[k:k + 1], vb.U[k:k + 1])
        if c.size:
            # q_c = Kcc^-1 (f_c - Kck q_kept);  v_c = -Kcc^-1 Kck v_kept + Kcc^-1 f_c'
            vk_Z = np.vstack([Sva, vb.Z])
            vk_U = np.vstack([np.zeros((na, self.n_inputs)), vb.U])
            qc = _Quantity(-Kcc_inv @ Kck @ Sq, Kcc_inv @ Bf[c])
            vc = _Quantity(-Kcc_inv @ Kck @ vk_Z, -Kcc_inv @ Kck @ vk_U, Kcc_inv @ Bf[c])
            for k, i in enumerate(c):
                self._q[i] = _Quantity(qc.Z[k:k + 1], qc.U[k:k + 1])
                self._v[i] = _Quantity(vc.Z[k:k + 1], vc.U[k:k + 1], vc.dU[k:k + 1])

    def _state_names(self, a: np.ndarray, b: np.ndarray) -> list[str]:
        """``"<mass>.x"``, ``"<mass>.v"`` of the massive DOFs, ``"<point>.x"`` of the first-order ones."""
        chain, pd = self.chain, self.point_dof
        first_mass: dict[int, str] = {}     # DOF -> its first mass (one pass over the chain, not one per DOF)
        for j, e in enumerate(chain.body, start=1):
            if _is_mass(e):
                first_mass.setdefault(int(pd[j]), e.name)
        first_point: dict[int, str] = {}
        for p, d in zip(chain.point_names(), pd):
            first_point.setdefault(int(d), p)
        labels = [first_mass[g] if g in first_mass else first_point[g] for g in range(pd.max(initial=-1) + 1)]
        return ([f"{labels[g]}.x" for g in a] + [f"{labels[g]}.v" for g in a]
                + [f"{labels[g]}.x" for g in b])

    def zero(self) -> _Quantity:
        return _Quantity(np.zeros((1, self.n_states)), np.zeros((1, self.n_inputs)))

    def unit_input(self, name: str) -> _Quantity:
        q = self.zero()
        if name in self.inputs:
            q.U[0, self.inputs.index(name)] = 1.0
        return q

    def _force_vector(self, name: str) -> np.ndarray:
        """DOF force vector of a unit input ``name`` [N]."""
        chain = self.chain
        inp = chain.input(name)
        e, pos, pd = inp.element, inp.position, self.point_dof
        f = np.zeros(self.M.shape[0])
        if _is_point(e):
            targets = [(pd[pos], 1.0)]
        elif _is_connector(e):
            targets = [(pd[pos], 1.0), (pd[pos - 1], -1.0)]
        elif isinstance(e, PrescribedForce):
            targets = [(pd[0 if pos == 0 else chain.n_points - 1], 1.0)]
        else:
            raise ModelError(f"to_state_space supports force inputs only; {name!r} is the "
                             f"{inp.input!r} input of a {type(e).__name__} (use frequency_response/to_frd)")
        for g, sign in targets:
            if g >= 0:
                f[g] += sign
        return f

    # -- signals ------------------------------------------------------------------------
    def kinematic(self, point: int, derivative: int, what: str) -> _Quantity:
        g = self.point_dof[point]
        if g < 0:
            return self.zero()
        q = (self._q, self._v, self._a)[derivative][g]
        if q is None:
            raise ModelError(f"to_state_space: {what} needs the acceleration of a massless point, which "
                             "has no finite-dimensional realisation; add a mass there")
        return q

    def _connector_force(self, pos: int) -> _Quantity:
        """Force of the connector at chain position ``pos`` on its outboard point (actuator included)."""
        e = self.chain.elements[pos]
        lumped = e.lumped_coefficients()
        what = f"the force of {e.name!r}"
        f = -lumped.stiffness * (self.kinematic(pos, 0, what) + -1.0 * self.kinematic(pos - 1, 0, what))
        for coefficient, derivative in ((lumped.damping, 1), (lumped.mass, 2)):
            if coefficient:
                f = f + -coefficient * (self.kinematic(pos, derivative, what)
                                        + -1.0 * self.kinematic(pos - 1, derivative, what))
        return f + self.unit_input(f"{e.name}.force")

    def _point_load(self, pos: int) -> _Quantity:
        """``m a + c v + k x - F`` of the point element at chain position ``pos``."""
        e = self.chain.elements[pos]
        lumped = e.lumped_coefficients()
        total = self.zero()
        for coef, deriv in ((lumped.stiffness, 0), (lumped.damping, 1), (lumped.mass, 2)):
            if coef:
                total = total + coef * self.kinematic(pos, deriv, f"the force next to {e.name!r}")
        return total + -1.0 * self.unit_input(f"{e.name}.force")

    def internal_force(self, point: int) -> _Quantity:
        """Force [N] by the inboard on the outboard part at connection point ``point``."""
        chain = self.chain
        els = chain.elements
        last = len(els) - 1
        if 1 <= point < last and _is_connector(els[point]):
            return self._connector_force(point)
        # outboard: f_p = f_(k-1) + sum over point elements p < j < k of (Z x - F)_j
        total, pos = self.zero(), point + 1
        while pos < last and _is_point(els[pos]):
            total = total + self._point_load(pos)
            pos += 1
        if pos < last:
            return total + self._connector_force(pos)
        end, n_end = chain.end, chain.n_points - 1
        if end.known == "force":
            f_end = getattr(end, "stiffness", 0.0) * self.kinematic(n_end, 0, "the end force")
            if getattr(end, "damping", 0.0):
                f_end = f_end + end.damping * self.kinematic(n_end, 1, "the end force")
            return total + f_end + -1.0 * self.unit_input(f"{end.name}.force")
        # inboard: f_p = f_i - sum over point elements i < j <= p of (Z x - F)_j
        total, pos = self.zero(), point
        while pos >= 1 and _is_point(els[pos]):
            total = total + -1.0 * self._point_load(pos)
            pos -= 1
        if pos >= 1:
            return total + self._connector_force(pos)
        start = chain.start
        if start.known != "force":
            raise ModelError(f"to_state_space: the force at point {chain.point_names()[point]!r} is a "
                             "support reaction between two fixed supports")
        f_start = -getattr(start, "stiffness", 0.0) * self.kinematic(0, 0, "the start force")
        if getattr(start, "damping", 0.0):
            f_start = f_start + -start.damping * self.kinematic(0, 1, "the start force")
        return total + f_start + self.unit_input(f"{start.name}.force")

    def output(self, name: str) -> _Quantity:
        sig = self.chain.signal(name)
        if sig.component == 0:
            q = self.kinematic(sig.point, sig.derivative, f"output {name!r}")
        else:
            q = self.internal_force(sig.point)
        if q.dU is not None and np.any(q.dU != 0.0):
            raise ModelError(f"to_state_space: output {name!r} needs the derivative of an input (velocity "
                             "of a loaded massless, undamped point); not realisable")
        return q


# -------------------------------------------------------------------------- state space
def default_signal_names(system) -> tuple[list[str], list[str]]:
    """Default ``(inputs, outputs)`` of :func:`chain_state_space`: the force on and the displacement of every
    mass, plus ``"<loop>.y"``, ``"<loop>.u"`` of every loop."""
    chain = system.plant if hasattr(system, "plant") else system
    inputs = [f"{e.name}.force" for e in chain.body if _is_mass(e)]
    outputs = [f"{e.name}.x" for e in chain.body if _is_mass(e)]
    for lp in getattr(system, "loops", ()):
        outputs += [f"{lp.name}.y", f"{lp.name}.u"]
    return inputs, outputs


def chain_state_space(system: Any, *, inputs: str | Sequence[str] | None = None,
                   outputs: str | Sequence[str] | None = None):
    """A :class:`control.StateSpace` realisation of a lumped, delay-free (controlled) chain.

    Parameters
    ----------
    system : Chain or ControlledChain
        1-D chain of lumped elements (masses, springs, dampers, grounded springs; ``Fixed``,
        ``Free``, ``Elastic``, ``PrescribedForce`` boundaries), optionally closed by
        :class:`~ctmm.control.loops.Feedback` loops without delay (gains or python-control LTI
        controllers).
    inputs : str or sequence of str, optional
        Force inputs (``"m2.force"``, ``"k3.force"``, ``"end.force"``) and loop references
        (``"<loop>.reference"``).  Default: the force on every mass.
    outputs : str or sequence of str, optional
        Signal names (``"m6.x"``, ``"m6.v"``, ``"m6.a"``, ``"k3.f"``, ``"<loop>.y"``,
        ``"<loop>.u"``).  Default: every mass displacement and the loop signals.

    Returns
    -------
    control.StateSpace
        Continuous-time, labelled with the ctmm names through :func:`control_name` (``"m6.x"`` ->
        ``"m6_x"``, python-control reserves dots); states ``[q_a, q_a', q_b]`` named
        ``"<mass>_x"``, ``"<mass>_v"`` (``"<point>_x"`` for massless damped points), followed by the
        controller states ``"<loop>_controller<k>"``.

    Raises
    ------
    ModelError
        Non-lumped elements, delayed loops, a prescribed-displacement input, an output that needs
        an input derivative, or an algebraic loop without a solution.

    Examples
    --------
    >>> import numpy as np, ctmm
    >>> from ctmm.elements import Fixed, Spring, Mass, Free
    >>> chain = ctmm.Chain("sdof", [Fixed("wall"), Spring("k", 100.0), Mass("m", 1.0), Free("end")])
    >>> ss = chain_state_space(chain, inputs="m.force", outputs="m.x")
    >>> complex(np.squeeze(ss(5j)))  # doctest: +ELLIPSIS
    (0.0133...+0j)
    """
    import control

    controlled = hasattr(system, "plant") and hasattr(system, "loops")
    chain: Chain = system.plant if controlled else system
    if not isinstance(chain, Chain):
        raise ModelError(f"system must be a ctmm.Chain or ctmm.control.ControlledChain for chain_state_space, "
                         f"got {system!r}")
    loops = tuple(system.loops) if controlled else ()
    for lp in loops:
        if lp.delay != 0.0:
            raise ModelError(f"loop {lp.name!r} has delay {lp.delay!r} s: no finite-dimensional realisation; "
                             "use to_frd (exact) or approximate e^(-s tau) with control.pade")
    d_in, d_out = default_signal_names(system)
    inputs = d_in if inputs is None else list(validation.names("inputs", inputs))
    outputs = d_out if outputs is None else list(validation.names("outputs", outputs))
    loop_names = {lp.name: i for i, lp in enumerate(loops)}
    references, forces = [], []
    for name in inputs:
        head, _, tail = name.partition(".")
        if head in loop_names and tail == "reference":
            references.append(name)
        elif head in loop_names:
            raise unknown_name("input", name, list(system.input_names()))
        else:
            forces.append(name)
    actuators = [actuator_inputs(system, lp.name) for lp in loops]     # [(input, weight), ...] per loop
    plant_inputs = list(dict.fromkeys(forces + [a for terms in actuators for a, _ in terms]))
    model = _LumpedModel(chain, plant_inputs)
    n_u = len(plant_inputs)
    # plant outputs: requested plant signals, then each loop's sensed value
    plant_out_names = []
    rows = []
    for name in outputs:
        head, _, tail = name.partition(".")
        if head in loop_names:
            if tail not in ("y", "u"):
                raise unknown_name("signal", name, list(system.signal_names()))
            continue
        rows.append(model.output(name))
        plant_out_names.append(name)
    y_rows = []
    for lp in loops:
        total = model.zero()
        for sig, weight in lp.terms:
            total = total + weight * model.output(sig)
        y_rows.append(total)
    A = model.A
    B = model.B
    Cz = np.vstack([q.Z for q in rows]) if rows else np.zeros((0, model.n_states))
    Dz = np.vstack([q.U for q in rows]) if rows else np.zeros((0, n_u))
    nl = len(loops)
    Cy = np.vstack([q.Z for q in y_rows]) if y_rows else np.zeros((0, model.n_states))
    Dy = np.vstack([q.U for q in y_rows]) if y_rows else np.zeros((0, n_u))
    # exogenous force inputs select columns of B/D; actuator columns get the loop forces
    col = {name: k for k, name in enumerate(plant_inputs)}
    Sw = np.zeros((n_u, len(forces)))
    for k, name in enumerate(forces):
        Sw[col[name], k] = 1.0
    Su = np.zeros((n_u, nl))
    for i, terms in enumerate(actuators):
        for name, weight in terms:
            Su[col[name], i] += weight
    B1, B2 = B @ Sw, B @ Su
    D11, D12 = Dz @ Sw, Dz @ Su
    D21, D22 = Dy @ Sw, Dy @ Su
    # controller K = blockdiag(C_l): xi' = Ak xi + Bk e, v = Ck xi + Dk e, u = -v, e = y - r
    Ak, Bk, Ck, Dk, sizes = block_controller(loops)
    nk = sum(sizes)
    R = np.zeros((nl, len(references)))
    for k, name in enumerate(references):
        R[loop_names[name.partition(".")[0]], k] = 1.0
    # u = -Ck xi - Dk (Cy x + D21 w + D22 u - R r)  ->  E u = -Dk Cy x - Ck xi - Dk D21 w + Dk R r
    E = np.eye(nl) + Dk @ D22
    if nl and np.linalg.cond(E) > 1e12:
        raise ModelError("algebraic loop without a solution: I + D_K D_yu is singular (a loop feeds its own "
                         "actuator force back through an acceleration or force measurement with gain -1)")
    Einv = np.linalg.inv(E) if nl else np.zeros((0, 0))
    Ux = -Einv @ Dk @ Cy
    Uxi = -Einv @ Ck
    Uw = -Einv @ Dk @ D21
    Ur = Einv @ Dk @ R
    # y = Cy x + D21 w + D22 u ; e = y - R r
    Ex, Exi, Ew, Er = Cy + D22 @ Ux, D22 @ Uxi, D21 + D22 @ Uw, D22 @ Ur - R
    n = model.n_states
    A_cl = np.block([[A + B2 @ Ux, B2 @ Uxi], [Bk @ Ex, Ak + Bk @ Exi]])
    B_cl = np.block([[B1 + B2 @ Uw, B2 @ Ur], [Bk @ Ew, Bk @ Er]])
    out_C, out_D = [], []
    z_index = {name: k for k, name in enumerate(plant_out_names)}
    for name in outputs:
        head, _, tail = name.partition(".")
        if head in loop_names:
            i = loop_names[head]
            if tail == "y":
                out_C.append(np.concatenate([Ex[i], Exi[i]]))
                out_D.append(np.concatenate([Ew[i], (D22 @ Ur)[i]]))
            else:
                out_C.append(np.concatenate([Ux[i], Uxi[i]]))
                out_D.append(np.concatenate([Uw[i], Ur[i]]))
        else:
            k = z_index[name]
            out_C.append(np.concatenate([Cz[k] + D12[k] @ Ux, D12[k] @ Uxi]))
            out_D.append(np.concatenate([D11[k] + D12[k] @ Uw, D12[k] @ Ur]))
    C_cl = np.array(out_C).reshape(len(outputs), n + nk)
    D_cl = np.array(out_D).reshape(len(outputs), len(forces) + len(references))
    states = model.state_names + [f"{lp.name}.controller{k}" for lp, size in zip(loops, sizes) for k in range(size)]
    return control.ss(A_cl, B_cl, C_cl, D_cl, inputs=[control_name(n) for n in forces + references],
                      outputs=[control_name(n) for n in outputs], states=[control_name(x) for x in states],
                      name=control_name(getattr(system, "name", "")) or None)
