"""Frequency responses of planar models by the one sweep's frequency context, batched over omega.

Rigid trees, modal beams and ``ctmm.fem`` subsystems (every body on the element protocol).  About a static
operating point ``q0`` the linearised body terms are ``Z_j(s) = s^2 M0 + s C0 + K0`` and
the joints ``kappa(s) = k + c s`` (:meth:`ctmm.planar.body_forms.PlanarScene.linear_terms`).  One
articulated sweep (:func:`ctmm.articulated.articulated_sweep`) on these terms, numpy-batched over all
``s = i omega`` at once, solves the dynamic-stiffness equations ``Z(s) x = f`` of the whole tree in
``O(N)`` per frequency, where

* the right-hand side ``f`` is one actuator at unit amplitude (one sweep per input column): a hinge
  torque is the amplitude of its joint's ``tau``; a body force or moment, a beam's modal force and a
  station force or moment load the body terms ``h = -[wrench at the inboard point ; modal forces]``
  (:meth:`ctmm.planar.ports.ActuatorInputs.inboard_wrench` at ``q0``);
* the unknowns are the displacement amplitudes ``x = [dx, dy, dtheta ; d eta]`` of every body, mapped to
  the coordinate amplitudes ``q_hat`` (:meth:`~ctmm.planar.body_forms.PlanarScene.coordinate_accelerations`);
* a sensor is the linear functional ``y = (dy/dq + s dy/dqdot) q_hat``
  (:func:`ctmm.planar_linearization.output_matrix`: angles, positions, their rates ``s x``, hinge angles,
  beam stations, coordinates).

The answer holds ``O(outputs x inputs x frequencies)`` numbers; the sweep's batched terms, while it runs,
``O(N x CHUNK)`` (frequencies are swept :data:`CHUNK` at a time).  The
feedback loops of a ``ControlledModel`` (with and without delay, static or LTI ``C(s)``) are closed at
each frequency by the phasor formula ``(I + K G_yu) u = K (r - G_yw w)``, ``K = diag(C_l(s) e^{-s tau_l})``
(:func:`ctmm.loop_phasors.close_loops`; a loop without delay is ``tau = 0``).

Certified or handed back, never a silent wrong number: at each frequency every pivot the sweep divides by
(joint pivots ``D_j``, modal blocks ``C_j``) is measured against the size of the terms it is made of; a
pivot below :data:`PIVOT_TOLERANCE` of them (``s`` at or next to a pole of the model, or a resonance of a
substructure that the elimination meets as a zero pivot), a non-finite answer, or a loop matrix
``I + K G_yu`` whose smallest singular value is below ``(1 + |K G_yu|_2) / RESOLVENT_CONDITION`` (a closed-loop
pole at or next to ``s``; :data:`~ctmm.controlled_linearization.RESOLVENT_CONDITION`)
marks that frequency as not answered here; :func:`ctmm.planar_frequency.frequency_response` answers
those by the dense resolvent, which answers or refuses them (its rule).

Not stated here (the caller uses the dense linearisation for the whole response): hinges with
translational springs and nonlinear hinges, beams with user state laws (not complex-step safe), a
moving or time-varying operating point, names that are not plain actuator / sensor / loop ports.
"""
from __future__ import annotations

from typing import Any, Sequence

import numpy as np

from .articulated import articulated_sweep, frequency_kappa
from .controlled_linearization import RESOLVENT_CONDITION, controller_response, loop_ports
from .errors import ModelError
from .loop_phasors import close_loops as close_phasor_loops
from .ops import NUMPY
from .protocol import BodyTerms, JointTerms

__all__ = ["SweepResponse", "closed_loop_response", "sweep_applies", "PIVOT_TOLERANCE", "CHUNK"]

PIVOT_TOLERANCE = float(np.sqrt(np.finfo(float).eps))
"""Smallest accepted pivot of the sweep relative to the terms it is made of (``sqrt(eps)``, about 1.5e-8; the
counterpart of the resolvent's ``1/sqrt(eps)`` condition bound): below it the elimination may lose more than
half the digits and the frequency is handed to the dense resolvent."""

CHUNK = 512
"""Frequencies swept at once (the batched terms of the sweep hold ``O(N CHUNK)`` numbers)."""


