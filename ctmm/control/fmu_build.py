"""Building FMI co-simulation FMUs from C sources (used by :mod:`ctmm.control.fmu`).

:func:`build_fmu` compiles a source folder (``modelDescription.xml`` + ``sources/*.c``) with the
system C compiler against the FMI headers shipped with fmpy, zips the result into
``<modelIdentifier>.fmu``, checks it with :func:`fmpy.validation.validate_fmu` and caches it by a
hash of everything that went into the build (sources, headers, compiler and flags).  The small
helpers that read model descriptions are shared with the FMU controller.
"""
from __future__ import annotations

import ctypes
import hashlib
import os
import shutil
import subprocess
import sys
import tempfile
import zipfile
from pathlib import Path

from .. import validation
from ..errors import ModelError

__all__ = ["build_fmu", "fmi_headers_dir"]

_BUILD_FORMAT = b"ctmm.build_fmu/1"
_COMPILE_FLAGS = ("-std=c99", "-O2", "-ffp-contract=off", "-shared", "-fPIC", "-fvisibility=hidden")
_REAL_TYPES = {2: "Real", 3: "Float64"}


def _fmpy():
    try:
        import fmpy
    except ImportError as exc:  # pragma: no cover - fmpy is a dependency of ctmm
        raise ModelError("FMU support needs the 'fmpy' package (pip install fmpy)") from exc
    return fmpy


def fmi_headers_dir() -> Path:
    """Folder holding the FMI 1/2/3 C headers shipped with fmpy (``fmpy/c-code``)."""
    return Path(_fmpy().__file__).resolve().parent / "c-code"


# --------------------------------------------------------------------------------------- build


def _default_cache_dir() -> Path:
    base = os.environ.get("XDG_CACHE_HOME") or os.path.join(os.path.expanduser("~"), ".cache")
    for candidate in (Path(base) / "ctmm" / "fmu",
                      Path(tempfile.gettempdir()) / f"ctmm-fmu-{getattr(os, 'getuid', lambda: 0)()}"):
        try:
            candidate.mkdir(parents=True, exist_ok=True)
        except OSError:
            continue
        if os.access(candidate, os.W_OK):
            return candidate
    raise ModelError("no writable cache directory for FMUs; pass output_dir to build_fmu")


def _peek_fmi_version(path: Path) -> str:
    """The root's fmiVersion attribute, read before any schema validation."""
    from xml.etree import ElementTree

    try:
        if path.is_dir():
            path = path / "modelDescription.xml"
        if path.suffix.lower() == ".xml":
            stream = open(path, "rb")
        else:
            with zipfile.ZipFile(path) as archive:
                stream = archive.open("modelDescription.xml")
        with stream:
            for _, element in ElementTree.iterparse(stream, events=("start",)):
                return str(element.get("fmiVersion", ""))
    except (OSError, KeyError, zipfile.BadZipFile, ElementTree.ParseError) as exc:
        raise ModelError(f"cannot read modelDescription.xml from {str(path)!r}: {exc}") from exc
    return ""


def _read_description(path: Path, what: str):
    fmpy = _fmpy()
    _fmi_major(_peek_fmi_version(path), what)
    try:
        return fmpy.read_model_description(str(path), validate=True)
    except Exception as exc:  # fmpy raises ValidationError, lxml errors, zip errors ...
        problems = getattr(exc, "problems", None)
        detail = "; ".join(problems) if problems else str(exc)
        raise ModelError(f"cannot read the model description of {what}: {detail}") from exc


def _fmi_major(version: str, what: str) -> int:
    major = version.split(".")[0]
    if major not in ("2", "3"):
        raise ModelError(f"{what} declares fmiVersion={version!r}; supported: '2.0' and '3.0' "
                         "(FMI 1.0 has a different C API; re-export the model as FMI 2.0 or 3.0)")
    return int(major)


def _required_functions(major: int) -> list[str]:
    """C functions fmpy loads for a co-simulation FMU of this FMI major version."""
    if major == 2:
        from fmpy.fmi2 import FMU2Slave as slave_class
    else:
        from fmpy.fmi3 import FMU3Slave as slave_class
    prefix = f"fmi{major}"
    return sorted(name for name in dir(slave_class) if name.startswith(prefix))


