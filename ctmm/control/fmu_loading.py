"""Loading FMU archives and shared libraries without side effects on the process.

A failed load must leave the process as it was.  This module therefore

* extracts an FMU into a fresh temporary folder that is removed again if anything fails
  (members with absolute paths or ``..`` are refused),
* checks that the platform binary exists, loads (``dlopen``) and exports the FMI functions with a
  plain :class:`ctypes.CDLL` -- no change of working directory -- and unloads it again,
* wraps fmpy's constructors (which change the working directory around ``LoadLibrary``) so that
  the working directory is the same afterwards whatever happens.
"""
from __future__ import annotations

import contextlib
import ctypes
import os
import shutil
import struct
import sys
import tempfile
import zipfile
from pathlib import Path, PurePosixPath
from typing import Any, Iterator

from ..errors import ModelError
from .fmu_description import require_fmpy

__all__ = ["extract_fmu", "library_path", "check_binary_file", "required_functions", "missing_functions", "check_library",
           "working_directory_kept", "construct_instance"]


def extract_fmu(path: Path, what: str) -> Path:
    """Extract the ``.fmu`` archive ``path`` into a new temporary folder and return that folder.

    Raises
    ------
    ModelError
        Corrupt or truncated archive, unsafe member names, or a full disk; the temporary folder is
        removed before the error is raised.
    """
    folder = Path(tempfile.mkdtemp(prefix="ctmm-fmu-"))
    try:
        with zipfile.ZipFile(path) as archive:
            for member in archive.namelist():
                parts = PurePosixPath(member.replace("\\", "/")).parts
                if member.startswith(("/", "\\")) or ".." in parts or (parts and ":" in parts[0]):
                    raise ModelError(f"{what} contains the unsafe member name {member!r}; allowed: "
                                     "relative paths inside the archive")
            archive.extractall(folder)
    except ModelError:
        shutil.rmtree(folder, ignore_errors=True)
        raise
    except (OSError, EOFError, zipfile.BadZipFile, zipfile.LargeZipFile, RuntimeError, ValueError) as exc:
        shutil.rmtree(folder, ignore_errors=True)
        raise ModelError(f"cannot extract {what}: {type(exc).__name__}: {exc}") from exc
    return folder


def library_path(unzip_dir: Path, model_identifier: str, major: int) -> Path:
    """Path of the shared library for this platform inside an extracted FMU."""
    fmpy = require_fmpy()
    platform_dir = fmpy.platform if major == 2 else fmpy.platform_tuple
    return unzip_dir / "binaries" / platform_dir / f"{model_identifier}{fmpy.sharedLibraryExtension}"


def required_functions(major: int, interface: str = "co-simulation") -> list[str]:
    """C functions fmpy loads for an FMU of this FMI major version and interface.

    ``interface`` is ``"co-simulation"`` or ``"model exchange"``.
    """
    if major == 2:
        from fmpy.fmi2 import FMU2Model, FMU2Slave
        classes = {"co-simulation": FMU2Slave, "model exchange": FMU2Model}
    else:
        from fmpy.fmi3 import FMU3Model, FMU3Slave
        classes = {"co-simulation": FMU3Slave, "model exchange": FMU3Model}
    prefix = f"fmi{major}"
    return sorted(name for name in dir(classes[interface]) if name.startswith(prefix))


