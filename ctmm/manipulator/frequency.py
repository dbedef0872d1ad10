"""Linearised controlled manipulator in the frequency domain, built from ctmm elements.

About a target pose at rest (``theta_dot = 0``, undeformed arm; horizontal plane, no
gravity) the hub-arm system is a beam in inertial axes (layout :data:`~ctmm.layouts.BENDING`,
``w = (r + x) theta + u``) pinned at the pivot:

``BeamPinned("pivot")`` (``w = 0``, ``moment = 0``) -> :class:`RigidHub` ``"hub"`` (inertia
``J_h``, radius ``r``, motor torque input) -> exact :class:`~ctmm.elements.beams.BeamField`
pieces ``"arm_1" ...`` between the patch stations -> a
:class:`~ctmm.elements.beams.BeamPointLoad` at every patch end (``"<patch>_x1"``,
``"<patch>_x2"``) -> ``BeamFree("tip")``.

Loops (:class:`~ctmm.control.Feedback`, closed exactly by the extended-state Riccati sweep):

* ``"pd"``: sensor ``hub.theta``, controller ``C(s) = kp + kd s`` (python-control, improper),
  actuator ``hub.torque``, reference input ``pd.reference`` = desired angle ``theta_d``.
* one loop per patch (named like the patch): sensor ``sum_j G_kj (theta_dot(x2_j) -
  theta_dot(x1_j))`` (the slope rates of the inertial beam; the rigid rotation cancels in the
  difference), gain 1, actuator the moment pair ``[(<patch>_x1.moment, -c_a), (<patch>_x2.moment,
  +c_a)]`` so that the loop force ``<patch>.u`` is the voltage ``V`` [V].

Exact delays ``e^{-s tau}`` enter through the loops.  The tip deflection in the hub frame is
``u(L) = tip.w - (r + L) hub.theta``.
"""
from __future__ import annotations

from dataclasses import dataclass
from typing import Any, Mapping

import numpy as np

from .. import validation
from ..control import ControlledChain, Feedback
from ..control.analysis import Margins, loop_transfer_function, margins
from ..elements.base import Element
from ..elements.beams import BeamField, BeamFree, BeamPinned, BeamPointLoad, laplace_array
from ..elements.bending_bodies import RigidSegment
from ..errors import ModelError, unknown_name
from ..frequency import frequency_response
from ..results import FrequencyResponse
from ..system import Chain
from .laws import HubPD, PZTFeedback, check_pzt
from .parameters import Manipulator

#: Most beam fields :func:`plant_chain` builds from ``max_piece`` (a larger count is a unit mistake).
MAX_PIECES = 100_000

__all__ = ["RigidHub", "plant_chain", "LinearManipulator"]


class RigidHub(RigidSegment):
    """Rigid hub pivoted at its centre, arm clamped at radius ``r`` (bending layout, linear).

    The hub receives ``(shear_in, moment_in)`` at the pivot, ``-(shear_out, moment_out)`` at the
    clamp and the motor torque ``tau``.  Kinematics ``w_out = w_in + r theta``, ``theta_out =
    theta_in``; Newton (centre at the pivot) ``m s^2 w_in = shear_in - shear_out``; Euler about
    the pivot ``J s^2 theta = moment_in - moment_out - r shear_out + tau``::

        U = [[1,         r,       0,  0],
             [0,         1,       0,  0],
             [-m s^2,    0,       1,  0],
             [r m s^2,  -J s^2,  -r,  1]],     u = [0, 0, 0, tau]

    (for ``r -> 0`` the point inertia :class:`~ctmm.elements.beams.BeamPointMass`; the rigid-bar
    part equals a beam field at ``s = 0``: ``moment' = -shear``).  It is the
    :class:`~ctmm.elements.bending_bodies.RigidSegment` of length ``r`` with its centre of mass at
    the pivot (the transfer matrix is that one), the motor torque as its input.

    Parameters
    ----------
    name : str
    inertia : float
        ``J`` [kg m^2] about the pivot, > 0.
    radius : float
        ``r`` [m], >= 0.
    mass : float
        ``m`` [kg] (enters only if the pivot moves), >= 0.
    """

    inputs = ("torque",)

    def __init__(self, name: str, inertia: float, radius: float = 0.0, *, mass: float = 0.0) -> None:
        super().__init__(name, length=validation.nonnegative(f"{name}: radius", radius),
                         mass=mass, inertia=validation.positive(f"{name}: inertia", inertia), center=0.0)
        self.radius = self.length

    def parameters(self) -> dict[str, Any]:
        return {"inertia": self.inertia, "radius": self.radius, "mass": self.mass}

    def load_vector(self, s: Any, amplitudes: Mapping[str, Any]) -> np.ndarray:
        self.check_inputs(amplitudes)
        u = np.zeros(laplace_array(s).shape + (4,), dtype=complex)
        u[..., 3] = amplitudes.get("torque", 0.0)
        return u


