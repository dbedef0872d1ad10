"""Element library."""
from .base import DiscreteElement, Element, Linearisation
from .boundary import Boundary, Elastic, Fixed, Free, PrescribedDisplacement, PrescribedForce
from .lumped import Connector, Damper, GroundedSpring, Mass, PointElement, Spring, SpringDamper

__all__ = ["Element", "DiscreteElement", "Linearisation", "Boundary", "Fixed", "Free", "Elastic",
           "PrescribedDisplacement", "PrescribedForce", "PointElement", "Mass", "GroundedSpring",
           "Connector", "Spring", "Damper", "SpringDamper"]
