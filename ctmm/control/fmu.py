"""FMU controllers: build an FMI co-simulation FMU from C sources and run it as a ctmm controller.

Two public pieces:

* :func:`build_fmu` compiles a source folder (``modelDescription.xml`` + ``sources/*.c``) with
  the system C compiler against the FMI headers shipped with fmpy, zips the result into
  ``<modelIdentifier>.fmu``, checks it with :func:`fmpy.validation.validate_fmu` and caches it by
  a hash of everything that went into the build.
* :class:`FMUController` adapts an FMI 2.0 or FMI 3.0 co-simulation FMU to the
  :class:`ctmm.control.protocol.Controller` protocol.  The controller object is an immutable
  description; the FMU instance lives in the :class:`FMUControllerState` returned by
  :meth:`FMUController.init`.

Semantics of ``u, state = controller.step(t, y, state)`` (sample time ``h``):

1. the inputs are set to ``y`` (measurements at ``t``),
2. the outputs are read; with direct feedthrough they already depend on ``y(t)``,
3. ``doStep(t, h)`` advances the FMU to ``t + h`` with the inputs held (zero-order hold),
4. ``u`` is returned; the caller holds it on ``[t, t + h)``.

FMI 1.0 FMUs and model-exchange-only FMUs are rejected with a :class:`~ctmm.errors.ModelError`.
"""
from __future__ import annotations

import collections
import ctypes
import os
import shutil
import weakref
from pathlib import Path
from types import MappingProxyType
from typing import Any, Mapping

import numpy as np

from .. import validation
from ..errors import ModelError, SimulationError, unknown_name
from .fmu_build import _REAL_TYPES, _fmi_major, _fmpy, _read_description, build_fmu, fmi_headers_dir  # noqa: F401
from .protocol import ControllerStep

__all__ = ["build_fmu", "fmi_headers_dir", "FMUController", "FMUControllerState", "FMUSnapshot"]


class FMUSnapshot:
    """A saved FMU state (``fmi2GetFMUstate`` / ``fmi3GetFMUState``) and the controller time.

    Created by :meth:`FMUController.snapshot`; valid until released with
    :meth:`FMUController.release` or until the owning state is closed.
    """

    __slots__ = ("handle", "time", "steps", "owner", "__weakref__")

    def __init__(self, handle: ctypes.c_void_p, time: float, steps: int, owner: "FMUControllerState"):
        self.handle = handle
        self.time = time
        self.steps = steps
        self.owner = weakref.ref(owner)

    def __repr__(self) -> str:
        return f"FMUSnapshot(time={self.time!r}, released={not self.handle})"


class FMUControllerState:
    """Running FMU instance of an :class:`FMUController` (mutable; one per simulation).

    Use as a context manager, or call :meth:`close`, to terminate and free the instance; it is
    also freed when the state is garbage-collected.

    Attributes
    ----------
    time : float
        Communication point [s] of the next :meth:`FMUController.step` call.
    steps : int
        Number of completed ``doStep`` calls since :meth:`FMUController.init`.
    log : collections.deque of str
        The FMU's most recent log messages (the last 50).
    closed : bool
        Whether the instance has been freed.
    """

    def __init__(self, controller: "FMUController", slave: Any, callbacks: Any, log: collections.deque,
                 t0: float) -> None:
        self.controller = controller
        self.slave = slave
        self.start_time = t0
        self.time = t0
        self.steps = 0
        self.log = log
        self.closed = False
        self.failed_at: float | None = None
        self._callbacks = callbacks  # keeps the ctypes callbacks alive while the FMU may call them
        self._snapshots: set[FMUSnapshot] = set()  # freed by release() or close()
        n_in, n_out = len(controller.inputs), len(controller.outputs)
        real = ctypes.c_double
        self._vr_in = (ctypes.c_uint32 * n_in)(*controller._vr_in)
        self._vr_out = (ctypes.c_uint32 * n_out)(*controller._vr_out)
        self._in = (real * max(n_in, 1))()
        self._out = (real * n_out)()
        self._in_view = np.ctypeslib.as_array(self._in)[:n_in]
        self._out_view = np.ctypeslib.as_array(self._out)
        flags = [ctypes.c_bool() for _ in range(3)] + [ctypes.c_double()]  # FMI 3 doStep results
        self._flags = flags
        self._flag_pointers = [ctypes.pointer(flag) for flag in flags]
        self._finalizer = weakref.finalize(self, _free_instance, slave)

    def close(self) -> None:
        """Terminate and free the FMU instance (idempotent)."""
        self.controller.close(self)

    def __enter__(self) -> "FMUControllerState":
        return self

    def __exit__(self, *exc_info: object) -> None:
        self.close()

    def __repr__(self) -> str:
        status = "closed" if self.closed else f"t={self.time!r}, steps={self.steps}"
        return f"FMUControllerState({self.controller.model_identifier!r}, {status})"


