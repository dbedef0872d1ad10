"""Building FMUs from C sources: a source folder, an FMU that ships sources, or its extracted folder.

:func:`build_fmu` compiles the C sources with the system C compiler against the FMI headers shipped
with fmpy, packs the result into ``<modelIdentifier>.fmu``, checks it with
:func:`fmpy.validation.validate_fmu` and caches it by a hash of everything that went into the build
(sources, headers, compiler and flags).

Which sources are compiled: the FMU's own source list when it declares one (FMI 2:
``<SourceFiles>`` of the interface in ``modelDescription.xml``; FMI 3:
``sources/buildDescription.xml``, ``BuildConfiguration`` of the model identifier, with its
``PreprocessorDefinition`` and ``IncludeDirectory`` entries), otherwise every ``sources/*.c``.
"""
from __future__ import annotations

import os
import shutil
import sys
import tempfile
import zipfile
from pathlib import Path
from typing import Any

from ..codegen import cache_directory, cache_key, compiler_identity, find_compiler, run_compiler
from ..errors import ModelError
from .fmu_description import fmi_headers_dir, fmi_major_version, read_description, require_fmpy
from .fmu_loading import extract_fmu, missing_functions, required_functions

__all__ = ["build_fmu", "fmi_headers_dir"]

_BUILD_FORMAT = b"ctmm.build_fmu/1"
_COMPILE_FLAGS = ("-std=c99", "-O2", "-ffp-contract=off", "-shared", "-fPIC", "-fvisibility=hidden")
_LANGUAGE_STANDARDS = {"C89": "-std=gnu89", "C90": "-std=gnu90", "C99": "-std=gnu99", "C11": "-std=gnu11",
                       "C17": "-std=gnu17", "C18": "-std=gnu17"}
_PACKED = ("modelDescription.xml", "model.png", "sources", "resources", "documentation", "extra", "binaries",
           "terminalsAndIcons", "licenses", "icons")


class _Library:
    """One shared library to compile: model identifier, interfaces, sources, flags."""

    def __init__(self, identifier: str, interfaces: list[str], sources: list[Path], flags: list[str]) -> None:
        self.identifier = identifier
        self.interfaces = interfaces
        self.sources = sources
        self.flags = flags


def _libraries(root: Path, description: Any, major: int, what: str) -> list[_Library]:
    """The libraries to compile, with their source files and flags, from the FMU's own build info."""
    interfaces: dict[str, list[str]] = {}
    for label, interface in (("co-simulation", description.coSimulation), ("model exchange", description.modelExchange)):
        if interface is not None:
            interfaces.setdefault(interface.modelIdentifier, []).append(label)
    if not interfaces:
        raise ModelError(f"{what} declares neither <CoSimulation> nor <ModelExchange>; build_fmu builds those")
    source_dir = root / "sources"
    # source-code FMI 3 FMUs prefix their functions with "<modelIdentifier>_"; a binary needs none
    version_flags = ["-DFMI3_OVERRIDE_FUNCTION_PREFIX"] if major == 3 else []
    configurations = {c.modelIdentifier: c for c in (description.buildConfigurations or [])}
    result = []
    for identifier, labels in interfaces.items():
        configuration = configurations.get(identifier)
        if configuration is None and len(configurations) == 1 and len(interfaces) == 1:
            configuration = next(iter(configurations.values()))
        if configuration is None:
            sources = sorted(source_dir.glob("*.c"))
            if not sources:
                raise ModelError(f"{what} has no C sources in sources/*.c and declares no source list "
                                 f"for model identifier {identifier!r}")
            result.append(_Library(identifier, labels, sources, [*_COMPILE_FLAGS, *version_flags]))
            continue
        sources, flags = [], [flag for flag in _COMPILE_FLAGS if not flag.startswith("-std=")]
        standard = "-std=gnu99"
        for file_set in configuration.sourceFileSets:
            language = (file_set.language or "C99").upper()
            if language not in _LANGUAGE_STANDARDS:
                raise ModelError(f"{what}: source file set language {file_set.language!r} is not supported; "
                                 f"allowed: {', '.join(_LANGUAGE_STANDARDS)}")
            standard = _LANGUAGE_STANDARDS[language]
            for name in file_set.sourceFiles:
                path = source_dir / name
                if not path.is_file():
                    raise ModelError(f"{what}: source file {name!r} listed for {identifier!r} is missing "
                                     f"(expected sources/{name})")
                sources.append(path)
            for definition in file_set.preprocessorDefinitions:
                flags.append(f"-D{definition.name}" + (f"={definition.value}" if definition.value is not None else ""))
            for include in file_set.includeDirectories:
                flags.append(f"-I{source_dir / include}")
        if not sources:
            raise ModelError(f"{what}: the build configuration of {identifier!r} lists no source files")
        result.append(_Library(identifier, labels, sources, [standard, *flags, *version_flags]))
    return result


