"""The files of an exported plant FMU: ``modelDescription.xml`` and the C sources (:mod:`ctmm.fmu_export`).

:func:`write_sources` writes a source folder that :func:`ctmm.control.fmu_build.build_fmu` compiles:

* ``modelDescription.xml`` -- FMI 2.0 co-simulation, flat names, value references in the order
  inputs, outputs, parameters, start values (:class:`~ctmm.fmu_export_model.ExportedSystem`); its
  ``<SourceFiles>`` list the two C files, so the FMU also ships its sources (rebuild it elsewhere);
* ``sources/<identifier>.c`` -- the FMI interface (:mod:`ctmm.fmu_export_runtime`);
* ``sources/ctmm_fmu_source.c`` -- casadi-generated C of ``ctmm_initial``, ``ctmm_step`` and
  ``ctmm_outputs`` (no exported symbols: two exported FMUs load in one process).

The GUID is derived from the SHA-256 of the C text and the description, so the same system gives the
same files (and the build cache of :func:`~ctmm.control.fmu_build.build_fmu` finds them).
"""
from __future__ import annotations

import hashlib
import tempfile
import uuid
from pathlib import Path
from typing import Iterable
from xml.sax.saxutils import quoteattr

from .fmu_export_model import ExportedSystem, ExportedVariable
from .fmu_export_runtime import runtime_source
from .version import __version__

__all__ = ["UNIT_EXPONENTS", "casadi_text", "model_description", "write_sources"]

GENERATED_FILE = "ctmm_fmu_source.c"
"""Name of the casadi-generated C file inside ``sources/``."""

UNIT_EXPONENTS: dict[str, dict[str, int]] = {
    "rad": {"rad": 1}, "rad/s": {"rad": 1, "s": -1}, "rad/s^2": {"rad": 1, "s": -2},
    "m": {"m": 1}, "m/s": {"m": 1, "s": -1}, "m/s^2": {"m": 1, "s": -2}, "s": {"s": 1},
    "kg": {"kg": 1}, "kg m^2": {"kg": 1, "m": 2}, "N": {"kg": 1, "m": 1, "s": -2},
    "N m": {"kg": 1, "m": 2, "s": -2}, "N m/rad": {"kg": 1, "m": 2, "s": -2, "rad": -1},
    "N m s/rad": {"kg": 1, "m": 2, "s": -1, "rad": -1}}
"""SI base-unit exponents of the unit texts ctmm uses (a variable with another unit text carries it in its
description only)."""


def casadi_text(system: ExportedSystem) -> str:
    """C text of the system's three generated functions, without exported symbols."""
    import casadi as ca

    generator = ca.CodeGenerator("ctmm_fmu_source", {"with_header": False, "with_export": False})
    for function in (system.initial_function, system.step_function, system.output_function):
        generator.add(function)
    with tempfile.TemporaryDirectory() as folder:
        generator.generate(folder + "/")
        return (Path(folder) / f"{GENERATED_FILE}").read_text()


def _numbers(values: Iterable[float]) -> str:
    """C initialiser of doubles at full precision (``0`` for an empty list: arrays have one spare entry)."""
    text = ", ".join(repr(float(value)) for value in values)
    return text or "0"


def _variable(variable: ExportedVariable, reference: int, causality: str) -> str:
    unit = f" unit={quoteattr(variable.unit)}" if variable.unit in UNIT_EXPONENTS else ""
    description = variable.description + (f" [{variable.unit}]" if variable.unit else "")
    if causality == "output":
        head, real = 'causality="output" variability="continuous" initial="calculated"', f"<Real{unit}/>"
    elif causality == "input":
        head, real = 'causality="input" variability="continuous"', f'<Real{unit} start="{variable.start!r}"/>'
    else:
        head = 'causality="parameter" variability="fixed" initial="exact"'
        real = f'<Real{unit} start="{variable.start!r}"/>'
    return (f"    <ScalarVariable name={quoteattr(variable.name)} valueReference=\"{reference}\" {head}\n"
            f"        description={quoteattr(description)}>{real}</ScalarVariable>\n")


