"""Plant FMU export: :func:`export_fmu` writes an FMI co-simulation FMU of a ctmm system (issue 17, item 1).

The FMU runs the generated C of the system's RK4 step -- the step of ``ctmm.simulate(...,
compiled=True)``, from the same casadi terms (:mod:`ctmm.fmu_export_model`), embedded loops and LTI
controllers closed inside it -- behind a hand-written FMI 2.0 or 3.0 interface (:mod:`ctmm.fmu_export_runtime`).
No Python runs in the FMU.  The archive holds the model description, the two C sources and a binary
for this platform; it is built by :func:`ctmm.control.fmu_build.build_fmu` (cached by a hash of the
sources, the FMI headers, the compiler and the flags) and checked by :func:`fmpy.validation.validate_fmu`.

What exports (``docs/fmu_export.md``): planar models (rigid trees, modal beams, hub-beam scenes),
controlled planar models (``ctmm.control.with_feedback``) and spatial models (:mod:`ctmm.fmu_export_spatial`)
that ``compiled=True`` runs.  Refused by name (:class:`~ctmm.errors.ModelError`): controlled spatial
models (no generated step with loops yet), 1-D chains and controlled chains (no generated step).
FMI 2.0 and 3.0 co-simulation are written (:mod:`ctmm.fmu_export_fmi3`).
"""
from __future__ import annotations

import math
import os
import re
import shutil
import tempfile
from pathlib import Path
from typing import Any, Mapping, Sequence

from . import validation
from .codegen import cache_directory, cache_key
from .control.controlled_model import ControlledModel
from .control.fmu_build import build_fmu
from .errors import ModelError
from .fmu_export_files import write_sources
from .fmu_export_model import planar_export
from .fmu_export_spatial import spatial_export
from .planar.model import PlanarModel
from .spatial.model import SpatialModel

__all__ = ["FMI_VERSIONS", "export_fmu"]

FMI_VERSIONS = ("2.0", "3.0")
"""FMI versions :func:`export_fmu` writes."""
_KEY_FORMAT = b"ctmm.export_fmu/1"
_IDENTIFIER = re.compile(r"[A-Za-z_][A-Za-z0-9_]*\Z")