def build_fmu(source_dir: str | os.PathLike, output_dir: str | os.PathLike | None = None, *,
              compiler: str = "cc") -> Path:
    """Compile an FMU source folder into a co-simulation ``.fmu`` (cached by content hash).

    Parameters
    ----------
    source_dir : path
        Folder with ``modelDescription.xml`` and ``sources/*.c`` (optional ``sources/*.h`` and a
        ``resources/`` folder, which is packed as is).  FMI 2.0 and 3.0 descriptions are accepted.
    output_dir : path, optional
        Where ``<modelIdentifier>.fmu`` is written (with a ``.sha256`` stamp beside it).  Default:
        a per-user cache (``$XDG_CACHE_HOME/ctmm/fmu/<hash>/``, falling back to the temp folder).
    compiler : str, optional
        C compiler command (``"cc"``, ``"gcc"``, ``"clang"`` or a path); called as
        ``compiler -std=c99 -O2 -ffp-contract=off -shared -fPIC -fvisibility=hidden
        -I<fmpy/c-code> -I<source_dir/sources> sources/*.c -lm`` (no fused multiply-add, so
        the arithmetic matches numpy's bit for bit).

    Returns
    -------
    pathlib.Path
        Path of the ``.fmu`` file.  It is rebuilt only when the description, a source, the FMI
        headers, the compiler (path and ``--version``) or the flags changed.

    Raises
    ------
    ModelError
        Missing files, an unsupported FMI version or platform, a compiler error (the message
        contains the compiler's stderr), missing FMI functions in the binary, or problems
        reported by :func:`fmpy.validation.validate_fmu`.

    Examples
    --------
    >>> path = build_fmu("controllers/fmu/pd_controller")          # doctest: +SKIP
    >>> path.name                                                   # doctest: +SKIP
    'pd_controller.fmu'
    """
    fmpy = _fmpy()
    source = validation.path("source_dir", source_dir)
    if not source.is_dir():
        raise ModelError(f"source_dir must be an existing folder, got {str(source)!r}")
    description_file = source / "modelDescription.xml"
    if not description_file.is_file():
        raise ModelError(f"source_dir {str(source)!r} has no modelDescription.xml")
    c_files = sorted((source / "sources").glob("*.c"))
    if not c_files:
        raise ModelError(f"source_dir {str(source)!r} has no C sources in sources/*.c")
    description = _read_description(description_file, str(description_file))
    major = _fmi_major(description.fmiVersion, str(description_file))
    if description.coSimulation is None:
        raise ModelError(f"{description_file} declares no <CoSimulation> interface; build_fmu builds "
                         "co-simulation FMUs only")
    identifier = description.coSimulation.modelIdentifier
    if not sys.platform.startswith(("linux", "darwin")):
        raise ModelError(f"build_fmu supports Linux and macOS C compilers, not platform {sys.platform!r}")
    compiler_path = shutil.which(compiler)
    if compiler_path is None:
        raise ModelError(f"compiler {compiler!r} not found on PATH; pass compiler='gcc' or a full path")
    platform_dir = fmpy.platform if major == 2 else fmpy.platform_tuple
    headers = fmi_headers_dir()

    digest = hashlib.sha256(_BUILD_FORMAT)
    parts: list[tuple[str, bytes]] = [("compiler", compiler_path.encode()),
                                      ("compiler-version", _compiler_version(compiler_path)),
                                      ("flags", " ".join(_COMPILE_FLAGS).encode()),
                                      ("platform", platform_dir.encode())]
    parts += [(f"header/{h.name}", h.read_bytes()) for h in sorted(headers.glob("fmi*.h"))]
    packed = [p for p in sorted(source.rglob("*")) if p.is_file()
              and (p.parts[len(source.parts)] in ("sources", "resources") or p == description_file)]
    parts += [(f"source/{p.relative_to(source).as_posix()}", p.read_bytes()) for p in packed]
    for label, payload in parts:
        digest.update(label.encode() + b"\0" + len(payload).to_bytes(8, "little") + payload)
    key = digest.hexdigest()

    target_dir = Path(output_dir) if output_dir is not None else _default_cache_dir() / key[:20]
    target_dir.mkdir(parents=True, exist_ok=True)
    target = target_dir / f"{identifier}.fmu"
    stamp = target_dir / f"{identifier}.fmu.sha256"
    if target.is_file() and stamp.is_file() and stamp.read_text().strip() == key:
        return target

    with tempfile.TemporaryDirectory(prefix=f".{identifier}-", dir=target_dir) as work:
        work_path = Path(work)
        library = work_path / "binaries" / platform_dir / f"{identifier}{fmpy.sharedLibraryExtension}"
        library.parent.mkdir(parents=True)
        command = [compiler_path, *_COMPILE_FLAGS, f"-I{headers}", f"-I{source / 'sources'}",
                   *map(str, c_files), "-o", str(library), "-lm"]
        try:
            completed = subprocess.run(command, capture_output=True, text=True, timeout=600)
        except (OSError, subprocess.TimeoutExpired) as exc:
            raise ModelError(f"compiling FMU {identifier!r} failed to run {compiler!r}: {exc}") from exc
        if completed.returncode != 0:
            raise ModelError(f"compiling FMU {identifier!r} failed (exit {completed.returncode}):\n"
                             f"$ {' '.join(command)}\n{completed.stderr.strip()}")
        missing = _missing_symbols(library, _required_functions(major))
        if missing:
            raise ModelError(f"FMU {identifier!r}: the compiled library does not export the FMI "
                             f"{major} functions {', '.join(missing)}")
        archive = work_path / f"{identifier}.fmu"
        with zipfile.ZipFile(archive, "w", zipfile.ZIP_DEFLATED) as zf:
            zf.write(description_file, "modelDescription.xml")
            zf.write(library, library.relative_to(work_path).as_posix())
            for path in packed:
                if path != description_file:
                    zf.write(path, path.relative_to(source).as_posix())
        from fmpy.validation import validate_fmu
        problems = validate_fmu(str(archive))
        if problems:
            raise ModelError(f"FMU {identifier!r} built from {str(source)!r} is not valid:\n- "
                             + "\n- ".join(problems))
        os.replace(archive, target)
    stamp.write_text(key + "\n")
    return target


def _compiler_version(compiler_path: str) -> bytes:
    try:
        return subprocess.run([compiler_path, "--version"], capture_output=True, timeout=60).stdout
    except (OSError, subprocess.TimeoutExpired):
        return b""


def _missing_symbols(library: Path, names: list[str]) -> list[str]:
    handle = ctypes.CDLL(str(library))
    try:
        return [name for name in names if not hasattr(handle, name)]
    finally:
        _fmpy().freeLibrary(handle._handle)


# --------------------------------------------------------------------------------------- run


