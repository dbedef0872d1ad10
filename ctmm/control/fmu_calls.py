"""Low-level FMI call plumbing for :class:`ctmm.control.fmu.FMUController`.

fmpy classes per interface, typed get/set calls on preallocated buffers, status names and the
FMI 2 logging callbacks.
"""
from __future__ import annotations

import collections
import ctypes
from typing import Any

from .fmu_variables import ValueChannel

__all__ = ["STATUS_NAMES", "status_text", "instance_class", "exchange", "decode", "fmi2_callbacks"]

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


def fmi2_callbacks(log: collections.deque) -> Any:
    """FMI 2 callback struct whose logger appends the FMU's messages to ``log``.

    The returned object must stay referenced while the FMU instance exists.
    """
    from fmpy import calloc, free
    from fmpy.fmi2 import (fmi2CallbackAllocateMemoryTYPE, fmi2CallbackFreeMemoryTYPE,
                           fmi2CallbackFunctions, fmi2CallbackLoggerTYPE)

    def logger(component, instance_name, status, category, message):  # noqa: ANN001 - ctypes callback
        log.append(decode(message))

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