def check_binary_file(library: Path, what: str, label: str | None = None) -> None:
    """Refuse a truncated or malformed ELF library before ``dlopen`` maps it.

    ``dlopen`` maps the segments listed in the ELF program headers; if the file is shorter than
    they say, touching the missing pages kills the process with SIGBUS.  This checks that the
    header, the program and section header tables and every segment lie inside the file.  Non-ELF files (macOS Mach-O) are left to the loader.

    Raises
    ------
    ModelError
        The file is truncated or its headers are inconsistent (``label`` names it, default: its path).
    """
    label = label or str(library)
    try:
        with open(library, "rb") as stream:
            head = stream.read(64)
            size = os.fstat(stream.fileno()).st_size
            if head[:4] != b"\x7fELF":
                if sys.platform.startswith("linux"):
                    raise ModelError(f"{what}: the shared library {label!r} is not an ELF file "
                                     f"(starts with {head[:4]!r}); allowed: a Linux shared library")
                return
            wide, order = head[4] == 2, "<" if head[5] == 1 else ">"
            layout = "Q" if wide else "I"
            offsets = (0x20, 0x28, 0x36) if wide else (0x1C, 0x20, 0x2A)
            if len(head) < (64 if wide else 52):
                raise ModelError(f"{what}: the shared library {label!r} is truncated ({size} bytes)")
            phoff, = struct.unpack_from(order + layout, head, offsets[0])
            shoff, = struct.unpack_from(order + layout, head, offsets[1])
            phentsize, phnum, shentsize, shnum = struct.unpack_from(order + "HHHH", head, offsets[2])
            problems = []
            if phoff + phnum * phentsize > size:
                problems.append("program header table")
            if shoff and shoff + shnum * shentsize > size:
                problems.append("section header table")
            if not problems:
                stream.seek(phoff)
                table = stream.read(phnum * phentsize)
                for k in range(phnum):
                    entry = table[k * phentsize:(k + 1) * phentsize]
                    if wide:
                        kind, _, offset, _, _, filesz = struct.unpack_from(order + "IIQQQQ", entry)
                    else:
                        kind, offset, _, _, filesz = struct.unpack_from(order + "IIIII", entry)
                    if filesz and offset + filesz > size:  # every segment's bytes must be in the file
                        label_kind = "loadable segment" if kind == 1 else f"segment (type {kind:#x})"
                        problems.append(f"{label_kind} {k} (bytes {offset}..{offset + filesz})")
    except (OSError, struct.error) as exc:
        raise ModelError(f"{what}: cannot read the shared library {label!r}: {exc}") from exc
    if problems:
        raise ModelError(f"{what}: the shared library {label!r} is truncated or corrupt: "
                         f"{', '.join(problems)} extend past the end of the file ({size} bytes)")


def missing_functions(library: Path, names: list[str], what: str, label: str | None = None) -> list[str]:
    """Load ``library`` (no change of working directory), list which of ``names`` it lacks, unload it.

    Raises
    ------
    ModelError
        The library cannot be loaded (truncated file, wrong architecture, missing dependency).
    """
    label = label or str(library)
    check_binary_file(library, what, label)
    try:
        handle = ctypes.CDLL(str(library))
    except OSError as exc:
        reason = str(exc).replace(f"{library}: ", "").replace(str(library), label)
        raise ModelError(f"{what}: cannot load the shared library {label!r}: {reason}") from exc
    try:
        return [name for name in names if not hasattr(handle, name)]
    finally:
        require_fmpy().freeLibrary(handle._handle)


def check_library(unzip_dir: Path, model_identifier: str, major: int, what: str,
                  interface: str = "co-simulation") -> Path:
    """Check that the FMU's binary for this platform exists, loads and exports the FMI functions.

    Returns
    -------
    pathlib.Path
        The library path.

    Raises
    ------
    ModelError
        No binary for this platform (the message lists the platforms present and whether the FMU
        ships C sources for :func:`~ctmm.control.fmu_build.build_fmu`), a library that cannot be
        loaded, or missing FMI functions.
    """
    library = library_path(unzip_dir, model_identifier, major)
    if not library.is_file():
        binaries = unzip_dir / "binaries"
        present = sorted(p.name for p in binaries.iterdir() if p.is_dir() and any(p.iterdir())) \
            if binaries.is_dir() else []
        has_sources = (unzip_dir / "sources").is_dir()
        hint = " It ships C sources: compile them with ctmm.control.fmu.build_fmu(path)." if has_sources else ""
        raise ModelError(f"{what} has no binary for this platform: expected "
                         f"{library.relative_to(unzip_dir).as_posix()}; platforms present: "
                         f"{', '.join(present) or '(none)'}.{hint}")
    label = library.relative_to(unzip_dir).as_posix()
    missing = missing_functions(library, required_functions(major, interface), what, label)
    if missing:
        raise ModelError(f"{what}: the shared library {label} does not export the FMI {major} "
                         f"{interface} functions {', '.join(missing)}")
    return library


@contextlib.contextmanager
def working_directory_kept() -> Iterator[None]:
    """Restore the working directory if the body changed it (fmpy does, around ``LoadLibrary``)."""
    before = os.getcwd()
    try:
        yield
    finally:
        try:
            changed = os.getcwd() != before
        except OSError:  # the current folder was removed
            changed = True
        if changed:
            os.chdir(before)


def construct_instance(instance_class: type, what: str, **kwargs: Any) -> Any:
    """Create an fmpy FMU object (loads the library), keeping the working directory.

    Raises
    ------
    ModelError
        The library cannot be loaded or lacks functions.
    """
    with working_directory_kept():
        try:
            return instance_class(**kwargs)
        except Exception as exc:  # noqa: BLE001 - fmpy raises bare Exception / AttributeError here
            raise ModelError(f"cannot load {what}: {exc}") from exc
