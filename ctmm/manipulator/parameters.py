"""Physical parameters of the controlled flexible manipulator (seed 001 §9.6.1, Figs. 9.42-9.43).

A rigid hub (rotary inertia ``J_h`` about a fixed vertical pivot, radius ``r_h``) turned by a
motor carries a uniform aluminium arm (Euler-Bernoulli, clamped to the hub at ``r_h``) with
segmented PZT patches bonded on one face.  The plane of motion is horizontal (no gravity).

Moment per volt of a patch (``docs/manipulator.md`` §2)
------------------------------------------------------
Assumptions of the seed (§9.6.1): bonding layer neglected, patch rigidly bonded, patch mass
and stiffness neglected (uniform arm), voltage uniform over the patch, polarisation along the
transverse (thickness) direction.  A voltage ``V`` along the poling axis gives the patch the
free strain ``Lambda = d31 V / t_a``; blocked by the (much stiffer, rigidly bonded) arm it
pushes with the force ``E_p b_p t_a Lambda`` on the arm surface at the lever arm
``(t_b + t_a)/2`` from the neutral axis.  The patch therefore acts on the arm as a pair of
concentrated moments at its ends (pin-force / Bailey-Hubbard model):

    M_p = c_a V,      c_a = -E_p d31 b_p (t_b + t_a) / 2      [N m / V]

``M_p > 0`` bends the arm towards positive curvature ``u'' > 0`` (patch on the face
``z = +t_b/2`` with the transverse axis ``z`` along ``+u``; axial strain ``-z u''``); with
``d31 < 0`` a positive voltage contracts the patch and ``c_a > 0``.  The generalised force of
the pair on a deformation mode ``phi_i`` is ``c_a V (phi_i'(x2) - phi_i'(x1))``.

Symbols: ``E_p`` patch Young's modulus [Pa], ``d31`` piezoelectric strain constant [m/V],
``b_p`` patch width [m] (default: arm width), ``t_a`` patch thickness, ``t_b`` arm thickness [m].
"""
from __future__ import annotations

import math
from dataclasses import dataclass, field

import numpy as np

from .. import validation
from ..errors import ModelError

__all__ = ["Arm", "Hub", "PiezoMaterial", "PZT_5A", "PZT_5H", "PZTPatch", "Manipulator",
           "moment_per_volt", "CycloidalMove", "seed_manipulator", "SEED_PATCHES",
           "SEED_KP", "SEED_KD", "SEED_PZT_GAIN", "SEED_MOVE"]


@dataclass(frozen=True)
class Arm:
    """Uniform rectangular Euler-Bernoulli arm.

    Parameters
    ----------
    length : float
        ``L`` [m] from the hub clamp to the free tip, > 0.
    width : float
        ``b`` [m], > 0.
    thickness : float
        ``t_b`` [m] (in the plane of motion), > 0.
    youngs_modulus : float
        ``E`` [Pa] (aluminium: 70 GPa).
    density : float
        ``rho`` [kg/m^3] (aluminium: 2700).
    kelvin_voigt_time : float
        Strain-rate damping time ``tau_d`` [s] (``EI (1 + tau_d s)``; mode ``k`` gets the damping
        ratio ``tau_d omega_k / 2``), >= 0.
    """

    length: float = 1.0
    width: float = 0.04
    thickness: float = 0.003
    youngs_modulus: float = 70e9
    density: float = 2700.0
    kelvin_voigt_time: float = 0.0

    def __post_init__(self) -> None:
        for attribute in ("length", "width", "thickness", "youngs_modulus", "density"):
            object.__setattr__(self, attribute,
                               validation.positive(f"arm: {attribute}", getattr(self, attribute)))
        object.__setattr__(self, "kelvin_voigt_time",
                           validation.nonnegative("arm: kelvin_voigt_time", self.kelvin_voigt_time))

    @property
    def area(self) -> float:
        """Cross-section ``A = b t_b`` [m^2]."""
        return self.width * self.thickness

    @property
    def second_moment(self) -> float:
        """``I = b t_b^3 / 12`` [m^4] (bending in the plane of motion)."""
        return self.width * self.thickness ** 3 / 12.0

    @property
    def bending_stiffness(self) -> float:
        """``EI`` [N m^2]."""
        return self.youngs_modulus * self.second_moment

    @property
    def mass_per_length(self) -> float:
        """``rho A`` [kg/m]."""
        return self.density * self.area

    @property
    def mass(self) -> float:
        """``rho A L`` [kg]."""
        return self.mass_per_length * self.length

    def clamped_free_frequency(self, mode: int = 1) -> float:
        """Clamped-free natural frequency ``beta_k^2 sqrt(EI / (rho A L^4))`` [rad/s] (k = 1..4)."""
        betas = (1.8751040687, 4.6940911330, 7.8547574382, 10.9955407349)
        if mode not in (1, 2, 3, 4):
            raise ModelError(f"arm: mode must be 1..4, got {mode!r}")
        return betas[mode - 1] ** 2 * math.sqrt(self.bending_stiffness
                                                / (self.mass_per_length * self.length ** 4))


