"""Controllers: protocol, embedded feedback loops, Python and FMU adapters, co-simulation.

* :class:`Feedback` / :class:`ControlledChain` -- linear loops embedded in transfer matrices.
* :class:`ControlledModel` / :func:`with_feedback` -- the same loops on planar models (any plant).
* :func:`simulate_controlled` -- DT-TMM with real-time / delayed loops and co-simulated controllers.
* :class:`Controller` -- protocol for sampled, stateful or nonlinear controllers (Python, FMU);
  :class:`DelayedController` reads a controller's inputs a measurement delay late;
  :class:`StaticGainController` is a sampled matrix gain ``u = clip(K y)`` on named signals.
* :class:`FMUController`, :func:`build_fmu` -- FMI 2.0/3.0 co-simulation and model-exchange FMUs through fmpy.
* :func:`loop_transfer_function`, :func:`margins` (gain/phase/delay), :func:`bode_plot`,
  :func:`nyquist_plot`, :class:`PlantCache` (cheap re-evaluation in control-design loops).
* :func:`tune` -- gradient-based tuning on the exact sensitivities of :mod:`ctmm.sensitivity`.
"""
from .analysis import closed_loop_response, encirclements, loop_transfer_function, margins
from .loop_plots import bode_plot, nyquist_plot
from .design import PlantCache
from .fmu import FMUController, build_fmu
from .loops import ControlledChain, Feedback
from .controlled_model import ControlledModel, with_feedback
from .protocol import Controller, ControllerStep
from .measurement_delay import DelayedController
from .static_gain import StaticGainController
from .simulate import simulate_controlled
from .tuning import Constraint, Quantity, TuningResult, tune

__all__ = ["Controller", "ControllerStep", "DelayedController", "StaticGainController", "Feedback", "ControlledChain", "ControlledModel", "with_feedback", "simulate_controlled",
           "FMUController", "build_fmu", "loop_transfer_function", "margins", "closed_loop_response",
           "bode_plot", "nyquist_plot", "encirclements", "PlantCache"]
__all__ += ["tune", "Quantity", "Constraint", "TuningResult"]

