"""1-D lumped chains on the element protocol: the tree, the frequency and the explicit contexts.

A chain ``[start, e_1, ..., e_N, end]`` of lumped elements (``docs/plans/one_core.md`` §2.2, plan
S4A) is a serial tree with point dimension ``d = 1`` (:class:`~ctmm.articulated.Tree`,
``dimension=1``):

* every **point element** (mass, grounded spring/damper) is a body (:meth:`PointElement.terms
  <ctmm.elements.lumped.PointElement.terms>`); consecutive point elements at one connection point
  are bodies joined by welds (joints without free direction);
* every **connector** (spring, damper, spring-damper, inerter) is the joint between the node before
  it and the node after it (:meth:`Connector.terms <ctmm.elements.lumped.Connector.terms>`);
* the **start boundary** is the first body's joint to ground (:meth:`Boundary.terms
  <ctmm.elements.boundary.Boundary.terms>`): weld (``Fixed``), prescribed (base excitation), free,
  elastic or loaded;
* a **massless node** -- a connection point between two connectors, or between a connector and a
  force-type boundary -- is a body without inertia (``M = 0``, ``h = 0``).  Its displacement is
  algebraic: in the frequency context its pivot is ``D = Phi + kappa(s)`` with the connector's
  ``kappa(s) = k + c s + b s^2 != 0``, so the node is well posed wherever the connector's dynamic
  stiffness does not vanish (where it does, today's transfer matrix ``1 / (k + c s)`` is infinite
  too); the implicit context has ``kappa = k cx + c A + b C > 0``; the **explicit context refuses**
  a massless node without inertance next to it (:class:`~ctmm.errors.ModelError`: an ODE needs its
  static condensation, not an acceleration);
* the **end boundary** closes the chain.  A force-type end (``Free``, ``Elastic``,
  ``PrescribedForce``) is a joint whose child is the ground; a displacement-type end (``Fixed``,
  ``PrescribedDisplacement``) makes the last node the ground: the point elements there do not move,
  and the last connector becomes a joint from the last moving node to that moving ground.  Either
  way the end joint's force on the ground, ``F_e = tau + tau_a (a_g - a)`` with
  ``q_rel = x_g - x``, is folded into the last moving body's terms: in the frequency context
  ``Z += kappa(s)``, ``h += tau_u - kappa(s) X_g`` (``tau_u``: the inputs' part of the law), in the
  explicit context ``M += -tau_a``, ``h += tau(q_rel, v_rel) + tau_a a_g``.  This is the one
  closure a serial chain needs (a second grounded leaf, §2.4), solved exactly, not iterated.

Frequency context (:func:`frequency_states`): the terms are linearised about the unstretched rest
configuration (``x = v = 0``, inputs 0), ``Z(s) = s^2 M + s dh/dv + dh/dx`` from the affine form of
the body terms (:func:`ctmm.elements.axial.body_coefficients`), joints ``kappa(s) = -(tau_q + s tau_v + s^2 tau_a)``, loads = the inputs' part of
``h`` and ``tau``; the unknowns are displacement phasors.  The characteristic function is
``prod D_j`` over the free joints (``det`` of the dynamic stiffness of the moving nodes, a
polynomial in ``s``).

Implicit context (:func:`implicit_corrections`): the scheme's ``x = cx delta + dx``,
``v = A delta + B``, ``a = C delta + D`` at every node, joints ``kappa = k cx + c A + b C`` (the
connector's ``k_eff`` of the DT-TMM step), one sweep per step for these linear families.  Explicit
context (:func:`explicit_accelerations`): its special case ``cx = A = 0``, ``C = 1``, ``D = 0``:
``kappa = -tau_a`` (inertance), accelerations of every node.
"""
from __future__ import annotations

from dataclasses import dataclass
from typing import Any, Mapping

import numpy as np

from .articulated import Tree, articulated_sweep
from .errors import ModelError
from .ops import NUMPY, batch_column
from .protocol import BodyTerms, JointTerms, Motion

__all__ = ["MasslessNode", "LumpedTree", "lumped_tree", "frequency_states", "explicit_accelerations",
           "implicit_corrections", "FrequencyStates", "node_inertia", "massless_nodes"]