def sweep_applies(model: Any, point: Any) -> bool:
    """True when the one sweep's frequency context states ``model`` about ``point`` (module docstring):
    revolute (linear laws), driven, welded and free-base joints, rigid bodies and modal beams without user
    state laws, at a static operating point."""
    from .planar.model import BUSHING

    if np.any(point.qdot != 0.0) or not point.equilibrium or model.nonlinear_hinges:
        return False
    if any(int(kind) == BUSHING for kind in model.joint_kind):
        return False
    return not any(beam.data.laws for beam in model.beams.values())


class SweepResponse:
    """The open-loop response ``G(s)`` of a planar model about a static operating point by the batched sweep.

    Parameters
    ----------
    model : PlanarModel
    point : OperatingPoint
        A static equilibrium (:func:`ctmm.planar_linearization.operating_point`).
    ports : PlanarPorts, optional
        The model's resolved ports (built when omitted).

    Raises
    ------
    ModelError
        The model is not stated by the sweep (:func:`sweep_applies`), or ``point`` is not an equilibrium.
    """

    def __init__(self, model: Any, point: Any, ports: Any = None) -> None:
        from .planar.body_forms import PlanarScene
        from .planar.ports import PlanarPorts

        if not sweep_applies(model, point):
            raise ModelError(f"the one sweep's frequency context does not state {model.name!r} (hinges with "
                             "translational springs, nonlinear hinges, beams with user laws, or a moving point)")
        self.model, self.point = model, point
        self.scene = PlanarScene(model)
        self.terms = self.scene.linear_terms(point.q, point.t)
        self.ports = PlanarPorts(model) if ports is None else ports
        self.theta = np.asarray(model.body_angles(point.q, np.zeros(model.n_coordinates), point.t)[0], dtype=float)
        # the pivots of the mass terms alone (s^2 = 1): the inertia part of every pivot, the scale it is measured by
        inertia = [BodyTerms(M0[None], np.zeros((1, M0.shape[0], 1)), Kin, dict.fromkeys(Kin), RF)
                   for M0, _, _, Kin, RF in self.terms.bodies]
        with np.errstate(all="ignore"):
            masses = articulated_sweep(NUMPY, self.terms.tree, inertia, self.terms.joints, forces=False)
        self.mass_pivots, self.mass_modal = masses.pivot, masses.modal
        sizes: dict = {}
        for j, body in enumerate(self.terms.bodies):
            sizes.setdefault(body[0].shape[0], []).append(j)
        # (members, M0, C0, K0) per body size, stacked (members, 1, size, size): Z of all of them in one operation
        self.stacks = [(members, *(np.stack([self.terms.bodies[j][k] for j in members])[:, None] for k in range(3)))
                       for members in sizes.values()]
        self.undamped = not any(np.any(C0) for _, C0, _, _, _ in self.terms.bodies) and not any(
            joint.tau_v is not None and np.any(joint.tau_v) for joint in self.terms.joints)

    def _loads(self, name: str) -> tuple[list, list]:
        """Body load columns ``h`` (1, 3 + n_j, 1) and joint terms of actuator ``name`` at unit amplitude."""
        inputs = self.ports.inputs({name: 1.0})
        wrench = inputs.inboard_wrench(self.model, self.theta)
        loads = []
        for j, (M0, _, _, _, _) in enumerate(self.terms.bodies):
            h = np.zeros((1, M0.shape[0], 1))
            h[0, :3, 0] = -wrench[j]
            if j in inputs.modal_force:
                h[0, 3:, 0] = -np.asarray(inputs.modal_force[j], dtype=float)
            loads.append(h)
        joints = []
        for j, joint in enumerate(self.terms.joints):
            if joint.axis is not None and joint.prescribed is None and inputs.hinge_torque[j] != 0.0:
                joints.append(JointTerms(S=joint.S, tau=np.full((1, 1, 1), float(inputs.hinge_torque[j])),
                                         tau_q=joint.tau_q, tau_v=joint.tau_v, axis=joint.axis))
            else:
                joints.append(joint)
        return loads, joints

    def response(self, s: np.ndarray, inputs: Sequence[str], outputs: Sequence[str]
                 ) -> tuple[np.ndarray, np.ndarray]:
        """``G[k, i_out, i_in]`` at the Laplace variables ``s`` (B,) and a mask (B,) of the frequencies it
        certifies (module docstring); entries at the others are not meaningful.

        Parameters
        ----------
        s : ndarray of complex, shape (B,)
            ``i omega`` [1/s].
        inputs : sequence of str
            Actuator names (:func:`ctmm.planar.ports.actuator_names`).
        outputs : sequence of str
            Sensor names (:func:`ctmm.planar.ports.sensor_names`).
        """
        from .planar_linearization import output_matrix

        for name in inputs:
            self.ports.check_actuator(name)
        for name in outputs:
            self.ports.check_sensor(name)
        s = np.asarray(s, dtype=complex).reshape(-1)
        rows = output_matrix(self.model, list(outputs), self.point)            # (outputs, 2 n): [dy/dq, dy/dqdot]
        loads = [self._loads(name) for name in inputs]
        G = np.zeros((s.size, len(outputs), len(inputs)), dtype=complex)
        good = np.zeros(s.size, dtype=bool)
        for start in range(0, s.size, CHUNK):       # the sweep's batched terms: O(N CHUNK) at a time
            part = slice(start, min(start + CHUNK, s.size))
            try:
                G[part], good[part] = self._batch(s[part], loads, rows)
                continue
            except np.linalg.LinAlgError:   # an exactly singular block at some s (a free base at omega = 0)
                pass
            for k in range(part.start, part.stop):
                try:
                    G[k:k + 1], good[k:k + 1] = self._batch(s[k:k + 1], loads, rows)
                except np.linalg.LinAlgError:
                    pass
        return G, good

    def _batch(self, s: np.ndarray, loads: list, rows: np.ndarray) -> tuple[np.ndarray, np.ndarray]:
        """:meth:`response` of the load cases ``loads`` (:meth:`_loads`) and sensor ``rows`` at ``s`` (B,)."""
        n = self.model.n_coordinates
        column = s.reshape(-1, 1, 1)
        if self.undamped and not np.any(s.real):    # s^2 = -omega^2: the whole sweep is real (same numbers, faster)
            stiffness = self._dynamic_stiffness((column * column).real, None)
            kappa = frequency_kappa(NUMPY, self.terms.joints, 0.0)
        else:
            stiffness = self._dynamic_stiffness(column * column, column)
            kappa = frequency_kappa(NUMPY, self.terms.joints, column)
        G = np.zeros((s.size, rows.shape[0], len(loads)), dtype=complex)
        good = np.ones(s.size, dtype=bool)
        for i, (body_loads, joints) in enumerate(loads):
            bodies = [BodyTerms(Z, h, Kin, dict.fromkeys(Kin), RF)           # c = None: zero
                      for Z, h, (_, _, _, Kin, RF) in zip(stiffness, body_loads, self.terms.bodies)]
            with np.errstate(all="ignore"):
                solution = articulated_sweep(NUMPY, self.terms.tree, bodies, joints, kappa, forces=False)
                amplitudes = self.scene.coordinate_accelerations(solution)       # q_hat (B, n)
                G[:, :, i] = amplitudes @ rows[:, :n].T + (s[:, None] * amplitudes) @ rows[:, n:].T
            if i == 0:
                good &= self._pivots_certified(solution, s)
            good &= np.all(np.isfinite(G[:, :, i]), axis=1)
        return G, good

    def _dynamic_stiffness(self, squared: np.ndarray, column: np.ndarray | None) -> list:
        """``Z_j = s^2 M0 + s C0 + K0`` (B, 3 + n_j, 3 + n_j) of every body (``column`` ``None``: no ``C0`` term),
        formed for all bodies of one size in one array operation."""
        out: list = [None] * len(self.terms.bodies)
        for members, M0, C0, K0 in self.stacks:
            Z = squared * M0 + K0 if column is None else squared * M0 + column * C0 + K0
            for position, j in enumerate(members):
                out[j] = Z[position]
        return out

    def _pivots_certified(self, solution: Any, s: np.ndarray) -> np.ndarray:
        """(B,) True where every pivot ``P(s)`` (joint ``D_j``, modal ``C_j``) is at least :data:`PIVOT_TOLERANCE`
        of the terms it is made of: its smallest singular value against ``|s|^2 |P_M| + |P(s) - s^2 P_M|``
        (``P_M``: the same pivot of the mass terms alone, a positive articulated inertia; the second part the
        stiffness, damping and joint-law terms), largest moduli.  At a resonance of the model or of the
        substructure the pivot closes, ``s^2 P_M`` and the stiffness cancel, and the ratio falls."""
        good = np.ones(s.size, dtype=bool)
        squared = (s * s).reshape(-1, 1, 1)
        with np.errstate(all="ignore"):
            for pivot, mass in zip(solution.pivot + solution.modal, self.mass_pivots + self.mass_modal):
                if pivot is None:
                    continue
                inertia = squared * mass
                scale = np.abs(inertia).max(axis=(-2, -1)) + np.abs(pivot - inertia).max(axis=(-2, -1))
                good &= _smallest_singular(pivot) >= PIVOT_TOLERANCE * scale
        return good


