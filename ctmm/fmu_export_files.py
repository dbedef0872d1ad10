"""The files of an exported plant FMU: ``modelDescription.xml`` and the C sources (:mod:`ctmm.fmu_export`).

:func:`write_sources` writes a source folder that :func:`ctmm.control.fmu_build.build_fmu` compiles:

* ``modelDescription.xml`` -- FMI 2.0 or 3.0 co-simulation, flat names, value references in the order
  inputs, outputs, parameters, start values (:class:`~ctmm.fmu_export_model.ExportedSystem`) and, FMI
  3, the independent variable ``time``; FMI 2 ``<SourceFiles>`` (FMI 3: ``sources/buildDescription.xml``)
  list the C files, so the FMU also ships its sources (rebuild it elsewhere);
* ``sources/<identifier>.c`` -- the FMI interface (:mod:`ctmm.fmu_export_runtime`);
* ``sources/ctmm_fmu_source.c`` -- casadi-generated C of ``ctmm_initial``, ``ctmm_step`` and
  ``ctmm_outputs`` (no exported symbols: two exported FMUs load in one process);
* ``sources/unsupported_fmi2.c`` or ``unsupported_fmi3.c`` -- the stubs of the calls the FMU does not support, the one
  source shared with the shipped controller FMUs (``controllers/fmu_common``, :func:`unsupported_source`).

The GUID is derived from the SHA-256 of the C text and the description, so the same system gives the
same files (and the build cache of :func:`~ctmm.control.fmu_build.build_fmu` finds them).
"""
from __future__ import annotations

import hashlib
import importlib.resources
import tempfile
import uuid
from pathlib import Path
from typing import Iterable
from xml.sax.saxutils import quoteattr

from .fmu_export_model import ExportedSystem, ExportedVariable
from .fmu_export_runtime import runtime_source
from .version import __version__

__all__ = ["UNIT_EXPONENTS", "UNSUPPORTED_FILES", "build_description", "casadi_text", "model_description",
           "unsupported_source", "write_sources"]

GENERATED_FILE = "ctmm_fmu_source.c"
"""Name of the casadi-generated C file inside ``sources/``."""

UNSUPPORTED_FILES = {"2": "unsupported_fmi2.c", "3": "unsupported_fmi3.c"}
"""``{FMI major version: file}`` of the shared stubs of unsupported calls (``controllers/fmu_common``)."""


def unsupported_source(fmi_version: str) -> tuple[str, str] | None:
    """``(file name, C text)`` of the stubs of the calls an FMI ``fmi_version`` FMU does not support, shared
    by the exported FMUs and the shipped controller FMUs; ``None`` where the interface keeps its own."""
    name = UNSUPPORTED_FILES.get(fmi_version.split(".")[0])
    if name is None:
        return None
    return name, importlib.resources.files("ctmm.controllers").joinpath("fmu_common", name).read_text()


UNIT_EXPONENTS: dict[str, dict[str, int]] = {
    "rad": {"rad": 1}, "rad/s": {"rad": 1, "s": -1}, "rad/s^2": {"rad": 1, "s": -2},
    "m": {"m": 1}, "m/s": {"m": 1, "s": -1}, "m/s^2": {"m": 1, "s": -2}, "s": {"s": 1},
    "kg": {"kg": 1}, "kg m^2": {"kg": 1, "m": 2}, "N": {"kg": 1, "m": 1, "s": -2},
    "N m": {"kg": 1, "m": 2, "s": -2}, "N m/rad": {"kg": 1, "m": 2, "s": -2, "rad": -1},
    "N m s/rad": {"kg": 1, "m": 2, "s": -1, "rad": -1}, "N/m": {"kg": 1, "s": -2}, "N s/m": {"kg": 1, "s": -1},
    "kg/m": {"kg": 1, "m": -1}, "kg m": {"kg": 1, "m": 1}, "N m^2": {"kg": 1, "m": 3, "s": -2}}
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


_ATTRIBUTES = {"output": 'causality="output" variability="continuous" initial="calculated"',
               "input": 'causality="input" variability="continuous"',
               "parameter": 'causality="parameter" variability="fixed" initial="exact"'}