def export_fmu(system: Any, path: str | os.PathLike, *, step: float, inputs: Sequence[str] | None = None,
               outputs: Sequence[str] | None = None, parameters: Sequence[str] | None = None,
               fmi_version: str = "2.0", q0: Any = None, qdot0: Any = None,
               references: Mapping[str, Any] | None = None, start_time: float = 0.0, stop_time: float = 1.0,
               stability_check: str = "warn", compiler: str = "cc",
               cache_dir: str | os.PathLike | None = None) -> Path:
    """Write a co-simulation FMU of ``system`` to ``path``.

    Parameters
    ----------
    system : PlanarModel, ControlledModel or SpatialModel
        A planar model (rigid, modal beams), a controlled planar model whose loops close inside the
        FMU's step, or a spatial model; what ``ctmm.simulate(..., compiled=True)`` compiles.
    path : path
        The ``.fmu`` file to write; its stem is the model identifier (a C identifier: letters, digits,
        ``_``, not starting with a digit).  Its folder is created if missing.
    step : float
        RK4 step of the FMU [s]; every communication step must be a whole multiple of it (the FMU
        runs ``H / step`` steps with the inputs held), and each loop delay too.
    inputs : sequence of str, optional
        Actuators exposed as inputs (``"<hinge>.torque"``, ``"<body>.force_x"``, modal forces; spatial:
        joint inputs, ``"<input>[k]"`` per component of a vector input, and on request body actuators
        ``"<body>.force_x"``, ``"<body>.moment_body_z"``, ...); default every actuator of the
        generated kernel (spatial: the joint inputs); the others are held at 0.
    outputs : sequence of str, optional
        Sensors exposed as outputs (any sensor of :mod:`ctmm.planar.ports`, and ``"<loop>.y"``,
        ``"<loop>.u"`` of a controlled model; spatial: coordinates, velocities, ``"<body>.position_x"``,
        ``"<body>.omega_x"`` ...); default every coordinate and its rate (``"<coordinate>_dot"``;
        spatial: the velocities).
    parameters : sequence of str, optional
        Model numbers exposed as fixed parameters (:func:`ctmm.fmu_export_model.parameter_names`:
        masses, inertias, gravity, hinge stiffnesses and dampings, hinge-law and load signal
        parameters that are not zero; spatial: :mod:`ctmm.fmu_export_spatial`, modal beams' numbers
        included, none with a finite-element body); default all of them; ``()`` none.
    fmi_version : {"2.0", "3.0"}
        FMI version of the co-simulation FMU (3.0: Float64 variables, the independent variable
        ``time``, no event mode).
    q0, qdot0 : array_like or mapping, optional
        Start values of the coordinates [rad, m, modal] and rates, as ``x0``, ``v0`` of ``ctmm.simulate``
        (``{coordinate: value}`` or every value in order; default zeros, spatial: the neutral configuration at
        rest); the FMU exposes them
        as parameters ``"<coordinate>_start"`` and ``"<coordinate>_dot_start"`` (spatial:
        ``"<velocity>_start"``).
    references : mapping, optional
        ``{loop: number or symbolic signal}`` references of a controlled model [sensed unit]
        (constants of the code, as in ``ctmm.simulate``).
    start_time, stop_time : float
        ``DefaultExperiment`` of the model description [s].
    stability_check : {"warn", "error", "ignore"}
        Policy when ``step`` exceeds the plant's linearised RK4 limit at the start values.
    compiler : str
        C compiler command or path.
    cache_dir : path, optional
        Cache folder (:func:`ctmm.codegen.cache_directory`): the scene's native library and the built
        FMUs (``fmu_export/<hash>/``); an unchanged export copies the cached FMU.

    Returns
    -------
    pathlib.Path
        ``path``.

    Raises
    ------
    ModelError
        An unsupported system or FMI version (named), unknown input, output or parameter names, a bad
        step, path or start values, a compile error, or an FMU that :func:`fmpy.validation.validate_fmu`
        rejects.

    Examples
    --------
    >>> fmu = ctmm.export_fmu(model, "pendulum.fmu", step=1e-3,             # doctest: +SKIP
    ...                       inputs=["h.torque"], outputs=["rod.theta"])
    >>> fmpy.simulate_fmu(str(fmu), stop_time=2.0, output_interval=0.01)    # doctest: +SKIP
    """
    if fmi_version not in FMI_VERSIONS:
        raise ModelError(f"export_fmu: fmi_version {fmi_version!r} is not written; allowed: "
                         f"{', '.join(map(repr, FMI_VERSIONS))}")
    step = validation.positive("step", step)
    if not math.isfinite(step):
        raise ModelError(f"step must be a finite number > 0 [s], got {step!r}")
    start_time = validation.finite("start_time", start_time)
    stop_time = validation.finite("stop_time", stop_time)
    if stop_time <= start_time:
        raise ModelError(f"stop_time must be > start_time = {start_time!r}, got {stop_time!r}")
    if not isinstance(path, (str, os.PathLike)) or not str(path):
        raise ModelError(f"path must be a file path ending in .fmu, got {path!r}")
    target = Path(path)
    if target.suffix != ".fmu" or not _IDENTIFIER.match(target.stem):
        raise ModelError(f"path must end in '<identifier>.fmu' with a C identifier as its stem (letters, digits, "
                         f"'_', not starting with a digit: the model identifier), got {str(path)!r}")
    if stability_check not in ("warn", "error", "ignore"):
        raise ModelError(f"stability_check must be 'warn', 'error' or 'ignore', got {stability_check!r}")
    plant = system.plant if isinstance(system, ControlledModel) else system
    if isinstance(system, SpatialModel):
        if references:
            raise ModelError(f"export_fmu: references apply to a ControlledModel (its loops), got {references!r} for "
                             f"the spatial model {system.name!r}")
        exported = spatial_export(system, inputs=inputs, outputs=outputs, parameters=parameters, q0=q0, qdot0=qdot0)
    elif isinstance(plant, PlanarModel):
        if references and not isinstance(system, ControlledModel):
            raise ModelError(f"export_fmu: references apply to a ControlledModel (its loops), got {references!r} "
                             f"for the model {plant.name!r} without loops")
        exported = planar_export(system, step=step, inputs=inputs, outputs=outputs, parameters=parameters, q0=q0,
                                 qdot0=qdot0, references=references, stability_check=stability_check,
                                 cache_dir=cache_dir)
    else:
        kind = type(plant).__name__ if plant is system else f"ControlledModel on a {type(plant).__name__}"
        raise ModelError(f"export_fmu: system must be a ctmm.planar.PlanarModel, a ControlledModel on one or a "
                         f"ctmm.spatial.SpatialModel, got {kind}; controlled spatial models, 1-D chains and "
                         "controlled chains are not exported yet")
    identifier = target.stem
    cache = cache_directory(cache_dir, subfolder="fmu_export")
    with tempfile.TemporaryDirectory(prefix=f".{identifier}-", dir=cache) as work:
        folder = Path(work)
        write_sources(exported, folder, identifier, step, start_time, stop_time, fmi_version)
        files = sorted(p for p in folder.rglob("*") if p.is_file())
        key = cache_key(_KEY_FORMAT, [(p.relative_to(folder).as_posix(), p.read_bytes()) for p in files])
        built = build_fmu(folder, cache / key[:24], compiler=compiler)
    partial = target.with_name(f".{target.name}.partial")
    try:
        target.parent.mkdir(parents=True, exist_ok=True)
        shutil.copyfile(built, partial)
        os.replace(partial, target)            # the FMU appears whole or not at all
    except OSError as exc:
        partial.unlink(missing_ok=True)
        raise ModelError(f"path {str(path)!r} cannot be written: {exc}") from None
    return target
