"""Low-level FMI call plumbing for :class:`ctmm.control.fmu.FMUController`.

fmpy classes per interface, typed get/set calls on preallocated buffers, status names and the
FMI 2 logging callbacks.
"""
from __future__ import annotations

import collections
import ctypes
import itertools
import weakref
from typing import Any

from .fmu_variables import ValueChannel

__all__ = ["STATUS_NAMES", "status_text", "instance_class", "exchange", "decode", "fmi2_callbacks", "FMI2LogRouter",
           "LOG_ROUTER"]

STATUS_NAMES = ("OK", "Warning", "Discard", "Error", "Fatal", "Pending")
"""FMI status codes 0..5 by name."""


def status_text(exc: BaseException) -> str:
    """``"status Discard"`` etc. for an fmpy ``FMICallException``, else the exception's text."""
    status = getattr(exc, "status", None)
    if isinstance(status, int) and 0 <= status < len(STATUS_NAMES):
        return f"status {STATUS_NAMES[status]}"
    return str(exc)


def instance_class(major: int, interface: str) -> type:
    """The fmpy class for this FMI version and interface."""
    if major == 2:
        from fmpy.fmi2 import FMU2Model, FMU2Slave
        return FMU2Slave if interface == "co-simulation" else FMU2Model
    from fmpy.fmi3 import FMU3Model, FMU3Slave
    return FMU3Slave if interface == "co-simulation" else FMU3Model


def exchange(function: Any, component: Any, channel: ValueChannel, fmi3: bool) -> None:
    """Call an fmiXSet*/fmiXGet* function on a channel's value references and buffer."""
    if fmi3:
        function(component, channel.references, channel.count, channel.buffer, channel.count)
    else:
        function(component, channel.references, channel.count, channel.buffer)


def decode(message: Any) -> str:
    """An FMU log message as text."""
    if isinstance(message, bytes):
        return message.decode("utf-8", "replace")
    return str(message)


class FMI2LogRouter:
    """Routes the FMI 2 log messages formatted by fmpy's logger proxy to the log of their instance.

    fmpy formats the variadic FMI 2 log messages in a native proxy that forwards every message to
    one process-wide logger pointer (the last one given to ``fmpy.logging.addLoggerProxy``); fmpy's
    own default callbacks use that pointer too.  Pointing it at a per-instance Python logger that is
    later freed makes the next FMU that logs through fmpy crash the process.  The router's one
    logger therefore lives as long as the process and dispatches on the callbacks'
    ``componentEnvironment``: a token registered by :func:`fmi2_callbacks` appends to that
    instance's log; any other environment (fmpy's default callbacks, an unregistered or freed
    instance) prints the message like fmpy's default logger.
    """

    def __init__(self) -> None:
        self.logs: weakref.WeakValueDictionary = weakref.WeakValueDictionary()  # token -> callbacks
        self.tokens = itertools.count(1)
        self.native_logger: Any = None  # the ctypes logger, created on first use, never freed
        self.structure: type | None = None  # fmi2CallbackFunctions subclass that keeps its log

    def logger(self) -> Any:
        """The process-lifetime ctypes FMI 2 logger of this router."""
        if self.native_logger is None:
            from fmpy.fmi2 import fmi2CallbackLoggerTYPE
            self.native_logger = fmi2CallbackLoggerTYPE(self.route)
        return self.native_logger

    def callbacks_class(self) -> type:
        """A subclass of fmpy's ``fmi2CallbackFunctions`` whose instances keep a ``log`` attribute."""
        if self.structure is None:
            from fmpy.fmi2 import fmi2CallbackFunctions
            self.structure = type("OwnedFMI2Callbacks", (fmi2CallbackFunctions,), {})
        return self.structure

    def register(self, callbacks: Any) -> int:
        """A fresh environment token whose messages go to ``callbacks.log`` while ``callbacks`` lives."""
        token = next(self.tokens)
        self.logs[token] = callbacks
        return token

    def route(self, environment: Any, instance_name: Any, status: int, category: Any, message: Any) -> None:
        """The ctypes logger: append to the registered log or print; never raises."""
        try:
            owner = self.logs.get(environment) if isinstance(environment, int) else None
            if owner is not None:
                owner.log.append(decode(message))
                return
            label = STATUS_NAMES[status].upper() if 0 <= status < len(STATUS_NAMES) else str(status)
            print(f"[{label}] {decode(message)}")
        except Exception:  # noqa: BLE001 - an exception must not cross the C boundary
            pass


LOG_ROUTER = FMI2LogRouter()
"""The process's one FMI 2 log router (mirrors fmpy's process-wide native logger pointer)."""


def fmi2_callbacks(log: collections.deque) -> Any:
    """FMI 2 callback struct whose logger appends the FMU's messages to ``log``.

    The struct owns its ctypes callbacks and ``log``; it must stay referenced while the FMU
    instance exists (fmpy's ``instantiate`` keeps it as ``slave.callbacks``).  Its logger is the
    process-lifetime :data:`LOG_ROUTER` logger behind fmpy's formatting proxy, so freeing the struct
    never leaves fmpy's global logger pointing at freed memory.
    """
    from fmpy import calloc, free
    from fmpy.fmi2 import fmi2CallbackAllocateMemoryTYPE, fmi2CallbackFreeMemoryTYPE

    callbacks = LOG_ROUTER.callbacks_class()()
    callbacks.log = log
    callbacks.logger = LOG_ROUTER.logger()
    callbacks.allocateMemory = fmi2CallbackAllocateMemoryTYPE(calloc)
    callbacks.freeMemory = fmi2CallbackFreeMemoryTYPE(free)
    callbacks.componentEnvironment = LOG_ROUTER.register(callbacks)
    try:
        from fmpy.logging import addLoggerProxy
        addLoggerProxy(ctypes.byref(callbacks))  # fmpy's global logger := the router (lives forever)
    except Exception:  # noqa: BLE001 - without the proxy the message is unformatted but still logged
        pass
    return callbacks