class MasslessNode:
    """A connection point without inertia between two connectors (body terms ``M = 0``, ``h = 0``)."""

    points = ("in", "out")
    coordinates: tuple[str, ...] = ()
    inputs: tuple[str, ...] = ()
    dimensions = frozenset({1})

    def __init__(self, name: str) -> None:
        self.name = name

    def terms(self, ops, motion: Motion, eta: Any = None, eta_dot: Any = None, t: float = 0.0,
              u: Mapping[str, Any] | None = None) -> BodyTerms:
        """``M = 0``, ``h = 0``, ``Kin = RF = [1]``, ``c = 0`` at ``"out"``."""
        one, zero = ops.eye(1), ops.zeros(1, 1)
        return BodyTerms(M=zero, h=zero + motion.pose[0] * 0.0, Kin={"out": one}, c={"out": zero}, RF={"out": one})


@dataclass(frozen=True)
class LumpedTree:
    """A lumped chain as a serial tree of ``d = 1`` bodies (module docstring).

    Attributes
    ----------
    chain : Chain
    bodies : tuple
        Body descriptions in tree order (point elements and :class:`MasslessNode` objects).
    joints : tuple
        Inboard joint of each body: ``(element, side, position)`` with ``element`` a boundary, a
        connector or ``None`` (weld to the previous body), ``side`` ``"start"`` for a boundary and
        ``position`` the element's position in the chain (0 for the start boundary).
    positions : tuple of int
        Chain position of each body's element (``-1`` for a massless node).
    node : tuple of int
        Node (connection point group) of each body; welded bodies share a node.
    grounded : tuple of bool
        Per node: welded to the ground at the start (``Fixed`` / ``PrescribedDisplacement``).
    cap : tuple
        ``(element, side, position)`` of the end joint folded into the last body (an end boundary
        with ``side = "end"``, or the last connector with the moving ground of a displacement-type end
        as child, ``side = None``).
    wall : tuple of int
        Chain positions of the point elements on a displacement-type end (they do not move).
    point_body : tuple of int
        Body of each chain connection point ``0 .. N`` (``-1``: on the end wall).
    tree : Tree
    """

    chain: Any
    bodies: tuple
    joints: tuple
    positions: tuple[int, ...]
    node: tuple[int, ...]
    grounded: tuple[bool, ...]
    cap: tuple
    wall: tuple[int, ...]
    point_body: tuple[int, ...]
    tree: Tree

    @property
    def n_nodes(self) -> int:
        """Number of nodes (groups of welded bodies)."""
        return len(self.grounded)

    @property
    def wall_moves(self) -> bool:
        """True when the end is displacement-type (its last node is the ground)."""
        return self.cap[1] is None


