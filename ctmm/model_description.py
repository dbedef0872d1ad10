"""A complete byte description of a model and its options, computed without building anything (issue 13).

The cache key of a generated kernel (:func:`ctmm.generated_loop.compiled_time_loop` with ``description=``) must
determine the generated code.  The generators are deterministic functions of the objects they are given (the model
with its elements, signals and numbers, the options) and of the code that reads them; :func:`describe` writes the
first, :func:`package_digest` the second:

* :func:`describe` walks the whole object graph reachable from a value -- every attribute of every object
  (``__dict__`` in insertion order and ``__slots__``), every item of every container, every array's dtype, shape and
  bytes, every float exactly (``float.hex``), the class (module and qualified name) of every object, and shared or
  cyclic references as back-references (the graph's shape, not only its leaves).  Whatever it cannot describe
  exactly makes it return ``None``, and the caller keys on the built functions instead: a function or method other
  than a module-level function of this package without closure or defaults (a user's ``lambda`` load, a bound
  method), a module, an object or class from outside the package's own files, ``numpy`` and the builtins (a
  python-control transfer function, a user's subclass, a casadi object, ``ctmm.controllers``, which is mapped from
  another folder), an object without ``__dict__`` or ``__slots__`` state.
* :func:`package_digest` is the SHA-256 of the text of every module of the installed ``ctmm`` package, so a change
  of any code that may read the model (element forms, sweeps, generators) gives a new key.

Equal descriptions mean equal generated code; different descriptions may still give the same code (a rebuilt, equal
library: a cache miss, never a wrong hit).
"""
from __future__ import annotations

import enum
import hashlib
import sys
import types
from pathlib import Path
from typing import Any

import numpy as np

__all__ = ["PACKAGE_DIGEST", "describe", "package_digest"]

_PACKAGE = Path(__file__).resolve().parent
_ATOMS = (type(None), bool, int, str, bytes)
_FUNCTIONS = (types.FunctionType, types.BuiltinFunctionType, types.MethodType, types.ModuleType,
              types.CodeType, types.FrameType, types.GeneratorType)


class _Graph:
    """The walk of one description: objects met so far (``id -> index``) and module verdicts (:func:`_in_package`)."""

    def __init__(self, verdicts: dict[str, bool], numbers: bool = True) -> None:
        self.seen: dict[int, int] = {}
        self.alive: list = []              # every object met stays alive, so no id is reused during the walk
        self.verdicts = verdicts
        self.numbers = numbers             # False: floats by their zero pattern only (describe(numbers=False))


class _NotDescribable(Exception):
    """Raised inside :func:`describe` at the first value it cannot describe exactly."""


def describe(value: Any, *, numbers: bool = True) -> bytes | None:
    """The complete description of ``value`` (module docstring), or ``None`` when some part of it cannot be
    described exactly.

    Parameters
    ----------
    value : object
        A model, options, a tuple of both...
    numbers : bool
        ``False``: every float (and complex, and every entry of a float or complex array) is written as
        zero or non-zero only -- the structure of ``value`` without its numbers, for a kernel that takes
        the numbers as inputs; the caller must key the constants of its code apart.

    Returns
    -------
    bytes or None
    """
    out: list[bytes] = []
    try:
        _write(value, out, _Graph({}, numbers))
    except (_NotDescribable, RecursionError):
        return None
    return b"".join(out)


def package_digest() -> bytes:
    """SHA-256 (hex, as bytes) of the path (relative) and text of every ``.py`` file of the ``ctmm`` package."""
    digest = hashlib.sha256()
    for path in sorted(_PACKAGE.rglob("*.py")):
        text = path.read_bytes()
        digest.update(str(path.relative_to(_PACKAGE)).encode() + b"\0" + len(text).to_bytes(8, "little") + text)
    return digest.hexdigest().encode()


def _in_package(module_name: str, verdicts: dict[str, bool]) -> bool:
    """True for a module loaded from a file of this package (its text is in :func:`package_digest`; not, e.g., the
    ``ctmm.controllers`` folder mapped from outside it); ``verdicts`` caches the answers of one description."""
    if module_name not in verdicts:
        path = getattr(sys.modules.get(module_name), "__file__", None)
        verdicts[module_name] = module_name.split(".")[0] == "ctmm" and path is not None and \
            Path(path).resolve().is_relative_to(_PACKAGE)
    return verdicts[module_name]


def _known(kind: type, verdicts: dict[str, bool]) -> bool:
    """A class whose behaviour the key covers: defined in this package (its code is in :func:`package_digest`),
    numpy or the builtins (versions: the caller's key)."""
    module = getattr(kind, "__module__", "") or ""
    return module == "builtins" or module.split(".")[0] == "numpy" or _in_package(module, verdicts)


def _class_name(kind: type, verdicts: dict[str, bool]) -> bytes:
    if not _known(kind, verdicts):
        raise _NotDescribable(kind)
    return f"{kind.__module__}.{kind.__qualname__}".encode()


