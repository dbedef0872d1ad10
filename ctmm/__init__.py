"""ctmm: controls-oriented transfer matrix method for multibody systems."""
from .errors import ModelError, SimulationError, ConvergenceError, SingularSystemError, UnknownNameError

__version__ = "0.1.0"
__all__ = ["ModelError", "SimulationError", "ConvergenceError", "SingularSystemError",
           "UnknownNameError", "__version__"]
