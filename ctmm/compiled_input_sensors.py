"""Loop sensors that respond to the actuators at once (cut forces), closed inside generated kernels.

A cut force of a kinematic loop model is solved with the accelerations under the actuator values of the instant:
``F = F(q, v, w, t)`` with ``w`` the kernel's actuator values (held inputs, the loops' outputs, open-loop inputs).
For given ``(q, v, t)`` the constrained dynamics are linear in the applied loads, so ``F = F_0(q, v, t) + J(q, v,
t) w`` exactly; the plant's symbols state ``F_0`` and ``J`` on casadi symbols
(``symbols.input_sensor_map(names, n_actuators)``, by :func:`affine_sensor_map`; the planar kinematic loop models of
:class:`ctmm.compiled_kinematic_loop_control.KinematicLoopSymbols` and the spatial ones of
:class:`ctmm.compiled_spatial_loop_symbols.SpatialKinematicLoopSymbols`, affine certified: ``J`` does not depend on
``w``).
:class:`InputDependentSensors` closes the loops of :class:`ctmm.compiled_loops.ClosedLoops` that read them:

* **real-time loops** (``tau = 0``) on them are algebraic, ``u = -(C z + D (y_0 + g (w_0 + W u) - r))``: the small
  linear system ``(I + D g W) u = -(C z + D (y_0 + g w_0 - r))`` is solved on symbols at every evaluation (symbolic
  QR); saturation on such a loop is refused (the loop would be piecewise affine), and a system singular at the start
  state is refused by name (:meth:`InputDependentSensors.check_start`: the loops and their gains);
* **delayed loops** read past samples (no algebraic loop): the sample stored at every step is the loop signal under
  the actuator values of that instant and its rate is the exact derivative along the motion
  (:meth:`InputDependentSensors.sample_function`: the state, the controller states, the delayed signals read from the
  ring and the time move together; a delayed signal held before the start moves not, as the numpy driver's
  backward difference reads it), the samples held before the start the fixed point ``y = y(u(y))`` of the loops
  reading them (:meth:`InputDependentSensors.initial_samples`; refused, as the numpy driver, where it is not
  contracting: a neutral delay loop).
"""
from __future__ import annotations

from typing import Any, Sequence

import numpy as np

from .errors import ModelError

__all__ = ["InputDependentSensors", "affine_sensor_map"]

SINGULAR_LIMIT = 1e12     # the largest (1 + |D g W|) / sigma_min(I + D g W) of an algebraic loop at the start state


def affine_sensor_map(sensors: Any, actuators: Any, arguments: Sequence[Any]) -> Any:
    """``(q, v, p, t) -> (F_0, J)`` of sensors ``sensors`` (a casadi column on the symbols ``arguments = [q, v, p,
    t]`` and the actuator values ``actuators``) affine in the actuator values, ``F = F_0 + J w``: the value and the
    Jacobian at ``w = 0`` (exact for the cut forces of kinematic loop models: the applied loads are linear in ``w``,
    the tree's accelerations affine in the loads, the boundary compliance a function of the positions alone)."""
    import casadi as ca

    zero = ca.DM.zeros(actuators.numel())
    return ca.Function("cut_forces", list(arguments), [ca.substitute(sensors, actuators, zero),
                                                       ca.substitute(ca.jacobian(sensors, actuators), actuators, zero)])