def lumped_tree(chain) -> LumpedTree:
    """The serial tree of a chain of lumped elements (module docstring).

    Raises
    ------
    ModelError
        When an element is not on the ``d = 1`` protocol (beams, controlled chains), or when no
        node of the chain can move (every point is held by the boundaries).
    """
    if getattr(chain, "layout", None) is None or chain.layout.half != 1 or hasattr(chain, "assemble_frequency"):
        raise ModelError(f"lumped_tree: {chain!r} is not a plain 1-D chain (layout half 1, no loops); only "
                         "lumped 1-D elements are on the element protocol so far")
    for element in chain.elements:
        if not callable(getattr(element, "terms", None)) or 1 not in getattr(element, "dimensions", ()):
            raise ModelError(f"lumped_tree: element {element.name!r} ({type(element).__name__}) of chain "
                             f"{chain.name!r} has no 1-D body or joint terms; only lumped 1-D elements are on "
                             "the element protocol so far")
    bodies, joints, positions, node, grounded = [], [], [], [], []
    point_body = [0]
    pending = (chain.start, "start", 0)           # joint waiting for its child body
    start_grounded = chain.start.known == "displacement"

    def add(body, joint, position):
        new_node = joint is not None
        if new_node:
            grounded.append(joint[0] is chain.start and start_grounded)
        node.append(len(grounded) - 1)
        bodies.append(body)
        joints.append(joint)
        positions.append(position)

    for position, element in enumerate(chain.body, start=1):
        if element.is_point:
            add(element, pending, position)
            pending = None
            point_body.append(len(bodies) - 1)
        else:
            if pending is not None:
                add(MasslessNode(f"{chain.elements[position - 1].name}|{element.name}"), pending, -1)
            pending = (element, None, position)
            point_body.append(len(bodies))        # the next body (or the wall, fixed below)
    wall: list[int] = []
    if chain.end.known == "displacement":
        if pending is not None:
            cap = pending
        else:                                     # trailing point elements are on the wall
            first = len(bodies) - 1
            while joints[first] is None:
                first -= 1
            cap = joints[first]
            if cap[0] is chain.start:
                raise ModelError(f"lumped_tree: no point of chain {chain.name!r} can move (no connector between "
                                 "its start and its displacement-type end)")
            wall = positions[first:]
            del bodies[first:], joints[first:], positions[first:], node[first:]
            grounded[:] = grounded[:node[-1] + 1] if node else []
        cap = (cap[0], None, cap[2])
        point_body = [b if b < len(bodies) else -1 for b in point_body]
    else:
        if pending is not None:
            add(MasslessNode(f"{chain.elements[-2].name}|{chain.end.name}"), pending, -1)
        cap = (chain.end, "end", len(chain.elements) - 1)
    if all(grounded):
        raise ModelError(f"lumped_tree: no point of chain {chain.name!r} can move")
    tree = Tree(parent=tuple(range(-1, len(bodies) - 1)), point=(None,) + ("out",) * (len(bodies) - 1),
                dimension=1)
    return LumpedTree(chain, tuple(bodies), tuple(joints), tuple(positions), tuple(node), tuple(grounded),
                      cap, tuple(wall), tuple(point_body), tree)


def _joint(tree: LumpedTree, entry, q_rel, v_rel, t, u) -> JointTerms:
    if entry is None:
        return JointTerms(S=NUMPY.zeros(1, 0))                      # weld
    element, side, _ = entry
    if side is not None:
        return element.terms(NUMPY, q_rel, v_rel, t, u, side=side)
    return element.terms(NUMPY, q_rel, v_rel, t, u)


def _inputs(amplitudes: Mapping, entry) -> dict:
    return dict(amplitudes.get(entry[2], {})) if entry is not None else {}


def _motion(x, v) -> Motion:
    return Motion(pose=(x,), twist=(v,))


def _kappa(joint: JointTerms, s: np.ndarray) -> np.ndarray | None:
    if joint.tau is None or joint.free == 0:
        return None
    out = -(joint.tau_q + s * joint.tau_v)
    return out if joint.tau_a is None else out - s * s * joint.tau_a


@dataclass(frozen=True)
class FrequencyStates:
    """Solution of the frequency context.

    Attributes
    ----------
    states : ndarray, shape (N + 1, B, 2)
        ``[x, f]`` phasors at every chain connection point (as :class:`ctmm.assembly.ChainSolution`).
    characteristic : ndarray, shape (B,)
        ``prod D_j`` over the free joints (1 when none).
    """

    states: np.ndarray
    characteristic: np.ndarray


