"""Named state-vector layouts and the package-wide sign convention.

Sign convention (one for the whole package)
-------------------------------------------
A state vector lives at a *connection point* between an inboard element and an outboard
element.  Its kinematic half holds displacements (or accelerations in the acceleration-based
layouts); its force half holds the force / moment **exerted by the inboard part on the
outboard part** at that point, in the global (or layout) axes.  For an axial chain this is
``f = -q`` with ``q`` the tension in the connection: a stretched spring pulls the mass
outboard of it back, so the force on that mass is negative.  Displacement component ``i`` and
force component ``i`` are work-conjugate.

Transfer equation: ``z_out = U z_in + u`` where ``u`` collects known terms (external loads,
integrator history, free lengths): the affine "1" component of the books is kept as a separate
vector rather than as a component, so layouts hold only physical quantities plus *extras*
(additional unknowns such as a sensed value carried along for non-collocated feedback).
"""
from __future__ import annotations

from dataclasses import dataclass, field

from .errors import ModelError, unknown_name


@dataclass(frozen=True)
class StateLayout:
    """Ordered, named components of a state vector.

    Parameters
    ----------
    name : str
        Layout name, e.g. ``"axial"``.
    displacements : tuple of str
        Kinematic components (displacements, rotations or their accelerations).
    forces : tuple of str
        Work-conjugate internal forces / moments (same length as ``displacements``),
        exerted by the inboard part on the outboard part.
    extras : tuple of str, optional
        Further components carried along the chain (e.g. sensed values ``"xs"``).
    """

    name: str
    displacements: tuple[str, ...]
    forces: tuple[str, ...]
    extras: tuple[str, ...] = ()
    _index: dict = field(init=False, repr=False, compare=False, hash=False)

    def __post_init__(self) -> None:
        if len(self.displacements) != len(self.forces):
            raise ModelError(
                f"layout {self.name!r}: displacements {self.displacements} and forces {self.forces} "
                "must have the same length")
        names = self.components
        if len(set(names)) != len(names):
            raise ModelError(f"layout {self.name!r}: component names must be unique, got {names}")
        object.__setattr__(self, "_index", {c: i for i, c in enumerate(names)})

    @property
    def components(self) -> tuple[str, ...]:
        """All component names in state-vector order."""
        return self.displacements + self.forces + self.extras

    @property
    def size(self) -> int:
        """Number of components ``n``."""
        return len(self.components)

    @property
    def half(self) -> int:
        """Number of displacement (= force) components ``d``."""
        return len(self.displacements)

    def index(self, component: str) -> int:
        """Position of ``component`` in the state vector."""
        try:
            return self._index[component]
        except KeyError:
            raise unknown_name(f"component of layout {self.name!r}", component, self.components) from None

    def with_extras(self, *extras: str) -> "StateLayout":
        """Return this layout extended by extra components (e.g. sensed values)."""
        return StateLayout(self.name + "+" + "+".join(extras), self.displacements, self.forces,
                           self.extras + tuple(extras))


AXIAL = StateLayout("axial", ("x",), ("f",))
"""1-D chain: displacement ``x`` [m], force ``f`` [N] by the inboard on the outboard part."""

TORSION = StateLayout("torsion", ("phi",), ("torque",))
"""Torsional chain: rotation ``phi`` [rad], torque [N m] by the inboard on the outboard part."""

BENDING = StateLayout("bending", ("w", "theta"), ("shear", "moment"))
"""Planar Euler-Bernoulli bending: deflection ``w`` [m], slope ``theta`` [rad], transverse
force ``shear`` [N] and bending moment ``moment`` [N m] exerted by the inboard on the outboard part."""

PLANAR = StateLayout("planar", ("x", "y", "theta"), ("fx", "fy", "tau"))
"""Linear planar multibody (small motion about a reference): displacements [m], rotation [rad],
forces [N] and moment [N m] by the inboard on the outboard body."""

PLANAR_ACCELERATION = StateLayout("planar_acceleration", ("ax", "ay", "alpha"), ("fx", "fy", "tau"))
"""Acceleration-based planar multibody: accelerations [m/s^2], angular acceleration [rad/s^2],
forces [N] and moment [N m] by the inboard on the outboard body."""
