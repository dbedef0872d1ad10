"""FMU controllers: run an FMI 2.0 / 3.0 FMU as a sampled ctmm controller.

:class:`FMUController` adapts a co-simulation or model-exchange FMU -- one built from the
project's C sources with :func:`~ctmm.control.fmu_build.build_fmu` or a third-party FMU -- to the
:class:`ctmm.control.protocol.Controller` protocol.  The controller object is an immutable
description; the FMU instance lives in the :class:`FMUControllerState` returned by
:meth:`FMUController.init`.

Semantics of ``u, state = controller.step(t, y, state)`` (sample time ``h``):

1. the inputs are set to ``y`` (measurements at ``t``, converted to the variables' FMI types, see
   :mod:`ctmm.control.fmu_variables`),
2. the outputs are read; with direct feedthrough they already depend on ``y(t)``,
3. ``doStep(t, h)`` advances the FMU to ``t + h`` with the inputs held (zero-order hold); a
   model-exchange FMU is integrated instead (:mod:`ctmm.control.fmu_model_exchange`),
4. ``u`` is returned; the caller holds it on ``[t, t + h)``.

Loading cannot corrupt the process: the archive is extracted into a temporary folder that is
removed on every failure, the binary is test-loaded without changing the working directory, and
the working directory is restored around fmpy's loader.  FMI 1.0, scheduled execution and array
variables are refused with a :class:`~ctmm.errors.ModelError`.
"""
from __future__ import annotations

import collections
import os
import shutil
import warnings
import weakref
from pathlib import Path
from types import MappingProxyType
from typing import Any, Mapping

import numpy as np

from .. import validation
from ..errors import ModelError, SimulationError
from .fmu_build import build_fmu
from .fmu_calls import decode, exchange, fmi2_callbacks, instance_class, status_text
from .fmu_description import fmi_headers_dir, fmi_major_version, read_description, require_fmpy
from .fmu_loading import check_library, construct_instance, extract_fmu
from .fmu_model_exchange import ModelExchangeIntegrator
from .fmu_state import FMUControllerState, FMUSnapshot
from .fmu_variables import ValueChannel, mapped_variable, settable_values, si_scaling, variable_type
from .protocol import ControllerStep

__all__ = ["build_fmu", "fmi_headers_dir", "FMUController", "FMUControllerState", "FMUSnapshot"]

_INTERFACES = ("co-simulation", "model exchange")
#: Most RK4 steps of a model-exchange FMU per communication step (a larger count is a unit mistake).
MAX_SOLVER_STEPS_PER_SAMPLE = 1e6