def frequency_states(tree: LumpedTree, s: Any, amplitudes: Mapping[int, Mapping[str, Any]] | None = None
                     ) -> FrequencyStates:
    """States of the chain at Laplace variables ``s`` from the element terms (module docstring).

    Parameters
    ----------
    tree : LumpedTree
    s : array_like
        Laplace variables [1/s], 1-D.
    amplitudes : mapping, optional
        ``{element position: {input name: phasor}}`` as :func:`ctmm.chain_assembly.solve` takes them
        (``"displacement"`` of a prescribed boundary is a displacement phasor [m]).

    Returns
    -------
    FrequencyStates
    """
    amplitudes = amplitudes or {}
    s = np.atleast_1d(np.asarray(s, dtype=complex)).reshape(-1, 1, 1)
    batch = s.shape[0]
    zero = np.zeros((1, 1, 1))
    body_Z, body_h, joint_terms, kappa = [], [], [], []
    for body, entry, position in zip(tree.bodies, tree.joints, tree.positions):
        Zj, hj = _frequency_body(body, s, dict(amplitudes.get(position, {})) if position >= 0 else {})
        body_Z.append(Zj)
        body_h.append(hj)
        joint, k = _frequency_joint(tree, entry, s, amplitudes)
        joint_terms.append(joint)
        kappa.append(k)
    Z, h = list(body_Z), list(body_h)
    cap_joint, cap_kappa = _frequency_joint(tree, tree.cap, s, amplitudes)
    X_g = _wall_displacement(tree, amplitudes, batch)
    if cap_kappa is not None:
        Z[-1] = Z[-1] + cap_kappa
        h[-1] = h[-1] + cap_joint.tau - cap_kappa * X_g
    elif cap_joint.tau is not None:
        h[-1] = h[-1] + cap_joint.tau
    terms = [BodyTerms(M=Zj, h=hj, Kin={"out": NUMPY.eye(1)}, c={"out": zero}, RF={"out": NUMPY.eye(1)})
             for Zj, hj in zip(Z, h)]
    with np.errstate(divide="ignore", invalid="ignore"):
        sweep = articulated_sweep(NUMPY, tree.tree, terms, joint_terms, kappa, characteristic=True)
    x = [xj[:, 0, 0] for xj in sweep.x]
    f_in = [fj[:, 0, 0] for fj in sweep.force]
    f_out = [f_in[j] - (body_Z[j][:, 0, 0] * x[j] + body_h[j][:, 0, 0]) for j in range(len(x))]
    return FrequencyStates(_point_states(tree, x, f_in, f_out, X_g[:, 0, 0], s, amplitudes),
                           np.ones(batch, dtype=complex) if sweep.characteristic is None
                           else sweep.characteristic[:, 0, 0])


def _frequency_body(body, s: np.ndarray, u: Mapping) -> tuple[np.ndarray, np.ndarray]:
    """``Z(s) = M s^2 + (dh/dv) s + dh/dx`` and the inputs' part of ``h`` (affine form of the terms)."""
    batch = s.shape[0]
    if isinstance(body, MasslessNode):
        return np.zeros((batch, 1, 1), dtype=complex), np.zeros((batch, 1, 1), dtype=complex)
    co = body.axial_coefficients()
    load = sum((co.inputs[key] * value for key, value in u.items()), 0.0)
    return (co.inertia * s * s + co.damping * s + co.stiffness + np.zeros((batch, 1, 1)),
            np.zeros((batch, 1, 1), dtype=complex) + load)


def _frequency_joint(tree: LumpedTree, entry, s: np.ndarray, amplitudes: Mapping):
    """Joint terms of the frequency context: law's input part as ``tau``, ``kappa(s)``."""
    if entry is None:
        return JointTerms(S=NUMPY.zeros(1, 0)), None
    zero = np.zeros((1, 1, 1))
    u = _inputs(amplitudes, entry)
    rest = _joint(tree, entry, zero, zero, 0.0, {})
    loaded = _joint(tree, entry, zero, zero, 0.0, u)
    if loaded.prescribed is not None:
        return JointTerms(S=loaded.S, prescribed=loaded.prescribed + np.zeros((s.shape[0], 1, 1))), None
    if loaded.free == 0:
        return loaded, None
    tau = loaded.tau - rest.tau + np.zeros((s.shape[0], 1, 1), dtype=complex)
    joint = JointTerms(S=loaded.S, tau=tau, tau_q=loaded.tau_q, tau_v=loaded.tau_v, tau_a=loaded.tau_a)
    return joint, _kappa(joint, s)


def _wall_displacement(tree: LumpedTree, amplitudes: Mapping, batch: int) -> np.ndarray:
    """Displacement phasor of the moving ground at a displacement-type end (0 otherwise)."""
    if not tree.wall_moves:
        return np.zeros((batch, 1, 1), dtype=complex)
    end = tree.chain.end
    value = _joint(tree, (end, "end", 0), 0.0, 0.0, 0.0, amplitudes.get(len(tree.chain.elements) - 1, {}))
    prescribed = value.prescribed if value.prescribed is not None else np.zeros((1, 1, 1))
    return np.zeros((batch, 1, 1), dtype=complex) + prescribed