def _stations(manipulator: Manipulator) -> list[tuple[float, str]]:
    out = []
    for p in manipulator.patches:
        out += [(p.start, f"{p.name}_x1"), (p.end, f"{p.name}_x2")]
    return sorted(out, key=lambda item: item[0])


def plant_chain(manipulator: Manipulator, *, name: str = "manipulator", max_piece: float | None = None) -> Chain:
    """The uncontrolled linear chain (module docstring); ``max_piece`` [m] splits long fields."""
    if not isinstance(manipulator, Manipulator):
        raise ModelError(f"manipulator must be a Manipulator, got {manipulator!r}")
    arm, hub = manipulator.arm, manipulator.hub
    if max_piece is not None:
        max_piece = validation.positive("max_piece", max_piece)
        if arm.length / max_piece > MAX_PIECES:
            raise ModelError(f"max_piece={max_piece!r} m splits the {arm.length:g} m arm into about "
                             f"{arm.length / max_piece:.3g} fields; at most {MAX_PIECES:.0e} are allowed")
    elements: list[Element] = [BeamPinned("pivot"), RigidHub("hub", hub.inertia, hub.radius)]
    x = 0.0
    k = 0

    def field(x_from: float, x_to: float) -> None:
        nonlocal k
        length = x_to - x_from
        if length <= 1e-12 * arm.length:
            return
        pieces = 1 if max_piece is None else max(1, int(np.ceil(length / max_piece - 1e-9)))
        for _ in range(pieces):
            k += 1
            elements.append(BeamField(f"arm_{k}", length / pieces, arm.bending_stiffness, arm.mass_per_length,
                                      kelvin_voigt_time=arm.kelvin_voigt_time))

    for position, station in _stations(manipulator):
        field(x, position)
        elements.append(BeamPointLoad(station))
        x = position
    field(x, arm.length)
    elements.append(BeamFree("tip"))
    return Chain(name, elements)


