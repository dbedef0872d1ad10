"""Element library."""
from .base import DiscreteElement, Element, Linearisation
from .beams import (BeamClamped, BeamField, BeamFree, BeamHinge, BeamPinned, BeamPointLoad, BeamPointMass,
                    BeamSliding, BeamSpring)
from .boundary import Boundary, Elastic, Fixed, Free, PrescribedDisplacement, PrescribedForce
from .lumped import Connector, Damper, GroundedSpring, Mass, PointElement, Spring, SpringDamper

__all__ = ["Element", "DiscreteElement", "Linearisation", "Boundary", "Fixed", "Free", "Elastic",
           "PrescribedDisplacement", "PrescribedForce", "PointElement", "Mass", "GroundedSpring",
           "Connector", "Spring", "Damper", "SpringDamper",
           "BeamField", "BeamPointMass", "BeamSpring", "BeamHinge", "BeamPointLoad",
           "BeamClamped", "BeamFree", "BeamPinned", "BeamSliding"]