def _free_instance(slave: Any) -> None:
    try:
        slave.terminate()
    except Exception:  # noqa: BLE001 - a failed FMU may refuse terminate; free it anyway
        pass
    try:
        slave.freeInstance()
    except Exception:  # noqa: BLE001
        pass


class FMUController:
    """An FMI 2.0 / 3.0 co-simulation FMU used as a sampled ctmm controller.

    Parameters
    ----------
    path : path
        The ``.fmu`` file (or a folder holding an extracted FMU).
    inputs : mapping of str to str
        FMU input variable name -> ctmm signal it reads, e.g. ``{"y": "m6.x", "ydot": "m6.v"}``.
    outputs : mapping of str to str
        FMU output variable name -> ctmm signal it writes, e.g. ``{"u": "m2.force"}``.
    parameters : mapping of str to float, optional
        Values for FMU parameters (causality ``parameter``), set before initialization.
    sample_time : float
        Communication step size ``h`` [s], > 0; the outputs are held on ``[t, t + h)``.
    direct_feedthrough : bool, optional
        Whether the outputs depend on the inputs at the same instant.  Default: derived from
        ``ModelStructure/Outputs`` (true if a mapped output depends on a mapped input, or if the
        FMU declares no dependencies).

    Raises
    ------
    ModelError
        Missing file, not a co-simulation FMU, FMI version not 2.0/3.0, no binary for this
        platform, an unknown variable name (the message lists the available ones), a variable of
        the wrong causality or type, a non-finite parameter value or a non-positive sample time.

    Examples
    --------
    >>> pd = FMUController(build_fmu("controllers/fmu/pd_controller"),
    ...                    inputs={"y": "m6.x", "ydot": "m6.v"}, outputs={"u": "m2.force"},
    ...                    parameters={"kp": 40.0, "kd": 4.0}, sample_time=1e-3)  # doctest: +SKIP
    >>> with pd.init(0.0) as state:                                                # doctest: +SKIP
    ...     u, state = pd.step(0.0, np.array([0.01, 0.0]), state)
    """

    def __init__(self, path: str | os.PathLike, *, inputs: Mapping[str, str], outputs: Mapping[str, str],
                 parameters: Mapping[str, float] | None = None, sample_time: float,
                 direct_feedthrough: bool | None = None) -> None:
        fmpy = _fmpy()
        fmu_path = validation.path("path", path)
        if not fmu_path.exists():
            raise ModelError(f"FMU file not found: {str(fmu_path)!r}")
        what = f"FMU {str(fmu_path)!r}"
        description = _read_description(fmu_path, what)
        major = _fmi_major(description.fmiVersion, what)
        if description.coSimulation is None:
            kinds = [k for k, v in (("model exchange", description.modelExchange),
                                    ("scheduled execution", getattr(description, "scheduledExecution", None)))
                     if v is not None]
            raise ModelError(f"{what} is not a co-simulation FMU (it provides {', '.join(kinds) or 'no interface'}); "
                             "FMUController needs <CoSimulation> because it calls doStep at the sample time")
        identifier = description.coSimulation.modelIdentifier
        if fmu_path.is_file():
            platforms = fmpy.supported_platforms(str(fmu_path))  # FMI 3 tuples reported as FMI 2 names
            if fmpy.platform not in platforms:
                hint = " (it ships C sources: compile them with build_fmu)" if "c-code" in platforms else ""
                raise ModelError(f"{what} has no binary for this platform ({fmpy.platform}); it supports: "
                                 f"{', '.join(platforms) or '(none)'}{hint}")

        variables = {v.name: v for v in description.modelVariables}
        self_inputs = self._map("inputs", inputs, variables, "input", major)
        self_outputs = self._map("outputs", outputs, variables, "output", major)
        if not self_outputs:
            raise ModelError("outputs must map at least one FMU output variable to a ctmm signal")
        duplicated = sorted({s for s in self_outputs.values() if list(self_outputs.values()).count(s) > 1})
        if duplicated:
            raise ModelError(f"outputs writes the ctmm signal(s) {', '.join(duplicated)} from more than one "
                             "FMU variable; allowed: each signal written once")
        if parameters is None:
            parameters = {}
        if not isinstance(parameters, Mapping):
            raise ModelError(f"parameters must be a mapping of FMU parameter name -> value, got {parameters!r}")
        param_values: dict[str, float] = {}
        for pname, value in parameters.items():
            variable = self._lookup(pname, variables, "parameter", major)
            if variable.variability not in ("fixed", "tunable"):
                raise ModelError(f"FMU parameter {pname!r} has variability {variable.variability!r}; "
                                 "allowed: 'fixed' or 'tunable'")
            param_values[pname] = validation.finite(f"parameters[{pname!r}]", value)

        if direct_feedthrough is None:
            feedthrough = _derive_feedthrough(description, [variables[n] for n in self_outputs],
                                              {id(variables[n]) for n in self_inputs})
        elif isinstance(direct_feedthrough, (bool, np.bool_)):
            feedthrough = bool(direct_feedthrough)
        else:
            raise ModelError(f"direct_feedthrough must be True, False or None, got {direct_feedthrough!r}")

        if fmu_path.is_dir():
            unzip_dir = fmu_path
        else:
            unzip_dir = Path(fmpy.extract(str(fmu_path)))
            weakref.finalize(self, shutil.rmtree, str(unzip_dir), True)

        attrs = dict(
            path=fmu_path.resolve(),
            model_description=description,
            model_identifier=identifier,
            fmi_version=major,
            inputs=tuple(self_inputs.values()),
            outputs=tuple(self_outputs.values()),
            input_variables=tuple(self_inputs),
            output_variables=tuple(self_outputs),
            parameters=MappingProxyType(param_values),
            sample_time=validation.positive("sample_time", sample_time),
            direct_feedthrough=feedthrough,
            can_snapshot=bool(description.coSimulation.canGetAndSetFMUstate),
            _unzip_dir=unzip_dir,
            _vr_in=tuple(variables[n].valueReference for n in self_inputs),
            _vr_out=tuple(variables[n].valueReference for n in self_outputs),
            _vr_par=tuple(variables[n].valueReference for n in param_values),
        )
        for key, value in attrs.items():
            object.__setattr__(self, key, value)

    # -- construction helpers
    @staticmethod
    def _lookup(var_name: str, variables: dict, causality: str, major: int):
        if not isinstance(var_name, str):
            raise ModelError(f"FMU variable names must be strings, got {var_name!r}")
        variable = variables.get(var_name)
        if variable is None:
            known = [v.name for v in variables.values() if v.causality == causality]
            raise unknown_name(f"FMU {causality} variable", var_name, known)
        if variable.causality != causality:
            raise ModelError(f"FMU variable {var_name!r} has causality {variable.causality!r}; "
                             f"allowed here: {causality!r}")
        if variable.type != _REAL_TYPES[major]:
            raise ModelError(f"FMU variable {var_name!r} has type {variable.type!r}; allowed: "
                             f"{_REAL_TYPES[major]!r} (ctmm signals are real numbers)")
        return variable

    @classmethod
    def _map(cls, argument: str, mapping: Mapping[str, str], variables: dict, causality: str,
             major: int) -> dict[str, str]:
        if not isinstance(mapping, Mapping):
            raise ModelError(f"{argument} must be a mapping of FMU variable name -> ctmm signal name, "
                             f"got {mapping!r}")
        result: dict[str, str] = {}
        for var_name, signal in mapping.items():
            cls._lookup(var_name, variables, causality, major)
            if not isinstance(signal, str) or not signal.strip():
                raise ModelError(f"{argument}[{var_name!r}] must be a non-empty ctmm signal name, got {signal!r}")
            result[var_name] = signal
        return result

    def __setattr__(self, key: str, value: object) -> None:
        raise AttributeError(f"FMUController is immutable; cannot set {key!r}")

    def __repr__(self) -> str:
        ins = ", ".join(f"{k}<-{v}" for k, v in zip(self.input_variables, self.inputs))
        outs = ", ".join(f"{k}->{v}" for k, v in zip(self.output_variables, self.outputs))
        return (f"FMUController({self.model_identifier!r}, FMI {self.fmi_version}, inputs=[{ins}], "
                f"outputs=[{outs}], sample_time={self.sample_time!r})")

    # -- protocol
    def init(self, t0: float = 0.0) -> FMUControllerState:
        """Instantiate and initialize the FMU at time ``t0`` [s]; return its state.

        The parameters are set after instantiation, then the FMU is initialized (FMI 2:
        ``setupExperiment``, enter/exit initialization mode; FMI 3: enter/exit initialization
        mode with start time ``t0``).

        Raises
        ------
        ModelError
            The shared library cannot be loaded, instantiation fails (e.g. wrong GUID) or the FMU
            rejects a parameter or its initialization.
        """
        t0 = validation.finite("t0", t0)
        log: collections.deque = collections.deque(maxlen=50)
        instance_name = f"{self.model_identifier}_{id(log):x}"  # unique among live instances
        if self.fmi_version == 2:
            from fmpy.fmi2 import FMU2Slave as slave_class
        else:
            from fmpy.fmi3 import FMU3Slave as slave_class
        try:
            slave = slave_class(guid=self.model_description.guid, unzipDirectory=str(self._unzip_dir),
                                modelIdentifier=self.model_identifier, instanceName=instance_name)
        except Exception as exc:  # noqa: BLE001 - fmpy raises bare Exception / AttributeError here
            raise ModelError(f"cannot load FMU {self.model_identifier!r} from {str(self.path)!r}: {exc}") from exc
        callbacks = None
        try:
            if self.fmi_version == 2:
                callbacks = _fmi2_callbacks(log)
                slave.instantiate(callbacks=callbacks)
            else:
                def log_message(env, status, category, message):  # noqa: ANN001 - ctypes callback
                    log.append(_decode(message))
                callbacks = log_message
                slave.instantiate(logMessage=log_message)
        except Exception as exc:  # noqa: BLE001
            slave.freeLibrary()
            raise ModelError(f"FMU {self.model_identifier!r}: instantiation failed ({exc}); "
                             f"FMU log: {' | '.join(log) or '(empty)'}") from exc
        state = FMUControllerState(self, slave, callbacks, log, t0)
        stage = "setting parameters"
        try:
            if self.fmi_version == 2:
                stage = "fmi2SetupExperiment"
                slave.setupExperiment(startTime=t0)
                stage = "setting parameters"
                if self._vr_par:
                    slave.setReal(list(self._vr_par), list(self.parameters.values()))
                stage = "initialization"
                slave.enterInitializationMode()
                slave.exitInitializationMode()
            else:
                if self._vr_par:
                    slave.setFloat64(list(self._vr_par), list(self.parameters.values()))
                stage = "initialization"
                slave.enterInitializationMode(startTime=t0)
                slave.exitInitializationMode()
        except Exception as exc:  # noqa: BLE001
            state.close()
            raise ModelError(f"FMU {self.model_identifier!r}: {stage} failed ({exc}); "
                             f"FMU log: {' | '.join(log) or '(empty)'}") from exc
        return state

    def step(self, t: float, y: np.ndarray, state: FMUControllerState) -> ControllerStep:
        """Set the inputs ``y`` at ``t`` [s], read the outputs, advance the FMU to ``t + h``.

        ``t`` must be the state's next communication point ``state.time`` (the FMU's own grid
        ``t0 + k h`` is used for ``doStep`` so that no rounding accumulates).

        Returns
        -------
        ControllerStep
            Outputs ordered like :attr:`outputs` (valid on ``[t, t + h)``) and the same state
            object, advanced in place.

        Raises
        ------
        SimulationError
            The state is closed or failed before, ``t`` is off the sample grid, ``y`` has the
            wrong length, or an FMI call (set, get, doStep) fails; ``error.time`` is ``t``.
        """
        h = self.sample_time
        t_fmu = state.time
        if state.closed:
            raise SimulationError(f"FMU {self.model_identifier!r}: step on a closed state", time=t)
        if state.failed_at is not None:
            raise SimulationError(f"FMU {self.model_identifier!r} failed at t = {state.failed_at!r}; restore a "
                                  "snapshot or init a new state", time=t)
        if abs(t - t_fmu) > 1e-6 * h:
            raise SimulationError(f"FMU {self.model_identifier!r}: step called at t = {t!r}, but the next "
                                  f"communication point is {t_fmu!r} (sample_time {h!r})", time=t)
        values = np.asarray(y, dtype=float)
        if values.shape != (len(self.inputs),):
            raise SimulationError(f"FMU {self.model_identifier!r}: y must have shape ({len(self.inputs)},) "
                                  f"ordered like {self.inputs}, got shape {values.shape}", time=t)
        slave = state.slave
        component = slave.component
        n_in, n_out = len(self.inputs), len(self.outputs)
        function = "set inputs"
        try:
            state._in_view[:] = values
            if self.fmi_version == 2:
                if n_in:
                    slave.fmi2SetReal(component, state._vr_in, n_in, state._in)
                function = "fmi2GetReal"
                slave.fmi2GetReal(component, state._vr_out, n_out, state._out)
                function = "fmi2DoStep"
                slave.fmi2DoStep(component, t_fmu, h, 0 if self.can_snapshot else 1)
            else:
                if n_in:
                    slave.fmi3SetFloat64(component, state._vr_in, n_in, state._in, n_in)
                function = "fmi3GetFloat64"
                slave.fmi3GetFloat64(component, state._vr_out, n_out, state._out, n_out)
                function = "fmi3DoStep"
                slave.fmi3DoStep(component, t_fmu, h, not self.can_snapshot, *state._flag_pointers)
                if state._flags[1].value:
                    raise RuntimeError("the FMU requested termination (terminateSimulation)")
        except Exception as exc:  # noqa: BLE001 - fmpy raises FMICallException
            state.failed_at = t_fmu
            raise SimulationError(f"FMU {self.model_identifier!r}: {function} failed at t = {t_fmu!r} ({exc}); "
                                  f"FMU log: {' | '.join(state.log) or '(empty)'}", time=t_fmu) from exc
        state.steps += 1
        state.time = state.start_time + state.steps * h
        return ControllerStep(state._out_view.copy(), state)

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
            raise SimulationError(f"FMU {self.model_identifier!r}: saving the FMU state failed ({exc})",
                                  time=state.time) from exc
        snap = FMUSnapshot(handle, state.time, state.steps, state)
        state._snapshots.add(snap)
        return snap

    def restore(self, state: FMUControllerState, snapshot: FMUSnapshot) -> FMUControllerState:
        """Return ``state`` rewound to ``snapshot`` (``set FMU state``); the snapshot stays valid."""
        self._require_snapshots()
        self._require_open(state)
        if not isinstance(snapshot, FMUSnapshot) or snapshot.owner() is not state:
            raise ModelError("snapshot must be an FMUSnapshot taken from this state with FMUController.snapshot")
        if not snapshot.handle:
            raise ModelError("snapshot has been released")
        try:
            if self.fmi_version == 2:
                state.slave.setFMUstate(snapshot.handle)
            else:
                state.slave.setFMUState(snapshot.handle)
        except Exception as exc:  # noqa: BLE001
            raise SimulationError(f"FMU {self.model_identifier!r}: restoring the FMU state failed ({exc})",
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
        state._snapshots.discard(snapshot)

    def close(self, state: FMUControllerState) -> None:
        """Release the snapshots, terminate and free the FMU instance (idempotent)."""
        if state.closed:
            return
        for snap in list(state._snapshots):
            try:
                self.release(state, snap)
            except Exception:  # noqa: BLE001 - freeing must not stop the cleanup
                snap.handle = None
        state.closed = True
        state._finalizer()

    # -- helpers
    def _require_snapshots(self) -> None:
        if not self.can_snapshot:
            raise ModelError(f"FMU {self.model_identifier!r} does not support saving its state "
                             "(canGetAndSetFMUstate is not true in its modelDescription.xml)")

    def _require_open(self, state: FMUControllerState) -> None:
        if not isinstance(state, FMUControllerState) or state.controller is not self:
            raise ModelError("state must be the FMUControllerState returned by this controller's init()")
        if state.closed:
            raise SimulationError(f"FMU {self.model_identifier!r}: the state is closed", time=state.time)


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


def _decode(message: Any) -> str:
    if isinstance(message, bytes):
        return message.decode("utf-8", "replace")
    return str(message)


def _fmi2_callbacks(log: collections.deque):
    from fmpy import calloc, free
    from fmpy.fmi2 import (fmi2CallbackAllocateMemoryTYPE, fmi2CallbackFreeMemoryTYPE,
                           fmi2CallbackFunctions, fmi2CallbackLoggerTYPE)

    def logger(component, instance_name, status, category, message):  # noqa: ANN001 - ctypes callback
        log.append(_decode(message))

    callbacks = fmi2CallbackFunctions()
    callbacks.logger = fmi2CallbackLoggerTYPE(logger)
    callbacks.allocateMemory = fmi2CallbackAllocateMemoryTYPE(calloc)
    callbacks.freeMemory = fmi2CallbackFreeMemoryTYPE(free)
    try:
        from fmpy.logging import addLoggerProxy
        addLoggerProxy(ctypes.byref(callbacks))
    except Exception:  # noqa: BLE001 - without the proxy the message is unformatted but still logged
        pass
    return callbacks