def build_fmu(source_dir: str | os.PathLike, output_dir: str | os.PathLike | None = None, *,
              compiler: str = "cc") -> Path:
    """Compile an FMU's C sources into an ``.fmu`` with a binary for this platform (cached).

    Parameters
    ----------
    source_dir : path
        One of: a folder with ``modelDescription.xml`` and ``sources/`` (optional ``resources/``);
        an ``.fmu`` file that ships C sources (a source-code FMU); or the folder of an extracted
        FMU.  FMI 2.0 and 3.0 are accepted; the FMI headers of the declared version are used.
    output_dir : path, optional
        Where ``<modelIdentifier>.fmu`` is written (with a ``.sha256`` stamp beside it).  Default:
        a per-user cache (``$XDG_CACHE_HOME/ctmm/fmu/<hash>/``, falling back to the temp folder).
    compiler : str, optional
        C compiler command (``"cc"``, ``"gcc"``, ``"clang"`` or a path).  Without a declared
        source list it is called as ``compiler -std=c99 -O2 -ffp-contract=off -shared -fPIC
        -fvisibility=hidden -I<fmpy/c-code> -I<sources> sources/*.c -lm`` (no fused multiply-add,
        so the arithmetic matches numpy's bit for bit); with one, the listed files are compiled
        with the declared preprocessor definitions and include folders and ``-std=gnuXX`` of the
        declared language.

    Returns
    -------
    pathlib.Path
        Path of the ``.fmu`` file.  It holds everything of the input (model description,
        sources, resources, documentation, other platforms' binaries) plus the new binary.  It is
        rebuilt only when an input file, the FMI headers, the compiler (path and ``--version``)
        or the flags changed.

    Raises
    ------
    ModelError
        Missing files (a listed source that does not exist), an unsupported FMI version,
        language or platform, a compiler error (the message contains the compiler's stderr),
        missing FMI functions in the binary, or problems reported by
        :func:`fmpy.validation.validate_fmu`.

    Examples
    --------
    >>> path = build_fmu("controllers/fmu/pd_controller")          # doctest: +SKIP
    >>> path.name                                                   # doctest: +SKIP
    'pd_controller.fmu'
    """
    if not isinstance(source_dir, (str, os.PathLike)) or str(source_dir) == "":
        raise ModelError(f"source_dir must be a folder or an .fmu file, got {source_dir!r}")
    if output_dir is not None and (not isinstance(output_dir, (str, os.PathLike)) or str(output_dir) == ""):
        raise ModelError(f"output_dir must be a folder path or None (the cache), got {output_dir!r}")
    source = Path(source_dir)
    if source.is_file():
        if not zipfile.is_zipfile(source):
            raise ModelError(f"source_dir {str(source)!r} is a file but not an FMU (ZIP) archive; allowed: a "
                             "source folder, an .fmu file that ships C sources, or an extracted FMU folder")
        root = extract_fmu(source, f"FMU {str(source)!r}")
        try:
            return _build(root, source, output_dir, compiler)
        finally:
            shutil.rmtree(root, ignore_errors=True)
    if not source.is_dir():
        raise ModelError(f"source_dir must be an existing folder or .fmu file, got {str(source)!r}")
    return _build(source, source, output_dir, compiler)


