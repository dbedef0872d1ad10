"""ctmm: controls-oriented transfer matrix method for multibody systems.

One model, two domains: the linear MSTMM in the frequency domain
(:func:`frequency_response`, :func:`natural_frequencies`, :func:`mode_shapes`) and the
discrete-time TMM in the time domain (:func:`simulate`), both solved by Riccati transfer.
"""
from . import signals
from .errors import ConvergenceError, ModelError, SimulationError, SingularSystemError, UnknownNameError
from .frequency import (characteristic_function, eigenvalue_count, frequency_response, mode_shapes, natural_frequencies,
                        steady_state_response)
from .system import Chain
from .linearize import LinearizedSystem, linearize
from .simulation import simulate
from .scene_files import load_scene
from .version import __version__

from . import control, stability  # noqa: E402  (submodules used as ctmm.control / ctmm.stability)
from .fmu_export import export_fmu  # noqa: E402
from . import sensitivity  # noqa: E402  (ctmm.sensitivity: exact derivatives for tuning)
from . import interop  # noqa: E402  (ctmm.interop: python-control export of any model)
from .batch import simulate_batch  # noqa: E402  (one generated kernel over parameter sets)
from .parameter_sets import parameter_names  # noqa: E402

__all__ = ["Chain", "simulate", "linearize", "LinearizedSystem", "characteristic_function", "frequency_response",
           "natural_frequencies", "mode_shapes", "eigenvalue_count",
           "steady_state_response", "signals", "ModelError", "SimulationError", "ConvergenceError",
           "SingularSystemError", "UnknownNameError", "control", "stability", "__version__", "load_scene", "export_fmu",
           "sensitivity", "simulate_batch", "parameter_names"]