def model_description(system: ExportedSystem, identifier: str, guid: str, step: float, start_time: float,
                      stop_time: float) -> str:
    """The FMI 2.0 ``modelDescription.xml`` text (co-simulation, value references as in the module docstring)."""
    groups = [(system.inputs, "input"), (system.outputs, "output"), (system.parameters, "parameter"),
              (system.starts, "parameter")]
    variables, reference = [], 0
    output_indices, start_indices = [], []
    for members, causality in groups:
        for variable in members:
            variables.append(_variable(variable, reference, causality))
            reference += 1
            if causality == "output":
                output_indices.append(reference)          # 1-based index in ModelVariables
            elif members is system.starts:
                start_indices.append(reference)
    used = sorted({v.unit for members, _ in groups for v in members if v.unit in UNIT_EXPONENTS})
    units = "".join(f"    <Unit name={quoteattr(name)}><BaseUnit " +
                    " ".join(f'{base}="{power}"' for base, power in UNIT_EXPONENTS[name].items()) + "/></Unit>\n"
                    for name in used)
    starts = " ".join(str(k) for k in start_indices)
    outputs = "".join(f'      <Unknown index="{k}" dependencies=""/>\n' for k in output_indices)
    initial = "".join(f'      <Unknown index="{k}" dependencies="{starts}"/>\n' for k in output_indices)
    description = (f"ctmm plant {system.name}: RK4 of the generated step, h = {step!r} s, inputs held over a "
                   "communication step; " + "; ".join(system.notes))
    return (
        '<?xml version="1.0" encoding="UTF-8"?>\n'
        f'<fmiModelDescription fmiVersion="2.0" modelName={quoteattr(system.name)} guid="{guid}"\n'
        f'  description={quoteattr(description)}\n'
        f'  generationTool={quoteattr("ctmm " + __version__ + " (ctmm.export_fmu)")}\n'
        '  variableNamingConvention="flat" numberOfEventIndicators="0">\n'
        f'  <CoSimulation modelIdentifier="{identifier}" canHandleVariableCommunicationStepSize="true"\n'
        '    canGetAndSetFMUstate="true" canSerializeFMUstate="false" canNotUseMemoryManagementFunctions="false"\n'
        '    canBeInstantiatedOnlyOncePerProcess="false" providesDirectionalDerivative="false">\n'
        f'    <SourceFiles><File name="{identifier}.c"/><File name="{GENERATED_FILE}"/></SourceFiles>\n'
        '  </CoSimulation>\n'
        + (f"  <UnitDefinitions>\n{units}  </UnitDefinitions>\n" if units else "")
        + f'  <DefaultExperiment startTime="{start_time!r}" stopTime="{stop_time!r}" stepSize="{step!r}"/>\n'
        '  <ModelVariables>\n' + "".join(variables) + '  </ModelVariables>\n'
        '  <ModelStructure>\n'
        + (f"    <Outputs>\n{outputs}    </Outputs>\n" if outputs else "")
        + (f"    <InitialUnknowns>\n{initial}    </InitialUnknowns>\n" if initial else "")
        + '  </ModelStructure>\n'
        '</fmiModelDescription>\n')


def write_sources(system: ExportedSystem, folder: Path, identifier: str, step: float, start_time: float,
                  stop_time: float) -> str:
    """Write ``modelDescription.xml`` and ``sources/`` of the FMU into ``folder``; returns the GUID."""
    generated = casadi_text(system)
    values = {"IDENTIFIER": identifier, "STEP": repr(float(step)), "N_INPUTS": str(len(system.inputs)),
              "N_U": str(system.n_inputs_total), "N_OUTPUTS": str(len(system.outputs)),
              "N_PARAMETERS": str(len(system.parameters)), "N_P": str(system.parameter_values.size),
              "N_START": str(len(system.starts)), "N_STATE": str(system.state_size),
              "INPUT_INDEX": ", ".join(str(v.index) for v in system.inputs) or "0",
              "PARAMETER_INDEX": ", ".join(str(v.index) for v in system.parameters) or "0",
              "P_START": _numbers(system.parameter_values),
              "START_VALUES": _numbers(v.start for v in system.starts)}
    draft = model_description(system, identifier, "{GUID}", step, start_time, stop_time)
    digest = hashlib.sha256()
    for part in (generated, runtime_source({**values, "GUID": "{GUID}"}), draft):
        digest.update(part.encode() + b"\0")
    guid = "{" + str(uuid.UUID(digest.hexdigest()[:32])) + "}"
    sources = folder / "sources"
    sources.mkdir(parents=True, exist_ok=True)
    (sources / GENERATED_FILE).write_text(generated)
    (sources / f"{identifier}.c").write_text(runtime_source({**values, "GUID": guid}))
    (folder / "modelDescription.xml").write_text(draft.replace("{GUID}", guid))
    return guid