def _point_states(tree: LumpedTree, x, f_in, f_out, x_wall, s, amplitudes) -> np.ndarray:
    chain = tree.chain
    batch = s.shape[0]
    states = np.zeros((chain.n_points, batch, 2), dtype=complex)
    body_of_position = {p: j for j, p in enumerate(tree.positions) if p >= 0}
    states[0, :, 0], states[0, :, 1] = x[0], f_in[0]
    for position in range(1, chain.n_points):
        j = tree.point_body[position]
        element = chain.elements[position]
        if j >= 0:
            states[position, :, 0] = x[j]
            states[position, :, 1] = f_out[j] if position in body_of_position else f_in[j]
            continue
        states[position, :, 0] = x_wall
        if position in tree.wall:                 # a point element on the wall: f_out = f_in - (Z X + h)
            Zw, load = _frequency_body(element, s, dict(amplitudes.get(position, {})))
            states[position, :, 1] = states[position - 1, :, 1] - (Zw[:, 0, 0] * x_wall + load[:, 0, 0])
        else:                                     # the connector into the wall carries f_out of the last body
            states[position, :, 1] = f_out[-1]
    return states


def explicit_accelerations(tree: LumpedTree, x: Any, v: Any, t: float = 0.0,
                           inputs: Mapping[int, Mapping[str, Any]] | None = None, *,
                           wall: tuple[Any, Any, Any] = (0.0, 0.0, 0.0), massless: str = "refuse") -> np.ndarray:
    """Accelerations of the nodes from the element terms (explicit context, ``kappa = -tau_a``).

    Parameters
    ----------
    tree : LumpedTree
    x, v : array_like, shape (B, n_nodes) or (n_nodes,)
        Displacements [m] and velocities [m/s] of the nodes (:attr:`LumpedTree.node`); nodes welded
        to a ``Fixed`` start must be given at its position (they are not checked).  The ground of a
        displacement-type end is at rest at 0.
    t : float
        Time [s] (passed to the terms).
    inputs : mapping, optional
        ``{element position: {input name: value}}`` (forces [N]; ``"displacement"`` of a prescribed
        start boundary as an acceleration [m/s^2]).
    wall : tuple of float or arrays
        Position [m], velocity [m/s] and acceleration [m/s^2] of the ground of a displacement-type
        end (``Fixed(position=...)``, ``PrescribedDisplacement``); ignored for a force-type end.
    massless : {"refuse", "residual"}
        What to do with the nodes without mass and without inertance next to them
        (:func:`node_inertia` ``== 0``): refuse them (:class:`ModelError`), or return the **net force
        [N]** on each of them in its column (``"residual"``: the caller condenses them, e.g.
        :mod:`ctmm.chain_ode`).  In the explicit context such a node is decoupled from the others
        (its joints have ``kappa = -tau_a = 0``), so a unit placeholder inertia at it changes no
        other node's acceleration and its own "acceleration" is the force on it.

    Returns
    -------
    ndarray, shape (B, n_nodes)
        Accelerations [m/s^2] (``"residual"``: forces [N] at the massless nodes).

    Raises
    ------
    ModelError
        When a node has neither mass nor inertance next to it (its displacement is algebraic) and
        ``massless="refuse"``.
    """
    xs = np.atleast_2d(np.asarray(x, dtype=float))
    if massless not in ("refuse", "residual"):
        raise ModelError(f"explicit_accelerations: massless must be 'refuse' or 'residual', got {massless!r}")
    if massless == "refuse":
        _require_inertia(tree)
        placeholder: tuple[int, ...] = ()
    else:
        placeholder = tuple(int(k) for k in np.flatnonzero(massless_nodes(tree)))
    wall_parts = (wall[0], wall[1], 0.0, wall[2])
    return implicit_corrections(tree, 0.0, 0.0, 1.0, x, v, np.zeros_like(xs), t, inputs,
                                wall=wall_parts, _placeholder=placeholder)