def _variable(variable: ExportedVariable, reference: int, causality: str, major: int) -> str:
    """One Real (FMI 2) or Float64 (FMI 3) variable of the model description."""
    unit = f" unit={quoteattr(variable.unit)}" if variable.unit in UNIT_EXPONENTS else ""
    start = "" if causality == "output" else f' start="{variable.start!r}"'
    description = quoteattr(variable.description + (f" [{variable.unit}]" if variable.unit else ""))
    head = f'name={quoteattr(variable.name)} valueReference="{reference}" {_ATTRIBUTES[causality]}'
    if major == 3:
        return f"    <Float64 {head}{start}{unit}\n        description={description}/>\n"
    return f"    <ScalarVariable {head}\n        description={description}><Real{unit}{start}/></ScalarVariable>\n"


def model_description(system: ExportedSystem, identifier: str, guid: str, step: float, start_time: float,
                      stop_time: float, fmi_version: str = "2.0") -> str:
    """The ``modelDescription.xml`` text, FMI 2.0 or 3.0 co-simulation; value references: inputs, outputs,
    parameters, start values and (FMI 3) the independent variable ``time``."""
    major = int(fmi_version[0])
    groups = [(system.inputs, "input"), (system.outputs, "output"), (system.parameters, "parameter"),
              (system.starts, "parameter")]
    variables, reference = [], 0
    outputs, starts = [], []            # FMI 2: 1-based indices in ModelVariables; FMI 3: value references
    for members, causality in groups:
        for variable in members:
            variables.append(_variable(variable, reference, causality, major))
            label = reference if major == 3 else reference + 1
            reference += 1
            if causality == "output":
                outputs.append(label)
            elif members is system.starts:
                starts.append(label)
    used = {v.unit for members, _ in groups for v in members if v.unit in UNIT_EXPONENTS}
    used |= {"s"} if major == 3 else set()
    units = "".join(f"    <Unit name={quoteattr(name)}><BaseUnit " +
                    " ".join(f'{base}="{power}"' for base, power in UNIT_EXPONENTS[name].items()) + "/></Unit>\n"
                    for name in sorted(used))
    depends = " ".join(str(k) for k in starts)
    description = quoteattr(f"ctmm plant {system.name}: RK4 of the generated step, h = {step!r} s, inputs held "
                            "over a communication step; " + "; ".join(system.notes))
    tool = quoteattr("ctmm " + __version__ + " (ctmm.export_fmu)")
    if major == 3:
        variables.append(f'    <Float64 name="time" valueReference="{reference}" causality="independent" '
                         'variability="continuous" unit="s"\n        description="Simulation time [s]"/>\n')
        head = (f'<fmiModelDescription fmiVersion="3.0" modelName={quoteattr(system.name)} '
                f'instantiationToken="{guid}"\n  description={description}\n  generationTool={tool}\n'
                '  variableNamingConvention="flat">\n'
                f'  <CoSimulation modelIdentifier="{identifier}" canHandleVariableCommunicationStepSize="true"\n'
                f'    fixedInternalStepSize="{step!r}" canGetAndSetFMUState="true" canSerializeFMUState="false"\n'
                '    hasEventMode="false" providesIntermediateUpdate="false"/>\n')
        structure = "".join(f'    <Output valueReference="{k}" dependencies=""/>\n' for k in outputs)
        structure += "".join(f'    <InitialUnknown valueReference="{k}" dependencies="{depends}"/>\n'
                             for k in outputs)
    else:
        head = (f'<fmiModelDescription fmiVersion="2.0" modelName={quoteattr(system.name)} guid="{guid}"\n'
                f'  description={description}\n  generationTool={tool}\n'
                '  variableNamingConvention="flat" numberOfEventIndicators="0">\n'
                f'  <CoSimulation modelIdentifier="{identifier}" canHandleVariableCommunicationStepSize="true"\n'
                '    canGetAndSetFMUstate="true" canSerializeFMUstate="false"\n'
                '    canNotUseMemoryManagementFunctions="true"\n'
                '    canBeInstantiatedOnlyOncePerProcess="false" providesDirectionalDerivative="false">\n'
                f'    <SourceFiles><File name="{identifier}.c"/><File name="{GENERATED_FILE}"/>'
                f'<File name="{UNSUPPORTED_FILES["2"]}"/></SourceFiles>\n'
                '  </CoSimulation>\n')
        structure = ("".join(f'      <Unknown index="{k}" dependencies=""/>\n' for k in outputs),
                     "".join(f'      <Unknown index="{k}" dependencies="{depends}"/>\n' for k in outputs))
        structure = ((f"    <Outputs>\n{structure[0]}    </Outputs>\n" if outputs else "")
                     + (f"    <InitialUnknowns>\n{structure[1]}    </InitialUnknowns>\n" if outputs else ""))
    return ('<?xml version="1.0" encoding="UTF-8"?>\n' + head
            + (f"  <UnitDefinitions>\n{units}  </UnitDefinitions>\n" if units else "")
            + f'  <DefaultExperiment startTime="{start_time!r}" stopTime="{stop_time!r}" stepSize="{step!r}"/>\n'
            + "  <ModelVariables>\n" + "".join(variables) + "  </ModelVariables>\n"
            + "  <ModelStructure>\n" + structure + "  </ModelStructure>\n</fmiModelDescription>\n")