@dataclass(frozen=True)
class Hub:
    """Rigid hub turning about a fixed pivot at its centre.

    Parameters
    ----------
    inertia : float
        ``J_h`` [kg m^2] about the pivot, > 0.
    radius : float
        ``r_h`` [m]: distance from the pivot to the arm clamp, >= 0.
    """

    inertia: float = 2.0
    radius: float = 0.05

    def __post_init__(self) -> None:
        object.__setattr__(self, "inertia", validation.positive("hub: inertia", self.inertia))
        object.__setattr__(self, "radius", validation.nonnegative("hub: radius", self.radius))


@dataclass(frozen=True)
class PiezoMaterial:
    """Piezoceramic data: ``d31`` [m/V] (negative for PZT) and Young's modulus ``E_p`` [Pa]."""

    name: str
    d31: float
    youngs_modulus: float

    def __post_init__(self) -> None:
        d31 = validation.finite(f"{self.name}: d31", self.d31)
        if d31 == 0.0:
            raise ModelError(f"{self.name}: d31 must be non-zero [m/V], got {self.d31!r}")
        object.__setattr__(self, "d31", d31)
        object.__setattr__(self, "youngs_modulus",
                           validation.positive(f"{self.name}: youngs_modulus", self.youngs_modulus))


# Typical manufacturer data sheets (e.g. Morgan/CTS, Piezo Systems): d31 and the short-circuit
# compliance s11^E = 1/E_p.  PZT-5A: d31 = -171e-12 m/V, s11^E = 16.4e-12 m^2/N (61 GPa);
# PZT-5H: d31 = -274e-12 m/V, s11^E = 16.5e-12 m^2/N (60.6 GPa).
PZT_5A = PiezoMaterial("PZT-5A", d31=-1.71e-10, youngs_modulus=61e9)
PZT_5H = PiezoMaterial("PZT-5H", d31=-2.74e-10, youngs_modulus=60.6e9)


def moment_per_volt(material: PiezoMaterial, *, patch_thickness: float, patch_width: float,
                    arm_thickness: float) -> float:
    """``c_a = -E_p d31 b_p (t_b + t_a) / 2`` [N m / V] (module docstring; seed §9.6.1 assumptions).

    Examples
    --------
    >>> round(moment_per_volt(PZT_5H, patch_thickness=5e-4, patch_width=0.04, arm_thickness=3e-3), 8)
    0.00116231
    """
    t_a = validation.positive("patch_thickness", patch_thickness)
    b_p = validation.positive("patch_width", patch_width)
    t_b = validation.positive("arm_thickness", arm_thickness)
    return -material.youngs_modulus * material.d31 * b_p * (t_b + t_a) / 2.0


@dataclass(frozen=True)
class PZTPatch:
    """A segmented PZT actuator bonded between ``start`` and ``end`` (arm coordinate from the clamp).

    Parameters
    ----------
    name : str
        Patch name (signals ``"<name>.voltage"`` ...).
    start, end : float
        Patch ends ``x1 < x2`` [m] measured from the clamp.
    thickness : float
        ``t_a`` [m], > 0.
    material : PiezoMaterial
        Piezoceramic (default PZT-5H).
    width : float or None
        ``b_p`` [m]; ``None``: the arm width.
    """

    name: str
    start: float
    end: float
    thickness: float = 5e-4
    material: PiezoMaterial = PZT_5H
    width: float | None = None

    def __post_init__(self) -> None:
        validation.name("PZT patch", self.name)
        object.__setattr__(self, "start", validation.finite(f"{self.name}: start", self.start))
        object.__setattr__(self, "end", validation.finite(f"{self.name}: end", self.end))
        object.__setattr__(self, "thickness", validation.positive(f"{self.name}: thickness", self.thickness))
        if not isinstance(self.material, PiezoMaterial):
            raise ModelError(f"{self.name}: material must be a PiezoMaterial, got {self.material!r}")
        if self.width is not None:
            object.__setattr__(self, "width", validation.positive(f"{self.name}: width", self.width))
        if not self.end > self.start:
            raise ModelError(f"{self.name}: end ({self.end!r} m) must be > start ({self.start!r} m)")

    def moment_per_volt(self, arm: Arm) -> float:
        """``c_a`` [N m/V] of this patch on ``arm``."""
        return moment_per_volt(self.material, patch_thickness=self.thickness,
                               patch_width=arm.width if self.width is None else self.width,
                               arm_thickness=arm.thickness)