def implicit_corrections(tree: LumpedTree, cx: float, A: float, C: float, dx: Any, B: Any, D: Any,  # noqa: N803
                         t: float = 0.0, inputs: Mapping[int, Mapping[str, Any]] | None = None, *,
                         wall: tuple[Any, Any, Any, Any] = (0.0, 0.0, 0.0, 0.0),
                         _placeholder: tuple[int, ...] = ()) -> np.ndarray:
    """The implicit (DT-TMM) context: the step's unknowns ``delta`` of the nodes by one sweep.

    Every node's kinematics at the step's evaluation level are affine in its unknown,
    ``x = cx delta + dx``, ``v = A delta + B``, ``a = C delta + D`` (:mod:`ctmm.schemes`).  Bodies
    become ``M_eff = M C + (dh/dv) A + (dh/dx) cx``, ``h_eff = h(dx, B, u) + M D``; joints
    ``kappa = -(tau_q cx + tau_v A + tau_a C)`` (the connector's ``k_eff``) and
    ``tau_eff = tau(dx_out - dx_in, B_out - B_in, u) + tau_a (D_out - D_in)``; the end joint to a
    resting ground folds ``kappa`` and ``tau(-dx, -B) - tau_a D`` into the last body.  The explicit
    context is ``cx = A = 0``, ``C = 1``, ``D = 0`` (then ``delta = a``).  Linear families (their
    tangents from :meth:`~ctmm.elements.axial.AxialBody.axial_coefficients`), one sweep: no Newton
    iteration is needed.

    Parameters
    ----------
    tree : LumpedTree
    cx, A, C : float
        The scheme's coefficients [-, 1/s, 1/s^2] (the same at every node).
    dx, B, D : array_like, shape (B, n_nodes) or (n_nodes,)
        Per node: displacement [m], velocity [m/s] and acceleration [m/s^2] parts independent of
        ``delta``.  Ground-welded nodes and the resting ground of a displacement-type end have
        ``delta = 0``.
    t : float
        Time [s] of the evaluation level.
    inputs : mapping, optional
        ``{element position: {input name: value}}`` at the evaluation level (``"displacement"`` of a
        prescribed start: its ``delta``).
    wall : tuple
        ``(dx, B, delta, D)`` of the ground of a displacement-type end (its position [m], velocity
        [m/s], its known ``delta`` and acceleration part [m/s^2]; all 0 for a ground at rest at 0).

    Returns
    -------
    ndarray, shape (B, n_nodes)
        ``delta`` per node.
    """
    inputs = inputs or {}
    columns = [np.atleast_2d(np.asarray(value, dtype=float)) for value in (dx, B, D)]
    if any(c.shape != columns[0].shape or c.shape[1] != tree.n_nodes for c in columns):
        raise ModelError(f"lumped_forms: the node values must have shape (B, {tree.n_nodes}) (one entry per node), "
                         f"got {[c.shape for c in columns]}")
    dxn, Bn, Dn = ([batch_column(c[:, [k]]) for k in range(tree.n_nodes)] for c in columns)
    bodies, joints, kappa = [], [], []
    for j, (body, entry, position) in enumerate(zip(tree.bodies, tree.joints, tree.positions)):
        k = tree.node[j]
        u = dict(inputs.get(position, {})) if position >= 0 else {}
        terms = body.terms(NUMPY, _motion(dxn[k], Bn[k]), t=t, u=u)
        M, h = terms.M * C, terms.h + terms.M * Dn[k]
        if not isinstance(body, MasslessNode) and (cx or A):
            co = body.axial_coefficients()
            M = M + (co.damping * A + co.stiffness * cx)
        if k in _placeholder and (j == 0 or tree.node[j - 1] != k):
            M = M + NUMPY.eye(1)                                    # unit placeholder of a massless node
        bodies.append(BodyTerms(M=M, h=h, Kin=terms.Kin, c=terms.c, RF=terms.RF))
        parent = tree.node[j - 1] if j > 0 else None
        relative = [value[k] - (value[parent] if parent is not None else 0.0) for value in (dxn, Bn, Dn)]
        joint, tangent = _step_joint(tree, entry, relative, cx, A, C, t, _inputs(inputs, entry))
        joints.append(joint)
        kappa.append(tangent)
    last = tree.node[-1]
    ground = [batch_column(np.atleast_2d(np.asarray(value, dtype=float)).reshape(-1, 1)) for value in wall]
    cap, tangent = _step_joint(tree, tree.cap, [ground[0] - dxn[last], ground[1] - Bn[last], ground[3] - Dn[last]],
                               cx, A, C, t, _inputs(inputs, tree.cap))
    if cap.tau is not None and cap.free:
        M, h = bodies[-1].M, bodies[-1].h + cap.tau
        if tangent is not None and tree.wall_moves:                 # the ground's known delta
            h = h - tangent * ground[2]
        if tangent is not None:
            M = M + tangent
        bodies[-1] = BodyTerms(M=M, h=h, Kin=bodies[-1].Kin, c=bodies[-1].c, RF=bodies[-1].RF)
    sweep = articulated_sweep(NUMPY, tree.tree, bodies, joints, kappa)
    out = np.zeros_like(columns[0])
    for j, xj in enumerate(sweep.x):
        out[:, tree.node[j]] = xj[:, 0, 0]
    return out


