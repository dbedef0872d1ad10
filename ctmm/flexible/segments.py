"""Finite-segment beams (seed 001 section 9.4): rigid segments joined by spring-damper hinges.

A uniform beam (``EI``, ``rhoA``, optional ``EA``) of length ``L`` is cut into ``N`` equal rigid
segments (``l = L/N``, ``m = rhoA l``, ``J_C = m l^2/12``, centre at ``l/2``).  Bending: the
elasticity of a segment is two torsional springs in series at its ends, each ``2 EI / l``
(seed 001 eq. (9.3)); two neighbouring half-springs in series give the interior hinge
stiffness ``EI / l`` (eq. (9.4)), while the root hinge carries only one half-spring,
**``2 EI / l``** -- the end-spring rule that makes the frequencies converge at second order
(FORMULAS 3.7: with ``EI/l`` at the root the error is O(1/N)).  Axial: springs ``EA / l``
(eq. (9.7)); ctmm's translational hinge springs are isotropic, so the same stiffness also acts
transversely (a shear stiffness ``EA`` instead of ``kappa G A`` -- negligible for slender beams,
documented in ``docs/flexible.md``), and the root spring is ``2 EA / l`` by the same rule.
Optional viscous dampers act in parallel (``bending_damping`` per unit ``EI``-spring ratio:
hinge damping = ``c_b / l`` interior, ``2 c_b / l`` at the root).
"""
from __future__ import annotations

from typing import Sequence

from .. import validation
from ..errors import ModelError
from ..planar.elements import ElasticHinge, RigidBody, SmoothHinge, SpringDamperHinge

ROOTS = ("clamped", "pinned")


def finite_segment_beam(name: str, *, length: float, bending_stiffness: float,
                        mass_per_length: float, n_segments: int,
                        axial_stiffness: float | None = None, bending_damping: float = 0.0,
                        root: str = "clamped", root_spring_factor: float = 2.0) -> list:
    """Elements ``[root hinge, seg1, hinge2, seg2, ..., segN]`` for :meth:`PlanarModel.chain`.

    Parameters
    ----------
    name : str
        Prefix: segments ``name1..nameN``, hinges ``name_k1..name_kN``.
    length, bending_stiffness, mass_per_length : float
        ``L`` [m], ``EI`` [N m^2], ``rhoA`` [kg/m], all > 0.
    n_segments : int
        ``N >= 1``.
    axial_stiffness : float, optional
        ``EA`` [N]: adds translational springs ``EA/l`` (root ``2 EA/l``) at every hinge.
    bending_damping : float
        ``c_b`` [N m^2 s]: rotary dampers ``c_b/l`` in parallel (root ``2 c_b/l``); 0 = none.
    root : {"clamped", "pinned"}
        Clamped: elastic root hinge ``root_spring_factor * EI / l``; pinned: smooth root hinge.
    root_spring_factor : float
        2 (default, second-order convergence); 1 reproduces the first-order variant.

    Examples
    --------
    >>> from ctmm.planar import Fixed, PlanarModel
    >>> parts = finite_segment_beam("s", length=1.0, bending_stiffness=2.0, mass_per_length=0.5,
    ...                             n_segments=4)
    >>> PlanarModel.chain("fs", [Fixed("g")] + parts).n_coordinates
    4
    """
    validation.name("element", name)
    L = validation.positive(f"{name}: length", length)
    EI = validation.positive(f"{name}: bending_stiffness", bending_stiffness)
    rhoA = validation.positive(f"{name}: mass_per_length", mass_per_length)
    if isinstance(n_segments, bool) or not isinstance(n_segments, int) or n_segments < 1:
        raise ModelError(f"{name}: n_segments must be an integer >= 1, got {n_segments!r}")
    if root not in ROOTS:
        raise ModelError(f"{name}: root must be one of {ROOTS}, got {root!r}")
    EA = None if axial_stiffness is None else validation.positive(f"{name}: axial_stiffness",
                                                                  axial_stiffness)
    cb = validation.nonnegative(f"{name}: bending_damping", bending_damping)
    factor = validation.positive(f"{name}: root_spring_factor", root_spring_factor)
    l = L / n_segments
    elements: list = []
    for k in range(1, n_segments + 1):
        scale = factor if k == 1 else 1.0
        hinge_name = f"{name}_k{k}"
        kt = {} if EA is None else {"translational_stiffness": scale * EA / l}
        if k == 1 and root == "pinned":
            hinge = SmoothHinge(hinge_name)
        elif cb > 0.0:
            hinge = SpringDamperHinge(hinge_name, stiffness=scale * EI / l,
                                      damping=scale * cb / l, **kt)
        else:
            hinge = ElasticHinge(hinge_name, stiffness=scale * EI / l, **kt)
        elements.append(hinge)
        elements.append(RigidBody.uniform_link(f"{name}{k}", mass=rhoA * l, length=l))
    return elements


def segment_names(name: str, n_segments: int) -> Sequence[str]:
    """Body names of a finite-segment beam (``name1..nameN``)."""
    return [f"{name}{k}" for k in range(1, n_segments + 1)]


__all__ = ["finite_segment_beam", "segment_names"]
