"""The inerter: a two-terminal element whose force is proportional to the relative acceleration.

An ideal inerter of inertance ``b`` [kg] transmits ``f = -b (a_out - a_in)`` (Smith 2002, "Synthesis
of mechanical networks: the inerter", IEEE TAC 47(10); the mechanical dual of a capacitor).  Here
it may sit in parallel with a spring ``k`` (free length ``l``) and a viscous damper ``c``, and an
actuator force ``F`` may act across it.  Layout :data:`~ctmm.layouts.AXIAL`, ``z = [x, f]``, ``f``
= force exerted by the inboard part on the outboard part (full derivation, Wittrick-Williams
counting and state-space form in ``docs/adding_an_element.md``):

    f = -b (a_out - a_in) - c (v_out - v_in) - k (x_out - x_in - l) + F

The element is massless in the usual sense (no inertia to ground) and the force is the same at
both ends, so it is a :class:`~ctmm.elements.lumped.Connector` whose law carries ``tau_a = -b``
(:meth:`Connector.terms <ctmm.elements.lumped.Connector.terms>`); every form below is derived from
those terms (:mod:`ctmm.elements.axial`), with the full dynamic stiffness
``kappa(s) = Z(s) = b s^2 + c s + k``:

    x_out = x_in - f / Z(s) + F / Z(s),   f_out = f_in                    (frequency domain)

In a DT-TMM step every connection point has ``x = cx delta + dx``, ``v = A delta + B``,
``a = C delta + D`` (the unknown ``delta`` of the step, the same ``cx, A, C`` at both ends), so

    delta_out = delta_in + (k l - k (dx_out - dx_in) - c (B_out - B_in) - b (D_out - D_in) + F - f) / k_eff
    k_eff = k cx + c A + b C                                                (DT-TMM)

For the natural-frequency count the element's undamped dynamic stiffness ``k - b w^2`` takes
the place of a spring's ``k`` (it may be negative: the Sturm count stays exact because the
element has no internal degrees of freedom, ``J_0 = 0``); in global matrices it adds
``b [[1, -1], [-1, 1]]`` to the mass matrix (:meth:`Inerter.lumped_coefficients`).
"""
from __future__ import annotations

from typing import Any


from .. import validation
from .base import Element
from .lumped import Connector

__all__ = ["Inerter"]


class Inerter(Connector):
    """Inerter ``b`` [kg], optionally in parallel with a spring and a viscous damper.

    Parameters
    ----------
    name : str
        Element name.
    inertance : float
        Inertance [kg], > 0: the force per unit relative acceleration of the two terminals.
    stiffness : float, optional
        Parallel spring stiffness [N/m], >= 0.
    damping : float, optional
        Parallel viscous damping [N s/m], >= 0.
    free_length : float, optional
        Free length [m] of the parallel spring (absolute coordinates in the time domain).

    Notes
    -----
    The input ``"force"`` acts across the element (``+F`` on its outboard point, ``-F`` on its
    inboard point), as for every connector.  A pure inerter (no spring) transmits no static
    force, so a chain held only through it has no static equilibrium (its transfer matrix is
    infinite at ``s = 0``, like a damper's).

    Examples
    --------
    >>> import ctmm
    >>> from ctmm.elements import Fixed, Free, Inerter, Mass
    >>> chain = ctmm.Chain("apparent_mass", [Fixed("g"), Inerter("b", 1.0, stiffness=100.0),
    ...                                      Mass("m", 3.0), Free("e")])
    >>> round(float(ctmm.natural_frequencies(chain, n_modes=1)[0]), 12)   # sqrt(k / (m + b))
    5.0
    """

    def __init__(self, name: str, inertance: float, *, stiffness: float = 0.0, damping: float = 0.0,
                 free_length: float = 0.0) -> None:
        # Connector.__init__ requires k + c > 0; an inerter is valid without either.
        Element.__init__(self, name)
        self.inertance = validation.positive(f"{name}: inertance", inertance)
        self.stiffness = validation.nonnegative(f"{name}: stiffness", stiffness)
        self.damping = validation.nonnegative(f"{name}: damping", damping)
        self.free_length = validation.finite(f"{name}: free_length", free_length)
        self.derive_forms()

    def parameters(self) -> dict[str, Any]:
        return {"inertance": self.inertance, "stiffness": self.stiffness, "damping": self.damping,
                "free_length": self.free_length}