@dataclass(frozen=True)
class Manipulator:
    """Hub + arm + PZT patches, validated together (every problem reported at once).

    Parameters
    ----------
    arm : Arm
    hub : Hub
    patches : sequence of PZTPatch
        Non-overlapping patches inside ``[0, L]``, any order (stored sorted by ``start``).
    voltage_limit : float
        Admissible ``|V|`` [V] of every patch (e.g. 200 V), > 0.
    """

    arm: Arm = field(default_factory=Arm)
    hub: Hub = field(default_factory=Hub)
    patches: tuple[PZTPatch, ...] = ()
    voltage_limit: float = 200.0

    def __post_init__(self) -> None:
        problems = []
        if not isinstance(self.arm, Arm):
            problems.append(f"arm must be an Arm, got {self.arm!r}")
        if not isinstance(self.hub, Hub):
            problems.append(f"hub must be a Hub, got {self.hub!r}")
        if not isinstance(self.patches, (list, tuple)):
            raise ModelError(f"patches must be a list or tuple of PZTPatch, got {self.patches!r}")
        patches = tuple(self.patches)
        for i, p in enumerate(patches):
            if not isinstance(p, PZTPatch):
                problems.append(f"patches[{i}] must be a PZTPatch, got {p!r}")
        if problems:
            raise ModelError("manipulator is invalid:\n  - " + "\n  - ".join(problems))
        patches = tuple(sorted(patches, key=lambda p: p.start))
        names = [p.name for p in patches]
        if len(set(names)) != len(names):
            problems.append(f"patch names must be unique, got {names}")
        L = self.arm.length
        for p in patches:
            if p.start < 0.0 or p.end > L:
                problems.append(f"patch {p.name!r} [{p.start:g}, {p.end:g}] m lies outside the arm [0, {L:g}] m")
            if p.width is not None and p.width > self.arm.width * (1 + 1e-12):
                problems.append(f"patch {p.name!r} is wider ({p.width:g} m) than the arm ({self.arm.width:g} m)")
        for a, b in zip(patches, patches[1:]):
            if b.start < a.end:
                problems.append(f"patches {a.name!r} [{a.start:g}, {a.end:g}] and {b.name!r} "
                                f"[{b.start:g}, {b.end:g}] overlap")
        try:
            limit = validation.positive("voltage_limit", self.voltage_limit)
        except ModelError as exc:
            problems.append(str(exc))
            limit = self.voltage_limit
        if problems:
            raise ModelError("manipulator is invalid:\n  - " + "\n  - ".join(problems))
        object.__setattr__(self, "patches", patches)
        object.__setattr__(self, "voltage_limit", limit)

    @property
    def n_patches(self) -> int:
        return len(self.patches)

    @property
    def patch_names(self) -> tuple[str, ...]:
        return tuple(p.name for p in self.patches)

    @property
    def patch_ends(self) -> np.ndarray:
        """``(P, 2)`` array of ``[x1, x2]`` [m] from the clamp."""
        return np.array([[p.start, p.end] for p in self.patches], dtype=float).reshape(-1, 2)

    @property
    def moments_per_volt(self) -> np.ndarray:
        """``c_a`` of every patch [N m/V]."""
        return np.array([p.moment_per_volt(self.arm) for p in self.patches], dtype=float)

    @property
    def rigid_inertia(self) -> float:
        """Hub + undeformed arm inertia about the pivot ``J_h + rho A ((r_h + L)^3 - r_h^3)/3`` [kg m^2]."""
        r, L = self.hub.radius, self.arm.length
        return self.hub.inertia + self.arm.mass_per_length * ((r + L) ** 3 - r ** 3) / 3.0