class FMUController:
    """An FMI 2.0 / 3.0 FMU (co-simulation or model exchange) used as a sampled ctmm controller.

    Parameters
    ----------
    path : path
        The ``.fmu`` file (or a folder holding an extracted FMU).
    inputs : mapping of str to str
        FMU input variable name -> ctmm signal it reads, e.g. ``{"y": "m6.x", "ydot": "m6.v"}``.
        Types Real/Float64, Float32, Integer/Int8...UInt64, Enumeration and Boolean are accepted
        (converted as described in :mod:`ctmm.control.fmu_variables`; values in a unit with a
        ``BaseUnit`` factor/offset are converted from and to SI).
    outputs : mapping of str to str
        FMU output variable name -> ctmm signal it writes, e.g. ``{"u": "m2.force"}``; same types.
    parameters : mapping of str to value, optional
        Values set after instantiation, before initialization: parameters (variability
        ``fixed`` or ``tunable``), start values of unmapped inputs and of variables with
        ``initial="exact"`` or ``"approx"`` (e.g. initial states).  The value must suit the type:
        a finite number for Real/Float, an integral number within range for Integer types,
        ``True``/``False`` for Boolean, ``str`` for String; and lie within the variable's declared
        ``min``/``max`` (an enumeration's value must be one of its items).
    sample_time : float, optional
        Communication step size ``h`` [s], > 0; the outputs are held on ``[t, t + h)``.
        Default: the FMU's ``DefaultExperiment stepSize`` (an error if it declares none).  With an
        FMI 3 ``fixedInternalStepSize`` it should be a whole multiple of that step (a
        ``UserWarning`` says so otherwise: the outputs then lag the FMU's internal grid).
    direct_feedthrough : bool, optional
        Whether the outputs depend on the inputs at the same instant.  Default: derived from
        ``ModelStructure/Outputs`` (true if a mapped output depends on a mapped input, or if the
        FMU declares no dependencies).
    instance_name : str, optional
        Name passed to ``fmiXInstantiate`` (shown in the FMU's log).  Default: the model identifier.
    interface : {"co-simulation", "model exchange"}, optional
        Which interface of the FMU to run.  Default: co-simulation if the FMU provides it, else
        model exchange.  A model-exchange FMU is integrated by ctmm between communication points
        with fixed-step RK4, exact time events and bisection-located state events
        (:mod:`ctmm.control.fmu_model_exchange`; no error control).
    solver_step : float, optional
        Model exchange only: largest RK4 step [s] (> 0, at most 1e6 steps per ``sample_time``).
        Default: the smaller of ``sample_time`` and the ``DefaultExperiment stepSize``.
    validate : bool, optional
        Check ``modelDescription.xml`` against the FMI schema (default True).  ``False`` accepts a
        description with schema violations that fmpy can still read, at the user's risk.

    Attributes
    ----------
    can_snapshot : bool
        Co-simulation FMU that declares ``canGetAndSetFMUstate`` (snapshots are not offered for
        model exchange: the integrator's event bookkeeping is not part of the FMU state).
    variable_step : bool
        The FMU declares ``canHandleVariableCommunicationStepSize`` (ctmm always uses the constant
        step ``sample_time``, so this is information only).

    Raises
    ------
    ModelError
        Missing or corrupt file (not a ZIP, truncated, no or invalid ``modelDescription.xml``),
        FMI version not 2.0/3.0, neither co-simulation nor model exchange (or not the requested
        ``interface``), no binary for this platform or one that
        cannot be loaded, an unknown variable name (the message lists the available ones), a
        variable of the wrong causality or type, an array variable, a bad parameter value, or a
        bad sample time.  The working directory, loaded libraries and temporary folders are left
        as they were.

    Examples
    --------
    >>> pd = FMUController(build_fmu("controllers/fmu/pd_controller"),
    ...                    inputs={"y": "m6.x", "ydot": "m6.v"}, outputs={"u": "m2.force"},
    ...                    parameters={"kp": 40.0, "kd": 4.0}, sample_time=1e-3)  # doctest: +SKIP
    >>> with pd.init(0.0) as state:                                                # doctest: +SKIP
    ...     u, state = pd.step(0.0, np.array([0.01, 0.0]), state)
    """

    def __init__(self, path: str | os.PathLike, *, inputs: Mapping[str, str], outputs: Mapping[str, str],
                 parameters: Mapping[str, Any] | None = None, sample_time: float | None = None,
                 direct_feedthrough: bool | None = None, instance_name: str | None = None,
                 interface: str | None = None, solver_step: float | None = None, validate: bool = True) -> None:
        require_fmpy()
        if not isinstance(path, (str, os.PathLike)) or str(path) == "":
            raise ModelError(f"path must be the path of an .fmu file or extracted FMU folder, got {path!r}")
        fmu_path = Path(path)
        if not fmu_path.exists():
            raise ModelError(f"FMU file not found: {str(fmu_path)!r}")
        what = f"FMU {str(fmu_path)!r}"
        if not isinstance(validate, (bool, np.bool_)):
            raise ModelError(f"{what}: validate must be True or False, got {validate!r}")
        description = read_description(fmu_path, what, bool(validate))
        major = fmi_major_version(description.fmiVersion, what)
        interface, kind = self._interface(interface, description, what)
        identifier = kind.modelIdentifier
        what = f"FMU {identifier!r} ({str(fmu_path)!r})"

        variables = {v.name: v for v in description.modelVariables}
        mapped_in = self._map("inputs", inputs, variables, "input", major, what)
        mapped_out = self._map("outputs", outputs, variables, "output", major, what)
        if not mapped_out:
            raise ModelError(f"{what}: outputs must map at least one FMU output variable to a ctmm signal")
        signals = list(mapped_out.values())
        duplicated = sorted({s for s in signals if signals.count(s) > 1})
        if duplicated:
            raise ModelError(f"{what}: outputs writes the ctmm signal(s) {', '.join(duplicated)} from more than "
                             "one FMU variable; allowed: each signal written once")
        settings = settable_values(parameters, variables, major, what, tuple(mapped_in))
        h = self._sample_time(sample_time, description, interface, what)
        step = self._solver_step(solver_step, h, description, interface, what)

        if direct_feedthrough is None:
            feedthrough = _derive_feedthrough(description, [variables[n] for n in mapped_out],
                                              {id(variables[n]) for n in mapped_in})
        elif isinstance(direct_feedthrough, (bool, np.bool_)):
            feedthrough = bool(direct_feedthrough)
        else:
            raise ModelError(f"{what}: direct_feedthrough must be True, False or None, got {direct_feedthrough!r}")
        if instance_name is None:
            instance_name = identifier
        if not isinstance(instance_name, str) or not instance_name.strip() or "\0" in instance_name:
            raise ModelError(f"{what}: instance_name must be a non-empty str without NUL characters, "
                             f"got {instance_name!r}")

        # last: touch the file system (every earlier error leaves nothing behind)
        if fmu_path.is_dir():
            unzip_dir = fmu_path.resolve()
            check_library(unzip_dir, identifier, major, what, interface)
        else:
            unzip_dir = extract_fmu(fmu_path, what)
            try:
                check_library(unzip_dir, identifier, major, what, interface)
            except BaseException:
                shutil.rmtree(unzip_dir, ignore_errors=True)
                raise
            weakref.finalize(self, shutil.rmtree, str(unzip_dir), True)

        attrs = dict(
            path=fmu_path.resolve(),
            model_description=description,
            model_identifier=identifier,
            fmi_version=major,
            instance_name=instance_name,
            inputs=tuple(mapped_in.values()),
            outputs=tuple(mapped_out.values()),
            input_variables=tuple(mapped_in),
            output_variables=tuple(mapped_out),
            parameters=MappingProxyType({name: value for name, (_, value) in settings.items()}),
            sample_time=h,
            direct_feedthrough=feedthrough,
            interface=interface,
            solver_step=step,
            can_snapshot=interface == "co-simulation" and bool(kind.canGetAndSetFMUstate),
            variable_step=bool(getattr(kind, "canHandleVariableCommunicationStepSize", True)),
            description_text=what,
            unzip_dir=unzip_dir,
            settings=tuple(settings.values()),
            discrete_inputs=any(variables[n].variability == "discrete"
                                or variable_type(variables[n], major).kind != "float" for n in mapped_in),
            input_groups=_group_by_type([variables[n] for n in mapped_in], major, description),
            output_groups=_group_by_type([variables[n] for n in mapped_out], major, description),
        )
        for key, value in attrs.items():
            object.__setattr__(self, key, value)

    # -- construction helpers
    @staticmethod
    def _map(argument: str, mapping: Mapping[str, str], variables: dict, causality: str,
             major: int, what: str) -> dict[str, str]:
        if not isinstance(mapping, Mapping):
            raise ModelError(f"{what}: {argument} must be a mapping of FMU variable name -> ctmm signal name, "
                             f"got {mapping!r}")
        result: dict[str, str] = {}
        for var_name, signal in mapping.items():
            mapped_variable(var_name, variables, causality, major, what)
            if not isinstance(signal, str) or not signal.strip():
                raise ModelError(f"{what}: {argument}[{var_name!r}] must be a non-empty ctmm signal name, "
                                 f"got {signal!r}")
            result[var_name] = signal
        return result

    @staticmethod
    def _interface(interface: str | None, description: Any, what: str) -> tuple[str, Any]:
        available = {"co-simulation": description.coSimulation, "model exchange": description.modelExchange}
        provided = [name for name, kind in available.items() if kind is not None]
        if interface is None:
            if not provided:
                other = " (it provides scheduled execution only)" if getattr(description, "scheduledExecution", None) \
                    else ""
                raise ModelError(f"{what} provides neither co-simulation nor model exchange{other}; FMUController "
                                 "supports those two (scheduled execution is not supported)")
            interface = provided[0]
        if interface not in _INTERFACES:
            raise ModelError(f"{what}: interface must be one of {_INTERFACES} or None, got {interface!r}")
        if available[interface] is None:
            raise ModelError(f"{what} does not provide the {interface} interface; it provides: "
                             f"{', '.join(provided) or '(none)'}")
        return interface, available[interface]

    @staticmethod
    def _solver_step(solver_step: float | None, h: float, description: Any, interface: str, what: str) -> float | None:
        if interface == "co-simulation":
            if solver_step is not None:
                raise ModelError(f"{what}: solver_step applies to model-exchange FMUs only (this FMU runs as "
                                 f"co-simulation with its own solver), got {solver_step!r}")
            return None
        if solver_step is None:
            experiment = description.defaultExperiment
            default = getattr(experiment, "stepSize", None) if experiment is not None else None
            return min(h, float(default)) if default else h
        step = _checked(validation.positive, "solver_step", solver_step, what)
        if h / step > MAX_SOLVER_STEPS_PER_SAMPLE:
            raise ModelError(f"{what}: solver_step={solver_step!r} s gives {h / step:.3g} RK4 steps per sample_time "
                             f"{h!r} s; at most {MAX_SOLVER_STEPS_PER_SAMPLE:.0e} are allowed (check the unit)")
        return step

    @staticmethod
    def _sample_time(sample_time: float | None, description: Any, interface: str, what: str) -> float:
        if sample_time is None:
            experiment = description.defaultExperiment
            step = getattr(experiment, "stepSize", None) if experiment is not None else None
            if step is None:
                raise ModelError(f"{what}: sample_time is required (the FMU declares no DefaultExperiment "
                                 "stepSize); allowed: a communication step > 0 [s]")
            sample_time = float(step)
        h = _checked(validation.positive, "sample_time", sample_time, what)
        fixed = getattr(description.coSimulation, "fixedInternalStepSize", None)
        if fixed and interface == "co-simulation":
            ratio = h / float(fixed)
            if abs(ratio - round(ratio)) > 1e-9 * max(1.0, ratio) or round(ratio) < 1:
                warnings.warn(f"{what}: sample_time = {h!r} s is not a whole multiple of the FMU's "
                              f"fixedInternalStepSize {float(fixed)!r} s; its outputs change only on its own "
                              f"grid, so they may lag by up to one internal step (use k * {float(fixed)!r} s, "
                              "k >= 1, to avoid this)", UserWarning, stacklevel=3)
        return h

    def __setattr__(self, key: str, value: object) -> None:
        raise AttributeError(f"FMUController is immutable; cannot set {key!r}")

    def __repr__(self) -> str:
        ins = ", ".join(f"{k}<-{v}" for k, v in zip(self.input_variables, self.inputs))
        outs = ", ".join(f"{k}->{v}" for k, v in zip(self.output_variables, self.outputs))
        return (f"FMUController({self.model_identifier!r}, FMI {self.fmi_version}, inputs=[{ins}], "
                f"outputs=[{outs}], sample_time={self.sample_time!r})")

    def make_channels(self, which: str) -> list[ValueChannel]:
        """Fresh typed value buffers for the mapped ``"inputs"`` or ``"outputs"`` (one per FMI type)."""
        groups = self.input_groups if which == "inputs" else self.output_groups
        return [ValueChannel(*group) for group in groups]

    # -- protocol
    def init(self, t0: float = 0.0) -> FMUControllerState:
        """Instantiate and initialize the FMU at time ``t0`` [s]; return its state.

        The parameters and start values are set after instantiation, then the FMU is initialized
        (FMI 2: ``setupExperiment``, enter/exit initialization mode; FMI 3: enter/exit
        initialization mode with start time ``t0``).  Every failure frees the instance and
        unloads the library before raising.

        Raises
        ------
        ModelError
            The shared library cannot be loaded, instantiation fails (e.g. wrong GUID or
            instantiation token, or an FMU that can be instantiated only once per process) or the
            FMU rejects a parameter or its initialization; the message includes the FMU's log.
        """
        t0 = _checked(validation.finite, "t0", t0, self.description_text)
        what = self.description_text
        log: collections.deque = collections.deque(maxlen=50)
        slave_class = instance_class(self.fmi_version, self.interface)
        token = self.model_description.guid  # FMI 3: fmpy stores the instantiationToken here
        slave = construct_instance(slave_class, what, guid=token, unzipDirectory=str(self.unzip_dir),
                                   modelIdentifier=self.model_identifier, instanceName=self.instance_name)
        try:
            if self.fmi_version == 2:
                callbacks = fmi2_callbacks(log)
                slave.instantiate(callbacks=callbacks)
            else:
                def log_message(env, status, category, message):  # noqa: ANN001 - ctypes callback
                    log.append(decode(message))
                callbacks = log_message
                slave.instantiate(logMessage=log_message)
        except Exception as exc:  # noqa: BLE001
            slave.component = None
            slave.freeLibrary()
            kind = self.model_description.coSimulation if self.interface == "co-simulation" \
                else self.model_description.modelExchange
            once = (" (the FMU declares canBeInstantiatedOnlyOncePerProcess: close the other state first)"
                    if kind.canBeInstantiatedOnlyOncePerProcess else "")
            raise ModelError(f"{what}: fmi{self.fmi_version}Instantiate failed ({exc}){once}; "
                             f"FMU log: {' | '.join(log) or '(empty)'}") from exc
        state = FMUControllerState(self, slave, callbacks, log, t0)
        stage = "setting parameters"
        try:
            if self.fmi_version == 2:
                stage = "fmi2SetupExperiment"
                slave.setupExperiment(startTime=t0)
                self._set_start_values(slave)
                stage = "fmi2EnterInitializationMode"
                slave.enterInitializationMode()
                state.lifecycle["initialized"] = True
                stage = "fmi2ExitInitializationMode"
                slave.exitInitializationMode()
            else:
                self._set_start_values(slave)
                stage = "fmi3EnterInitializationMode"
                slave.enterInitializationMode(startTime=t0)
                state.lifecycle["initialized"] = True
                stage = "fmi3ExitInitializationMode"
                slave.exitInitializationMode()
            if self.interface == "model exchange":
                stage = "the event iteration after initialization"
                description = self.model_description
                state.integrator = ModelExchangeIntegrator(slave, self.fmi_version,
                                                           description.numberOfContinuousStates,
                                                           description.numberOfEventIndicators, self.solver_step)
                state.integrator.start()
        except Exception as exc:  # noqa: BLE001
            state.close()
            detail = str(exc.args[0]) if isinstance(exc, _SettingError) else f"{stage} failed ({status_text(exc)})"
            raise ModelError(f"{what}: {detail}; FMU log: {' | '.join(log) or '(empty)'}") from exc
        return state

    def _set_start_values(self, slave: Any) -> None:
        for variable, value in self.settings:
            kind = variable_type(variable, self.fmi_version)
            function = "setString" if variable.type == "String" else "set" + kind.function
            try:
                getattr(slave, function)([variable.valueReference], [value])
            except Exception as exc:  # noqa: BLE001
                raise _SettingError(f"setting {variable.name!r} = {value!r} failed ({status_text(exc)}); the "
                                    f"FMU refused the value") from exc

    def step(self, t: float, y: np.ndarray, state: FMUControllerState) -> ControllerStep:
        """Set the inputs ``y`` at ``t`` [s], read the outputs, advance the FMU to ``t + h``.

        ``t`` must be the state's next communication point ``state.time`` (the FMU's own grid
        ``t0 + k h`` is used for ``doStep`` so that no rounding accumulates).

        Returns
        -------
        ControllerStep
            Outputs ordered like :attr:`outputs` (valid on ``[t, t + h)``) as float64, and the
            same state object, advanced in place.

        Raises
        ------
        SimulationError
            The state is closed or failed before, ``t`` is off the sample grid, ``y`` has the
            wrong length or a value that cannot be converted to its input's type, or an FMI call
            (set, get, doStep) returns Discard, Error or Fatal; the message names the FMU, the
            call, the time and the status, ``error.time`` is the communication point.
        """
        h = self.sample_time
        what = self.description_text
        if not isinstance(state, FMUControllerState) or state.controller is not self:
            raise ModelError(f"{what}: state must be the FMUControllerState returned by this controller's init(), "
                             f"got {type(state).__name__}")
        t_fmu = state.time
        if state.closed:
            raise SimulationError(f"{what}: step on a closed state", time=t)
        if state.failed_at is not None:
            raise SimulationError(f"{what} failed at t = {state.failed_at!r}; restore a snapshot or init a new "
                                  "state", time=t)
        if abs(t - t_fmu) > 1e-6 * h:
            raise SimulationError(f"{what}: step called at t = {t!r}, but the next communication point is "
                                  f"{t_fmu!r} (sample_time {h!r})", time=t)
        try:
            values = np.asarray(y, dtype=float)
        except (TypeError, ValueError) as exc:
            raise SimulationError(f"{what}: y must be {len(self.inputs)} real numbers ordered like {self.inputs}, "
                                  f"got {y!r}", time=t) from exc
        if values.shape != (len(self.inputs),):
            raise SimulationError(f"{what}: y must have shape ({len(self.inputs)},) ordered like {self.inputs}, "
                                  f"got shape {values.shape}", time=t)
        for channel in state.input_channels:
            channel.load(values, t_fmu, what)
        slave = state.slave
        component = slave.component
        fmi3 = self.fmi_version == 3
        function = f"fmi{self.fmi_version}Set"
        sample_event = state.integrator is not None and self.discrete_inputs
        try:
            if sample_event:  # model exchange: discrete inputs may change only in event mode
                function = f"fmi{self.fmi_version}EnterEventMode"
                slave.enterEventMode()
            for channel, setter in zip(state.input_channels, state.setters):
                function = f"fmi{self.fmi_version}Set{channel.kind.function}"
                exchange(setter, component, channel, fmi3)
            if sample_event:
                function = "the event iteration after setting discrete inputs"
                state.integrator.settle()
            for channel, getter in zip(state.output_channels, state.getters):
                function = f"fmi{self.fmi_version}Get{channel.kind.function}"
                exchange(getter, component, channel, fmi3)
                state.outputs[channel.positions] = channel.read()
            if state.integrator is not None:
                function = "model-exchange integration (RK4)"
                state.integrator.advance(t_fmu, h)
            elif fmi3:
                function = "fmi3DoStep"
                slave.fmi3DoStep(component, t_fmu, h, not self.can_snapshot, *state.step_flag_pointers)
                if state.step_flags[1].value:
                    raise _StepRefused("the FMU requested termination (terminateSimulation = true)")
                if state.step_flags[2].value:
                    raise _StepRefused(f"the FMU returned early at t = {state.step_flags[3].value!r} "
                                       "(earlyReturn = true)")
            else:
                function = "fmi2DoStep"
                slave.fmi2DoStep(component, t_fmu, h, 0 if self.can_snapshot else 1)
        except Exception as exc:  # noqa: BLE001 - fmpy raises FMICallException
            state.failed_at = t_fmu
            detail = status_text(exc)
            called = getattr(exc, "function", None)
            if called and called != function:
                detail = f"{called} returned {detail}"
            raise SimulationError(f"{what}: {function} failed at t = {t_fmu!r} ({detail}); "
                                  f"FMU log: {' | '.join(state.log) or '(empty)'}", time=t_fmu) from exc
        state.steps += 1
        state.time = state.start_time + state.steps * h
        return ControllerStep(state.outputs.copy(), state)

    # -- optional capabilities
    def snapshot(self, state: FMUControllerState) -> FMUSnapshot:
        """Save the FMU state (``get FMU state``) together with the controller time.

        Raises
        ------
        ModelError
            The FMU does not declare ``canGetAndSetFMUstate``.
        SimulationError
            The state is closed or the FMI call fails.
        """
        self._require_snapshots()
        self._require_open(state)
        try:
            handle = state.slave.getFMUstate() if self.fmi_version == 2 else state.slave.getFMUState()
        except Exception as exc:  # noqa: BLE001
            raise SimulationError(f"{self.description_text}: saving the FMU state failed ({exc})",
                                  time=state.time) from exc
        snap = FMUSnapshot(handle, state.time, state.steps, state)
        state.snapshots.add(snap)
        return snap

    def restore(self, state: FMUControllerState, snapshot: FMUSnapshot) -> FMUControllerState:
        """Return ``state`` rewound to ``snapshot`` (``set FMU state``); the snapshot stays valid."""
        self._require_snapshots()
        self._require_open(state)
        if not isinstance(snapshot, FMUSnapshot) or snapshot.owner() is not state:
            raise ModelError(f"{self.description_text}: snapshot must be an FMUSnapshot taken from this state with "
                             f"FMUController.snapshot, got {snapshot!r}")
        if not snapshot.handle:
            raise ModelError(f"{self.description_text}: the snapshot taken at t = {snapshot.time!r} has been "
                             "released; allowed: a snapshot not yet released")
        try:
            if self.fmi_version == 2:
                state.slave.setFMUstate(snapshot.handle)
            else:
                state.slave.setFMUState(snapshot.handle)
        except Exception as exc:  # noqa: BLE001
            raise SimulationError(f"{self.description_text}: restoring the FMU state failed ({exc})",
                                  time=state.time) from exc
        state.time, state.steps, state.failed_at = snapshot.time, snapshot.steps, None
        return state

    def release(self, state: FMUControllerState, snapshot: FMUSnapshot) -> None:
        """Free a snapshot's memory in the FMU (done automatically by :meth:`close`)."""
        if snapshot.handle and not state.closed:
            if self.fmi_version == 2:
                state.slave.freeFMUstate(snapshot.handle)
            else:
                state.slave.freeFMUState(snapshot.handle)
        snapshot.handle = None
        state.snapshots.discard(snapshot)

    def close(self, state: FMUControllerState) -> None:
        """Release the snapshots, terminate and free the FMU instance (idempotent)."""
        if state.closed:
            return
        for snap in list(state.snapshots):
            try:
                self.release(state, snap)
            except Exception:  # noqa: BLE001 - freeing must not stop the cleanup
                snap.handle = None
        state.closed = True
        state.finalizer()

    # -- helpers
    def _require_snapshots(self) -> None:
        if self.interface == "model exchange":
            raise ModelError(f"{self.description_text}: snapshots are offered for co-simulation FMUs only (the "
                             "model-exchange integrator's event bookkeeping is not part of the FMU state)")
        if not self.can_snapshot:
            raise ModelError(f"{self.description_text} does not support saving its state "
                             "(canGetAndSetFMUstate is not true in its modelDescription.xml)")

    def _require_open(self, state: FMUControllerState) -> None:
        if not isinstance(state, FMUControllerState) or state.controller is not self:
            raise ModelError(f"{self.description_text}: state must be the FMUControllerState returned by this "
                             f"controller's init(), got {type(state).__name__}")
        if state.closed:
            raise SimulationError(f"{self.description_text}: the state is closed", time=state.time)


