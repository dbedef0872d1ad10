"""Ready-made controllers for ctmm (importable as ``ctmm.controllers``).

Python objects implementing :class:`ctmm.control.protocol.Controller`:

* :class:`SaturatedPD` -- PD law with symmetric saturation (stateless, direct feedthrough).
* :class:`PID` -- sampled PID with filtered derivative and clamping anti-windup (stateful).

FMU sources (build with :func:`ctmm.control.fmu.build_fmu`, run with
:class:`ctmm.control.fmu.FMUController`); :func:`fmu_source` returns their folders:

* ``pd_controller`` -- FMI 2.0 co-simulation, the :class:`SaturatedPD` law (inputs ``y``, ``ydot``;
  output ``u``; parameters ``kp``, ``kd``, ``limit``, ``reference``, ``fail_at_time``).
* ``pi_controller`` -- FMI 2.0 co-simulation PI with an internal integrator advanced in doStep
  (input ``y``; output ``u``; parameters ``kp``, ``ki``, ``reference``, ``fail_at_time``).
* ``pd_controller_fmi3`` -- the PD law as an FMI 3.0 co-simulation FMU.
* ``typed_io_fmi3`` -- FMI 3.0 test controller with Float32 / Int32 / UInt8 / Boolean variables,
  two array variables and a doStep that can return Discard (sources listed in
  ``sources/buildDescription.xml``).
* ``lag_filter_me`` -- FMI 2.0 model-exchange first-order lag with a state event (threshold
  crossings) and a time event (reset), for the model-exchange path of the FMU controller.
"""
from __future__ import annotations

from pathlib import Path

from ctmm.errors import unknown_name

from .pd import SaturatedPD, SaturatedPDState
from .pid import PID, PIDState

__all__ = ["SaturatedPD", "SaturatedPDState", "PID", "PIDState", "FMU_SOURCES", "fmu_source"]

_FMU_DIR = Path(__file__).resolve().parent / "fmu"

FMU_SOURCES: tuple[str, ...] = ("pd_controller", "pi_controller", "pd_controller_fmi3", "typed_io_fmi3",
                                 "lag_filter_me")
"""Names of the FMU source folders shipped in ``controllers/fmu``."""


def fmu_source(name: str) -> Path:
    """Folder of a shipped FMU source (``modelDescription.xml`` + ``sources/``).

    Parameters
    ----------
    name : str
        One of :data:`FMU_SOURCES`.

    Examples
    --------
    >>> from ctmm.control.fmu import build_fmu, FMUController
    >>> path = build_fmu(fmu_source("pd_controller"))                   # doctest: +SKIP
    """
    if name not in FMU_SOURCES:
        raise unknown_name("FMU source", name, FMU_SOURCES)
    return _FMU_DIR / name