def _step_joint(tree: LumpedTree, entry, relative, cx: float, A: float, C: float, t: float, u: Mapping):
    """Joint terms of the implicit context: ``tau_eff`` and ``kappa`` (module docstring)."""
    q_rel, v_rel, a_rel = relative
    joint = _joint(tree, entry, q_rel, v_rel, t, u)
    if joint.tau is None or joint.free == 0:
        return joint, None
    tau, tangent = joint.tau, None
    for value, coefficient in ((joint.tau_q, cx), (joint.tau_v, A), (joint.tau_a, C)):
        if value is not None and coefficient:
            tangent = -value * coefficient if tangent is None else tangent - value * coefficient
    if joint.tau_a is not None:
        tau = tau + joint.tau_a * a_rel
    return JointTerms(S=joint.S, tau=tau, tau_q=joint.tau_q, tau_v=joint.tau_v, tau_a=joint.tau_a), tangent


def node_inertia(tree: LumpedTree) -> np.ndarray:
    """Per node: its mass plus the inertance of the connectors touching it [kg].

    A node that is not held by the start and has ``node_inertia == 0`` is **massless**: its
    displacement is algebraic (between springs) or a first-order state (next to a damper), never an
    acceleration (:func:`massless_nodes`).
    """
    inertance = {}
    for j, entry in enumerate(tree.joints):
        if entry is not None and entry[1] is None:                  # a connector
            b = _inertance(entry[0])
            inertance[tree.node[j]] = inertance.get(tree.node[j], 0.0) + b
            if j > 0:
                inertance[tree.node[j - 1]] = inertance.get(tree.node[j - 1], 0.0) + b
    if tree.cap[1] is None:
        b = _inertance(tree.cap[0])
        inertance[tree.node[-1]] = inertance.get(tree.node[-1], 0.0) + b
    out = np.zeros(tree.n_nodes)
    for j, body in enumerate(tree.bodies):
        if not isinstance(body, MasslessNode):
            out[tree.node[j]] += body.axial_coefficients().inertia
    for k, b in inertance.items():
        out[k] += b
    return out


def _inertance(joint: Any) -> float:
    """A connector's inertance [kg]: its ``inertance`` attribute where it states one (a connector with a
    nonlinear law has no constant coefficients to read it from), else from its affine form."""
    stated = getattr(joint, "inertance", None)
    return float(stated) if stated is not None else joint.axial_coefficients().inertia


def massless_nodes(tree: LumpedTree) -> np.ndarray:
    """Boolean mask of the massless nodes (not held by the start, :func:`node_inertia` ``== 0``)."""
    return (node_inertia(tree) == 0.0) & ~np.asarray(tree.grounded, dtype=bool)


def _require_inertia(tree: LumpedTree) -> None:
    """Refuse nodes whose displacement is algebraic in the explicit context."""
    for k in np.flatnonzero(massless_nodes(tree)):
        names = [tree.bodies[j].name for j in range(len(tree.bodies)) if tree.node[j] == k]
        raise ModelError(f"explicit_accelerations: node {k} ({', '.join(names)}) of chain {tree.chain.name!r} has "
                         "no mass and no inertance next to it: its displacement is algebraic (a static "
                         "condensation, not an acceleration); the frequency and implicit contexts solve it, and "
                         "massless='residual' returns the force on it for a condensation (ctmm.chain_ode)")