def _smallest_singular(blocks: np.ndarray) -> np.ndarray:
    """Smallest singular value of each block (B, k, k) (``|D|`` for 1 x 1)."""
    if blocks.shape[-1] == 1:
        return np.abs(blocks[..., 0, 0])
    values = np.linalg.svd(blocks, compute_uv=False)
    return np.where(np.all(np.isfinite(values), axis=-1), values[..., -1], 0.0)


def closed_loop_response(plant: SweepResponse, loops: Sequence[Any], s: np.ndarray, inputs: Sequence[str],
                         outputs: Sequence[str]) -> tuple[np.ndarray, np.ndarray]:
    """``response[i_out, i_in, k]`` of the plant with ``loops`` closed at each ``s`` and the mask (B,) of the
    certified frequencies (module docstring).  ``inputs``: actuators and ``"<loop>.reference"``;
    ``outputs``: sensors, ``"<loop>.y"`` and ``"<loop>.u"`` (of loops with and without delay)."""
    index = {lp.name: j for j, lp in enumerate(loops)}

    def loop_signal(name: str, parts: tuple) -> tuple | None:
        head, _, tail = name.partition(".")
        return (index[head], tail) if head in index and tail in parts else None

    plain_in = [x for x in inputs if loop_signal(x, ("reference",)) is None]
    plain_out = [x for x in outputs if loop_signal(x, ("y", "u")) is None]
    actuators, sensors = loop_ports(loops)
    plant_in = list(dict.fromkeys(plain_in + actuators))
    plant_out = list(dict.fromkeys(plain_out + sensors))
    G, good = plant.response(s, plant_in, plant_out)
    # plant ports -> [plain inputs, one force per loop], [plain outputs, one sensed sum per loop]
    S_in = np.zeros((len(plant_in), len(plain_in) + len(loops)))
    S_out = np.zeros((len(plain_out) + len(loops), len(plant_out)))
    for k, name in enumerate(plain_in):
        S_in[plant_in.index(name), k] = 1.0
    for k, name in enumerate(plain_out):
        S_out[k, plant_out.index(name)] = 1.0
    for j, lp in enumerate(loops):
        for name, weight in lp.actuator_terms:
            S_in[plant_in.index(name), len(plain_in) + j] += weight
        for name, weight in lp.terms:
            S_out[len(plain_out) + j, plant_out.index(name)] += weight
    G = S_out @ G @ S_in
    n_i, n_o = len(plain_in), len(plain_out)
    blocks = (G[:, :n_o, :n_i], G[:, :n_o, n_i:], G[:, n_o:, :n_i], G[:, n_o:, n_i:])
    K = np.zeros((s.size, len(loops), len(loops)), dtype=complex)
    for j, loop in enumerate(loops):
        K[:, j, j] = controller_response(loop.gain, s) * np.exp(-s * loop.delay)
    if loops:                       # I + K G_yu against its terms: a closed-loop pole on the axis closes it
        with np.errstate(all="ignore"):
            loop = np.where(good[:, None, None], K @ blocks[3], 0.0)
            smallest = np.linalg.svd(np.eye(len(loops)) + loop, compute_uv=False)[:, -1]
            largest = np.linalg.svd(loop, compute_uv=False)[:, 0]
        good &= smallest * RESOLVENT_CONDITION >= 1.0 + largest
        blocks = tuple(np.where(good[:, None, None], b, 0.0) for b in blocks)
    return close_phasor_loops(blocks, K, inputs, outputs, plain_in, plain_out, loop_signal), good