def _write(value: Any, out: list[bytes], graph: "_Graph") -> None:
    kind = type(value)
    if kind in _ATOMS:
        out.append(b"a" + kind.__name__.encode() + b":" + repr(value).encode() + b";")
        return
    if kind in (float, complex) and not graph.numbers:
        out.append(b"z;" if value == 0 else b"x;")
        return
    if kind is float:
        out.append(b"f" + value.hex().encode() + b";")
        return
    if kind is complex:
        out.append(b"c" + value.real.hex().encode() + b"," + value.imag.hex().encode() + b";")
        return
    if kind in (slice, range):
        out.append(kind.__name__.encode() + b"(")
        for item in (value.start, value.stop, value.step):
            _write(item, out, graph)
        out.append(b")")
        return
    if isinstance(value, np.dtype):
        out.append(b"D" + value.str.encode() + b";")
        return
    if isinstance(value, np.generic) and not graph.numbers and np.issubdtype(value.dtype, np.inexact):
        out.append(b"g" + value.dtype.str.encode() + (b":z;" if value == 0 else b":x;"))
        return
    if isinstance(value, np.generic):
        out.append(b"g" + value.dtype.str.encode() + b":" + value.tobytes() + b";")
        return
    if id(value) in graph.seen:                       # shared or cyclic: the graph's shape
        out.append(b"r" + str(graph.seen[id(value)]).encode() + b";")
        return
    graph.seen[id(value)] = len(graph.seen)
    graph.alive.append(value)
    if isinstance(value, type):
        out.append(b"t" + _class_name(value, graph.verdicts) + b";")
    elif isinstance(value, np.ndarray):
        if value.dtype.hasobject:
            out.append(b"O" + repr(value.shape).encode() + b"[")
            for item in value.reshape(-1):
                _write(item, out, graph)
            out.append(b"]")
        else:
            data = np.ascontiguousarray(value if graph.numbers or not np.issubdtype(value.dtype, np.inexact)
                                        else np.packbits(value.reshape(-1) != 0)).tobytes()
            out.append(b"n" + value.dtype.str.encode() + repr(value.shape).encode() + len(data).to_bytes(8, "little")
                       + data)
    elif kind in (tuple, list):
        out.append(kind.__name__.encode() + str(len(value)).encode() + b"[")
        for item in value:
            _write(item, out, graph)
        out.append(b"]")
    elif kind is dict:                          # insertion order: generators iterate in it
        out.append(b"d" + str(len(value)).encode() + b"{")
        for key, item in value.items():
            _write(key, out, graph)
            _write(item, out, graph)
        out.append(b"}")
    elif kind in (set, frozenset):
        parts = []
        for item in value:
            part: list[bytes] = []
            _write(item, part, _Graph(graph.verdicts, graph.numbers))
            parts.append(b"".join(part))
        out.append(b"s" + str(len(value)).encode() + b"{" + b"".join(sorted(parts)) + b"}")
    elif isinstance(value, _FUNCTIONS):
        _write_function(value, out, graph.verdicts)
    elif isinstance(value, enum.Enum):
        out.append(b"e" + _class_name(kind, graph.verdicts) + b"." + value.name.encode() + b";")
    else:
        _write_object(value, out, graph)


def _write_function(value: Any, out: list[bytes], verdicts: dict[str, bool]) -> None:
    """A module-level function of ctmm without closure: its name (its code is in :func:`package_digest`)."""
    module = getattr(value, "__module__", "") or ""
    name = getattr(value, "__qualname__", "")
    if not isinstance(value, types.FunctionType) or not _in_package(module, verdicts) or "<" in name or \
            value.__closure__ or value.__defaults__ or value.__kwdefaults__:
        raise _NotDescribable(value)
    out.append(b"F" + f"{module}.{name}".encode() + b";")


def _write_object(value: Any, out: list[bytes], graph: "_Graph") -> None:
    """An object of a ctmm (or numpy) class: its class and every attribute (``__dict__``, then ``__slots__``)."""
    kind = type(value)
    out.append(b"o" + _class_name(kind, graph.verdicts) + b"{")
    state = getattr(value, "__dict__", None)
    slots = [name for cls in kind.__mro__ for name in getattr(cls, "__slots__", ()) if name not in ("__dict__",
                                                                                                     "__weakref__")]
    if state is None and not slots:
        raise _NotDescribable(value)
    for name, item in (state or {}).items():
        _write(name, out, graph)
        _write(item, out, graph)
    for name in slots:
        _write(name, out, graph)
        if hasattr(value, name):
            _write(getattr(value, name), out, graph)
        else:
            out.append(b"unset;")
    out.append(b"}")


PACKAGE_DIGEST = package_digest()
""":func:`package_digest` of the code this process imported from (read once, when this module is imported: by the
first generated kernel keyed on a description)."""