def build_description(identifier: str) -> str:
    """``sources/buildDescription.xml`` of an FMI 3.0 FMU: the C files of the model identifier."""
    return ('<?xml version="1.0" encoding="UTF-8"?>\n<fmiBuildDescription fmiVersion="3.0">\n'
            f'  <BuildConfiguration modelIdentifier="{identifier}">\n    <SourceFileSet language="C99">\n'
            f'      <SourceFile name="{identifier}.c"/>\n      <SourceFile name="{GENERATED_FILE}"/>\n'
            f'      <SourceFile name="{UNSUPPORTED_FILES["3"]}"/>\n'
            "    </SourceFileSet>\n  </BuildConfiguration>\n</fmiBuildDescription>\n")


def write_sources(system: ExportedSystem, folder: Path, identifier: str, step: float, start_time: float,
                  stop_time: float, fmi_version: str = "2.0") -> str:
    """Write ``modelDescription.xml`` and ``sources/`` of an FMI ``fmi_version`` FMU into ``folder``; returns
    the GUID (FMI 3: the instantiation token)."""
    generated = casadi_text(system)
    values = {"IDENTIFIER": identifier, "STEP": repr(float(step)), "N_INPUTS": str(len(system.inputs)),
              "N_U": str(system.n_inputs_total), "N_OUTPUTS": str(len(system.outputs)),
              "N_PARAMETERS": str(len(system.parameters)), "N_P": str(system.parameter_values.size),
              "N_START": str(len(system.starts)), "N_STATE": str(system.state_size),
              "INPUT_INDEX": ", ".join(str(v.index) for v in system.inputs) or "0",
              "PARAMETER_INDEX": ", ".join(str(v.index) for v in system.parameters) or "0",
              "P_START": _numbers(system.parameter_values),
              "START_VALUES": _numbers(v.start for v in system.starts)}
    draft = model_description(system, identifier, "{GUID}", step, start_time, stop_time, fmi_version)
    digest = hashlib.sha256()
    stubs = unsupported_source(fmi_version)
    for part in (generated, runtime_source({**values, "GUID": "{GUID}"}, fmi_version), draft, *(stubs or ())):
        digest.update(part.encode() + b"\0")
    guid = "{" + str(uuid.UUID(digest.hexdigest()[:32])) + "}"
    sources = folder / "sources"
    sources.mkdir(parents=True, exist_ok=True)
    (sources / GENERATED_FILE).write_text(generated)
    (sources / f"{identifier}.c").write_text(runtime_source({**values, "GUID": guid}, fmi_version))
    if stubs is not None:
        (sources / stubs[0]).write_text(stubs[1])
    if fmi_version.startswith("3"):
        (sources / "buildDescription.xml").write_text(build_description(identifier))
    (folder / "modelDescription.xml").write_text(draft.replace("{GUID}", guid))
    return guid