class InputDependentSensors:
    """The input-dependent sensors of the loops of a :class:`~ctmm.compiled_loops.ClosedLoops` (module docstring).

    Parameters
    ----------
    symbols : object
        The plant on symbols with ``input_sensor_map(names, n_actuators)`` (a casadi Function ``(q, v, p, t) ->
        (F_0, J)``) and ``parameters`` (the plant's numbers, for ``p = None``).
    laws : sequence of LoopLaw
    names : sequence of str
        The input-dependent sensors the laws read.
    actuators : sequence of str
        The kernel's actuators (the order of ``w``).
    channels : list
        :attr:`ClosedLoops.channels` (loops outside the actuators: refused when they read such a sensor).

    Raises
    ------
    ModelError
        A loop reading such a sensor that acts through a channel (a beam station load), or a real-time one with
        saturation.
    """

    def __init__(self, symbols: Any, laws: Sequence[Any], names: Sequence[str], actuators: Sequence[str],
                 channels: Sequence[Any]) -> None:
        import casadi as ca

        self.symbols, self.names, self.laws = symbols, tuple(names), tuple(laws)
        weights = np.zeros((len(laws), len(self.names)))
        reading = []
        for k, law in enumerate(laws):
            for sensor, w in law.sensors:
                if sensor in self.names:
                    weights[k, self.names.index(sensor)] += float(w)
                    reading.append(k)
        self.weights = weights
        reading = sorted(set(reading))
        channelled = {k for k, _ in channels if isinstance(k, int)}
        for k in reading:
            if k in channelled:
                raise ModelError(f"loop {laws[k].name!r} reads {self._sensed(k)} and acts on a beam station load "
                                 "(outside the kernel's actuator inputs); use compiled=None")
            if laws[k].steps == 0 and laws[k].saturation is not None:
                raise ModelError(f"loop {laws[k].name!r}: a real-time loop on {self._sensed(k)} with saturation = "
                                 f"{laws[k].saturation!r} is a piecewise-affine algebraic loop, which generated "
                                 "kernels do not solve; drop the saturation or give the loop a delay >= dt")
        self.algebraic = tuple(k for k in reading if laws[k].steps == 0)
        self.map = symbols.input_sensor_map(self.names, len(actuators))
        A, b = ca.SX.sym("A", len(self.algebraic), len(self.algebraic)), ca.SX.sym("b", len(self.algebraic))
        self.solver = ca.Function("algebraic_loop", [A, b], [ca.solve(A, b)])

    def _sensed(self, k: int) -> list[str]:
        return [sensor for sensor, _ in self.laws[k].sensors if sensor in self.names]

    def refusal(self, *_: Any) -> Any:
        """What paths that read the loop sensors from the state alone raise."""
        raise ModelError(f"the loop sensors {list(self.names)} respond to the actuators at once (cut forces), and this "
                         "path reads its loop sensors from the state alone; use the generated RK4 of the loop driver "
                         "(method='rk4') or compiled=None")

    def law_terms(self, q: Any, v: Any, p: Any, t: Any) -> tuple[Any, Any]:
        """``(y_0, g)``: the laws' input-dependent signal parts ``y_0 + g w`` (one row per law; ``p`` the plant's
        numbers, ``None``: its own)."""
        import casadi as ca

        F0, J = self.map(q, v, self.symbols.parameters if p is None else p, t)
        S = ca.DM(self.weights)
        return ca.mtimes(S, F0), ca.mtimes(S, J)

    def matrix(self, gains: Sequence[Any], gain: Any, weights: Any) -> Any:
        """``I + D g W`` of the algebraic loops (``gains`` their feedthroughs ``D``, ``gain`` the laws' ``g``,
        ``weights`` the actuator weights ``W`` (actuators, laws))."""
        import casadi as ca

        rows = ca.vertcat(*[gain[k, :] for k in self.algebraic])
        columns = ca.horzcat(*[weights[:, k] for k in self.algebraic])
        return ca.DM.eye(len(self.algebraic)) + ca.mtimes(ca.diag(ca.vertcat(*gains)), ca.mtimes(rows, columns))

    def solve_algebraic(self, demands: Sequence[Any], gains: Sequence[Any], gain: Any, weights: Any) -> list:
        """The algebraic loops' outputs ``u`` from their demands at ``u = 0`` (``(I + D g W) u = demands``)."""
        import casadi as ca

        solved = self.solver(self.matrix(gains, gain, weights), ca.vertcat(*demands))
        return [solved[j] for j in range(len(self.algebraic))]

    def check_start(self, loops: Any, q: np.ndarray, v: np.ndarray, t: float = 0.0) -> None:
        """Refuse an algebraic loop singular at the start state ``(q, v)`` at time ``t`` [s].

        Raises
        ------
        ModelError
            ``I + D g W`` singular against the loop gain's size, ``(1 + |D g W|) / sigma_min > 1e12`` (or not
            finite): the loops, their gains ``D`` and the sensors' responses ``g W`` to the loops' own actuators.
        """
        import casadi as ca

        if not self.algebraic:
            return
        offset, gain = self.law_terms(ca.DM(q), ca.DM(v), None, t)
        numbers = loops.numbers(None)
        gains = [float(numbers[k].D) for k in self.algebraic]
        matrix = np.asarray(ca.DM(self.matrix(gains, ca.DM(gain), ca.DM(loops.weights))), dtype=float)
        response = np.asarray(ca.mtimes(ca.DM(gain)[list(self.algebraic), :],
                                        ca.DM(loops.weights)[:, list(self.algebraic)]))
        # against the loop gain's size: I + D g W is I plus the loop gain, which cancel in a singular loop
        smallest = np.linalg.svd(matrix, compute_uv=False)[-1] if np.all(np.isfinite(matrix)) else 0.0
        size = 1.0 + np.linalg.norm(matrix - np.eye(len(gains)), 2) if smallest > 0.0 else np.inf
        condition = size / smallest if smallest > 0.0 else np.inf
        if not condition <= SINGULAR_LIMIT:
            named = ", ".join(f"{self.laws[k].name!r} (gain {g!r}, on {self._sensed(k)})"
                              for k, g in zip(self.algebraic, gains))
            raise ModelError(f"real-time loops {named}: the algebraic loop u = -D (y(u) - r) is singular at the start "
                             f"state (I + D g W = {matrix.tolist()!r}, (1 + |D g W|) / sigma_min = {condition:.3g}; "
                             f"the sensors' response g W to the loops' own actuators = {response.tolist()!r}); change "
                             "the gain or give the loop a delay >= dt")

    def sample_function(self, loops: Any, n_inputs: int, n_parameters: int) -> Any:
        """``sample(x, x_dot, d, d_dot, u, p, t) -> (y, y_dot)`` of the delayed loops: their signals at ``x = [q,
        qdot, z]`` with the delayed signals ``d`` read and the held ``u`` (``n_inputs``), and the exact time
        derivative along ``x_dot``, ``d_dot`` and the time (``p``: ``n_parameters``, the whole column)."""
        import casadi as ca

        x, rate = ca.SX.sym("x", loops.base + loops.n_controller_states), ca.SX.sym("x_dot", loops.base +
                                                                                      loops.n_controller_states)
        count = len(loops.delayed)
        d, d_rate = ca.SX.sym("d", count), ca.SX.sym("d_dot", count)
        u, p, t = ca.SX.sym("u", n_inputs), ca.SX.sym("p", n_parameters), ca.SX.sym("t")
        y = loops.close(u, p, t, x, [d[j] for j in range(count)])[0][loops.delayed]
        along = ca.jtimes(y, ca.vertcat(x, d, t), ca.vertcat(rate, d_rate, 1.0))
        return ca.Function("delayed_samples", [x, rate, d, d_rate, u, p, t], [y, along])

    def initial_samples(self, loops: Any, q: np.ndarray, v: np.ndarray, t: float) -> np.ndarray:
        """The delayed loops' samples held before the start ``t`` [s] at ``(q, v)``: the fixed point ``y = y(u(y))``
        (the loops reading the held samples; affine: solved at once).

        Raises
        ------
        ModelError
            Not contracting (spectral radius of ``dy/dy_held`` 1 or more): a neutral delay loop, as the numpy driver.
        """
        import casadi as ca

        count = len(loops.delayed)
        d = ca.SX.sym("d", count)
        x = np.concatenate([q, v, np.zeros(loops.n_controller_states)])
        y = loops.close(ca.DM.zeros(len(loops.actuators)), None, t, ca.DM(x), [d[j] for j in range(count)])[0]
        y = y[loops.delayed]
        function = ca.Function("held", [d], [y, ca.jacobian(y, d)])
        start, J = (np.asarray(a, dtype=float) for a in function(np.zeros(count)))
        radius = float(np.max(np.abs(np.linalg.eigvals(J)), initial=0.0))
        if not radius < 1.0:
            raise ModelError(f"delayed loops on the cut forces {list(self.names)}: the force held before the start does "
                             f"not settle (the loops' gain through its response to their own actuators is {radius:.3g}, "
                             "1 or more: a neutral delay loop, unstable at high frequency)")
        value = np.linalg.solve(np.eye(count) - J, start.reshape(-1))
        for _ in range(100):        # a saturating loop among them: on to the fixed point from the affine one
            new = np.asarray(function(value)[0], dtype=float).reshape(-1)
            if np.max(np.abs(new - value), initial=0.0) <= 1e-15 * max(1.0, float(np.max(np.abs(new), initial=0.0))):
                return new
            value = new
        raise ModelError(f"delayed loops on the cut forces {list(self.names)}: the force held before the start does "
                         "not settle in 100 iterations from the affine fixed point (saturating loops)")
