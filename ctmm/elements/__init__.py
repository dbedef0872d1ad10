"""Element library."""
from .base import DiscreteElement, Element, Linearisation, LumpedCoefficients
from .beams import (BeamClamped, BeamField, BeamFree, BeamHinge, BeamPinned, BeamPointLoad, BeamPointMass,
                    BeamSliding, BeamSpring)
from .boundary import Boundary, Elastic, Fixed, Free, PrescribedDisplacement, PrescribedForce
from .inerter import Inerter
from .lumped import Connector, Damper, GroundedSpring, Mass, PointElement, Spring, SpringDamper

__all__ = ["Element", "DiscreteElement", "Linearisation", "LumpedCoefficients", "Boundary", "Fixed", "Free", "Elastic",
           "PrescribedDisplacement", "PrescribedForce", "PointElement", "Mass", "GroundedSpring",
           "Connector", "Spring", "Damper", "SpringDamper", "Inerter",
           "BeamField", "BeamPointMass", "BeamSpring", "BeamHinge", "BeamPointLoad",
           "BeamClamped", "BeamFree", "BeamPinned", "BeamSliding"]
