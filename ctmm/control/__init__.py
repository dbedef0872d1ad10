"""Controllers: protocol, embeddable linear laws, delays, Python-object and FMU adapters."""
from .protocol import Controller, ControllerStep

__all__ = ["Controller", "ControllerStep"]