@dataclass(frozen=True)
class CycloidalMove:
    """Rest-to-rest cycloidal hub reference ``theta_d(t)`` (smooth velocity, bounded jerk-free acceleration).

    ``theta_d = a + (b - a) [s - sin(2 pi s)/(2 pi)]``, ``s = (t - t0)/T`` clipped to ``[0, 1]``.

    Parameters
    ----------
    final_angle : float
        ``b`` [rad].
    duration : float
        ``T`` [s], > 0.
    start_angle : float
        ``a`` [rad].
    start_time : float
        ``t0`` [s].
    """

    final_angle: float
    duration: float
    start_angle: float = 0.0
    start_time: float = 0.0

    def __post_init__(self) -> None:
        object.__setattr__(self, "final_angle", validation.finite("final_angle", self.final_angle))
        object.__setattr__(self, "duration", validation.positive("duration", self.duration))
        object.__setattr__(self, "start_angle", validation.finite("start_angle", self.start_angle))
        object.__setattr__(self, "start_time", validation.finite("start_time", self.start_time))

    def _s(self, t):
        return np.clip((np.asarray(t, dtype=float) - self.start_time) / self.duration, 0.0, 1.0)

    def _scalar_s(self, t: float) -> float:
        return min(max((t - self.start_time) / self.duration, 0.0), 1.0)

    def angle(self, t):
        """``theta_d(t)`` [rad] (float for a scalar ``t``, array otherwise)."""
        if isinstance(t, (float, int)):
            s = self._scalar_s(t)
            return self.start_angle + (self.final_angle - self.start_angle) * (s - math.sin(2 * math.pi * s) / (2 * math.pi))
        s = self._s(t)
        return self.start_angle + (self.final_angle - self.start_angle) * (s - np.sin(2 * np.pi * s) / (2 * np.pi))

    __call__ = angle

    def rate(self, t):
        """``theta_d'(t)`` [rad/s]."""
        if isinstance(t, (float, int)):
            s = self._scalar_s(t)
            return (self.final_angle - self.start_angle) / self.duration * (1.0 - math.cos(2 * math.pi * s))
        s = self._s(t)
        return (self.final_angle - self.start_angle) / self.duration * (1.0 - np.cos(2 * np.pi * s))

    def acceleration(self, t):
        """``theta_d''(t)`` [rad/s^2] (continuous; zero outside the move)."""
        if isinstance(t, (float, int)):
            s = self._scalar_s(t)
            return (self.final_angle - self.start_angle) * 2 * math.pi / self.duration ** 2 * math.sin(2 * math.pi * s)
        s = self._s(t)
        return (self.final_angle - self.start_angle) * 2 * np.pi / self.duration ** 2 * np.sin(2 * np.pi * s)

    @property
    def breakpoints(self) -> tuple[float, float]:
        """Start and end of the move [s] (the jerk jumps there)."""
        return (self.start_time, self.start_time + self.duration)


# Seed scene (parameters are our choice; the book's values were not recovered, FORMULAS §5.3).
SEED_PATCHES = (("pzt1", 0.02, 0.12), ("pzt2", 0.30, 0.40), ("pzt3", 0.55, 0.65))


def seed_manipulator(*, n_patches: int = 3, kelvin_voigt_time: float = 2e-4,
                     hub_inertia: float = 2.0) -> Manipulator:
    """The manipulator of the seed scene (``docs/manipulator.md`` §1): 1 m x 40 mm x 3 mm aluminium
    arm (Kelvin-Voigt time 0.2 ms: 0.16 % damping in the first clamped-free mode), hub
    2 kg m^2 (motor and gearbox reflected inertia) with 50 mm radius, ``n_patches`` (0..3)
    PZT-5H patches 0.5 mm x 100 mm at 20-120, 300-400 and 550-650 mm, limit 200 V.
    """
    if isinstance(n_patches, bool) or n_patches not in (0, 1, 2, 3):
        raise ModelError(f"n_patches must be 0..3, got {n_patches!r}")
    arm = Arm(kelvin_voigt_time=kelvin_voigt_time)
    patches = tuple(PZTPatch(name, a, b) for name, a, b in SEED_PATCHES[:n_patches])
    return Manipulator(arm=arm, hub=Hub(inertia=hub_inertia, radius=0.05), patches=patches,
                       voltage_limit=200.0)


# Seed scene controls (our choice, docs/manipulator.md §1): PD rigid-mode pole 9.8 rad/s with
# zeta 0.72 on the rigid inertia 2.125 kg m^2 (below the first flexible mode, 15.7 rad/s), per-patch
# slope-rate gain 1000 V s/rad (eq. (9.65) with Ka_i = 1000), 60 deg cycloidal slew in 1 s.
SEED_KP = 200.0
SEED_KD = 30.0
SEED_PZT_GAIN = 1000.0
SEED_MOVE = CycloidalMove(final_angle=math.pi / 3, duration=1.0)
