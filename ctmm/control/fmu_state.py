"""Running FMU instances of :class:`ctmm.control.fmu.FMUController`: state, snapshots, cleanup."""
from __future__ import annotations

import collections
import ctypes
import weakref
from typing import Any, Protocol, Sequence

import numpy as np

from .fmu_model_exchange import ModelExchangeIntegrator

__all__ = ["FMUSnapshot", "FMUControllerState", "FMUInstanceOwner", "free_instance"]


class FMUInstanceOwner(Protocol):
    """What a running instance needs of its controller (:class:`ctmm.control.fmu.FMUController`
    satisfies it; stated here so that this module does not import ``fmu``)."""

    model_identifier: str
    fmi_version: int
    outputs: Sequence[Any]

    def make_channels(self, which: str) -> list: ...

    def close(self, state: "FMUControllerState") -> None: ...


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

    Use as a context manager, or call :meth:`close`, to terminate and free the instance and
    unload its library; this also happens when the state is garbage-collected.

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
    failed_at : float or None
        Communication point [s] of a failed FMI call; further steps are refused.
    integrator : ModelExchangeIntegrator or None
        The RK4 integrator of a model-exchange FMU (its ``events`` counts handled events).
    """

    def __init__(self, controller: FMUInstanceOwner, slave: Any, callbacks: Any, log: collections.deque,
                 t0: float) -> None:
        self.controller = controller
        self.slave = slave
        self.start_time = t0
        self.time = t0
        self.steps = 0
        self.log = log
        self.closed = False
        self.failed_at: float | None = None
        self.integrator: ModelExchangeIntegrator | None = None  # model exchange only
        self.lifecycle = {"initialized": False}  # shared with the finalizer: terminate only if initialized
        self.snapshots: set[FMUSnapshot] = set()  # freed by release() or close()
        self.input_channels = controller.make_channels("inputs")
        self.output_channels = controller.make_channels("outputs")
        major = controller.fmi_version
        self.setters = [getattr(slave, f"fmi{major}Set{c.kind.function}") for c in self.input_channels]
        self.getters = [getattr(slave, f"fmi{major}Get{c.kind.function}") for c in self.output_channels]
        self.outputs = np.zeros(len(controller.outputs))
        flags = [ctypes.c_bool() for _ in range(3)] + [ctypes.c_double()]  # FMI 3 doStep results
        self.step_flags = flags
        self.step_flag_pointers = [ctypes.pointer(flag) for flag in flags]
        # the callbacks stay referenced by the finalizer until the instance is freed
        self.finalizer = weakref.finalize(self, free_instance, slave, self.lifecycle, callbacks)

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


def free_instance(slave: Any, lifecycle: dict, callbacks: Any) -> None:
    """Terminate (if initialized), free the instance and unload the library once; never raises.

    fmpy's ``freeInstance`` unloads the library itself; it is unloaded here only when the
    instance was never created or freeing it failed (each instance holds one ``dlopen``
    reference, so other instances of the same FMU stay loaded).
    """
    library_released = False
    if slave.component:
        if lifecycle.get("initialized"):
            try:
                slave.terminate()
            except Exception:  # noqa: BLE001 - a failed FMU may refuse terminate; free it anyway
                pass
        try:
            slave.freeInstance()  # fmiXFreeInstance, then fmpy's freeLibrary
            library_released = True
        except Exception:  # noqa: BLE001
            pass
        slave.component = None
    if not library_released:
        try:
            slave.freeLibrary()
        except Exception:  # noqa: BLE001
            pass
    lifecycle["initialized"] = False
    del callbacks