class _SettingError(Exception):
    """An FMU refused a parameter or start value (message already complete)."""


class _StepRefused(Exception):
    """fmi3DoStep returned OK but asked to stop or returned early."""


def _checked(check: Any, name: str, value: Any, what: str) -> float:
    """Run a :mod:`ctmm.validation` check; its error message is prefixed with the FMU's name."""
    try:
        return check(name, value)
    except ModelError as exc:
        raise ModelError(f"{what}: {exc}") from exc


def _group_by_type(variables: list, major: int, description: Any) -> tuple:
    """Mapped variables grouped by FMI type: (type, value references, positions, names, unit scalings) per type."""
    groups: dict[str, list] = {}
    for position, variable in enumerate(variables):
        groups.setdefault(variable.type, []).append((position, variable))
    return tuple((variable_type(members[0][1], major), tuple(v.valueReference for _, v in members),
                  tuple(p for p, _ in members), tuple(v.name for _, v in members),
                  tuple(si_scaling(v, description) for _, v in members))
                 for members in groups.values())


def _derive_feedthrough(description, outputs: list, input_ids: set[int]) -> bool:
    """True if a mapped output depends on a mapped input, or if dependencies are not declared."""
    unknowns = {id(u.variable): u for u in description.outputs}
    for variable in outputs:
        unknown = unknowns.get(id(variable))
        if unknown is None or unknown.dependencies is None:
            return True
        if any(id(dep) in input_ids for dep in unknown.dependencies):
            return True
    return False