@dataclass(frozen=True)
class LinearManipulator:
    """The linearised controlled manipulator (module docstring).

    Parameters
    ----------
    manipulator : Manipulator
    pd : HubPD
    pzt : PZTFeedback or None
        ``None``: patches present but not driven (``V = 0``).
    max_piece : float or None
        Longest beam field [m] (``None``: one field between stations; the exact field is
        accurate up to ``beta ~ 20`` per piece, i.e. far beyond the frequencies of interest).

    Examples
    --------
    >>> import numpy as np
    >>> from ctmm.manipulator import seed_manipulator, HubPD, PZTFeedback, LinearManipulator
    >>> model = LinearManipulator(seed_manipulator(), HubPD(kp=50.0, kd=15.0),
    ...                           PZTFeedback.per_patch([1000.0, 1000.0, 1000.0]))
    >>> r = model.response([1.0, 20.0])
    >>> r["tip"].shape, bool(abs(r["theta"][0]) > 0.9)
    ((2,), True)
    """

    manipulator: Manipulator
    pd: HubPD
    pzt: PZTFeedback | None = None
    max_piece: float | None = None

    def __post_init__(self) -> None:
        if not isinstance(self.pd, HubPD):
            raise ModelError(f"pd must be a HubPD, got {self.pd!r}")
        check_pzt(self.pzt, self.manipulator.n_patches)
        if self.pzt is not None and self.manipulator.n_patches == 0:
            raise ModelError("PZT feedback given but the manipulator has no patches")
        object.__setattr__(self, "_plant", plant_chain(self.manipulator, max_piece=self.max_piece))
        object.__setattr__(self, "_system", ControlledChain(self._plant, self._loops()))

    # ------------------------------------------------------------------------ structure
    def _loops(self) -> list[Feedback]:
        loops = [Feedback("pd", "hub.theta", "hub.torque", gain=self.pd.controller(), delay=self.pd.delay)]
        if self.pzt is None:
            return loops
        patches = self.manipulator.patches
        ca = self.manipulator.moments_per_volt
        G = self.pzt.gains
        for k, patch in enumerate(patches):
            sensor = []
            for j, other in enumerate(patches):
                if G[k, j] != 0.0:
                    sensor += [(f"{other.name}_x1.theta_dot", -G[k, j]), (f"{other.name}_x2.theta_dot", G[k, j])]
            if not sensor:  # an all-zero row: keep the loop (voltage signal) with zero weight
                sensor = [(f"{patch.name}_x2.theta_dot", 0.0)]
            loops.append(Feedback(patch.name, sensor,
                                  [(f"{patch.name}_x1.moment", -ca[k]), (f"{patch.name}_x2.moment", ca[k])],
                                  gain=1.0, delay=self.pzt.delay))
        return loops

    @property
    def plant(self) -> Chain:
        """The uncontrolled chain."""
        return self._plant

    @property
    def system(self) -> ControlledChain:
        """The chain closed by the PD and PZT loops."""
        return self._system

    @property
    def loop_names(self) -> tuple[str, ...]:
        return tuple(lp.name for lp in self._system.loops)

    def without_pzt(self) -> "LinearManipulator":
        """The same manipulator with the PZT loops open (PD only)."""
        return LinearManipulator(self.manipulator, self.pd, None, self.max_piece)

    # ------------------------------------------------------------------------ responses
    def _input(self, name: str) -> list[tuple[str, float]]:
        if name in ("theta_d", "pd.reference"):
            return [("pd.reference", 1.0)]
        if name in ("torque", "hub.torque"):
            return [("hub.torque", 1.0)]
        for k, patch in enumerate(self.manipulator.patches):
            if name == f"{patch.name}.voltage":
                ca = self.manipulator.moments_per_volt[k]
                return [(f"{patch.name}_x1.moment", -ca), (f"{patch.name}_x2.moment", ca)]
        known = ["theta_d", "torque"] + [f"{p.name}.voltage" for p in self.manipulator.patches]
        raise unknown_name("manipulator input", name, known)

    def response(self, omega: Any, *, input: str = "theta_d") -> dict[str, np.ndarray]:  # noqa: A002
        """Closed-loop responses per unit ``input`` over ``omega`` [rad/s].

        Parameters
        ----------
        input : str
            ``"theta_d"`` (desired hub angle [rad]), ``"torque"`` (extra motor torque [N m]) or
            ``"<patch>.voltage"`` (voltage added to a patch [V]).

        Returns
        -------
        dict
            ``"theta"`` [rad], ``"tip"`` (hub-frame tip deflection ``u(L)`` [m]), ``"tip_w"``
            (inertial ``w(L)``), ``"voltages"`` ``(P, n)`` [V] (total patch voltages: loop outputs
            ``<patch>.u`` plus an injected voltage),
            ``"torque"`` (PD output ``pd.u`` [N m]), ``"slopes"`` ``(P, n)`` (``theta(x2) -
            theta(x1)``) -- each per unit input.
        """
        w = np.atleast_1d(np.asarray(omega, dtype=float))
        terms = self._input(input)
        patches = self.manipulator.patches
        outputs = ["hub.theta", "tip.w", "pd.u"]
        outputs += [f"{p.name}_x{i}.theta" for p in patches for i in (1, 2)]
        if self.pzt is not None:
            outputs += [f"{p.name}.u" for p in patches]
        inputs = list(dict.fromkeys(n for n, _ in terms))
        frf = frequency_response(self._system, w, input=inputs, output=outputs)

        def value(signal: str) -> np.ndarray:
            return sum(weight * frf(signal, name) for name, weight in terms)

        theta = value("hub.theta")
        tip_w = value("tip.w")
        reach = self.manipulator.hub.radius + self.manipulator.arm.length
        slopes = np.array([value(f"{p.name}_x2.theta") - value(f"{p.name}_x1.theta") for p in patches]
                          ).reshape(len(patches), w.size)
        if self.pzt is not None:
            volts = np.array([value(f"{p.name}.u") for p in patches]).reshape(len(patches), w.size)
        else:
            volts = np.zeros((len(patches), w.size), dtype=complex)
        for k, patch in enumerate(patches):            # an injected voltage adds to the loop's output
            if input == f"{patch.name}.voltage":
                volts[k] += 1.0
        return {"omega": w, "theta": theta, "tip_w": tip_w, "tip": tip_w - reach * theta,
                "voltages": volts, "torque": value("pd.u"), "slopes": slopes}

    def loop_transfer(self, loop: str, omega: Any) -> FrequencyResponse:
        """``L(i omega)`` of loop ``"pd"`` or ``"<patch>"`` broken at its actuator (others closed)."""
        return loop_transfer_function(self._system, loop, omega)

    def margins(self, loop: str, omega: Any) -> Margins:
        """Gain/phase/delay margins of a loop (:func:`ctmm.control.analysis.margins`)."""
        return margins(self._system, loop, omega)