def _build(root: Path, source: Path, output_dir: str | os.PathLike | None, compiler: str) -> Path:
    fmpy = require_fmpy()
    description_file = root / "modelDescription.xml"
    if not description_file.is_file():
        raise ModelError(f"source_dir {str(source)!r} has no modelDescription.xml")
    if not (root / "sources").is_dir():
        raise ModelError(f"source_dir {str(source)!r} has no sources/ folder (this FMU does not ship C sources)")
    what = f"{str(source)!r}"
    description = read_description(root, what)
    major = fmi_major_version(description.fmiVersion, what)
    libraries = _libraries(root, description, major, what)
    if not sys.platform.startswith(("linux", "darwin")):
        raise ModelError(f"build_fmu supports Linux and macOS C compilers, not platform {sys.platform!r}")
    if not isinstance(compiler, (str, os.PathLike)) or not str(compiler).strip():
        raise ModelError(f"compiler must be a C compiler command or path such as 'cc' or 'gcc', got {compiler!r}")
    compiler_path = find_compiler(compiler)
    platform_dir = fmpy.platform if major == 2 else fmpy.platform_tuple
    headers = fmi_headers_dir()

    parts: list[tuple[str, bytes]] = [("compiler", compiler_identity(compiler_path)),
                                      ("platform", platform_dir.encode())]
    parts += [(f"flags/{lib.identifier}", " ".join(lib.flags).encode()) for lib in libraries]
    parts += [(f"header/{h.name}", h.read_bytes()) for h in sorted(headers.glob("fmi*.h"))]
    own_binaries = root / "binaries" / platform_dir
    packed = [p for p in sorted(root.rglob("*")) if p.is_file() and p.parts[len(root.parts)] in _PACKED
              and own_binaries not in p.parents]
    parts += [(f"source/{p.relative_to(root).as_posix()}", p.read_bytes()) for p in packed]
    key = cache_key(_BUILD_FORMAT, parts)

    name = libraries[0].identifier
    target_dir = Path(output_dir) if output_dir is not None else cache_directory(subfolder="fmu") / key[:20]
    try:
        target_dir.mkdir(parents=True, exist_ok=True)
    except (OSError, ValueError) as exc:    # a file in the way, read-only parent, NUL in the name
        raise ModelError(f"output_dir {str(target_dir)!r} cannot be used as a folder: {exc}") from None
    target = target_dir / f"{name}.fmu"
    stamp = target_dir / f"{name}.fmu.sha256"
    if target.is_file() and stamp.is_file() and stamp.read_text().strip() == key:
        return target

    with tempfile.TemporaryDirectory(prefix=f".{name}-", dir=target_dir) as work:
        work_path = Path(work)
        built = [_compile(lib, work_path, platform_dir, compiler_path, headers, root, major)
                 for lib in libraries]
        archive = work_path / f"{name}.fmu"
        with zipfile.ZipFile(archive, "w", zipfile.ZIP_DEFLATED) as zf:
            for path in packed:
                zf.write(path, path.relative_to(root).as_posix())
            for library in built:
                zf.write(library, library.relative_to(work_path).as_posix())
        from fmpy.validation import validate_fmu
        problems = validate_fmu(str(archive))
        if problems:
            raise ModelError(f"FMU {name!r} built from {str(source)!r} is not valid:\n- " + "\n- ".join(problems))
        os.replace(archive, target)
    stamp.write_text(key + "\n")
    return target


def _compile(lib: _Library, work_path: Path, platform_dir: str, compiler_path: str, headers: Path, root: Path,
             major: int) -> Path:
    """Compile one library into ``work_path/binaries/<platform>/`` and check its FMI functions."""
    fmpy = require_fmpy()
    library = work_path / "binaries" / platform_dir / f"{lib.identifier}{fmpy.sharedLibraryExtension}"
    library.parent.mkdir(parents=True, exist_ok=True)
    command = [compiler_path, *lib.flags, f"-I{headers}", f"-I{root / 'sources'}",
               *map(str, lib.sources), "-o", str(library), "-lm"]
    what = f"FMU {lib.identifier!r}"
    run_compiler(command, what)
    for interface in lib.interfaces:
        missing = missing_functions(library, required_functions(major, interface), what)
        if missing:
            raise ModelError(f"{what}: the compiled library does not export the FMI {major} {interface} "
                             f"functions {', '.join(missing)}")
    return library
