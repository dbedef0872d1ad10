"""Compile C source into a shared library, cache it on disk, load it (the one compile-and-cache helper).

Used by the compiled fast paths (:func:`load_ctypes`: C text loaded with :mod:`ctypes`;
:mod:`ctmm.manipulator.compiled`: casadi-generated C loaded with ``casadi.external``) and by
:func:`ctmm.control.fmu_build.build_fmu` (compiler lookup, compiler runs, the cache key of labelled
build inputs, :func:`cache_key`, and the cache folder).

Cache folder (:func:`cache_directory`): the ``folder`` argument, else ``$CTMM_CACHE``, else
``$XDG_CACHE_HOME/ctmm``, else ``~/.cache/ctmm``; when the default is not writable, the temp folder
(``ctmm-<uid>``).  A folder given explicitly (argument or ``$CTMM_CACHE``) that cannot be created
or written raises :class:`~ctmm.errors.ModelError`.  Libraries live in its ``kernels/`` subfolder.

Cache entry: ``kernels/<name>-<key>/`` holding ``<name>.c`` (the compiled text), ``<name>.so``
and ``<name>.so.sha256`` (the SHA-256 of the library file), where ``key`` is the SHA-256 of the C text, the compiler (resolved
path and ``--version`` output) and the flags.  An entry is built in a private temporary folder
inside ``kernels/`` and published by one atomic rename, so concurrent processes never see a half
written library (the loser of a race discards its own build and uses the winner's).  An entry
whose library does not match its checksum (truncated or overwritten file) is discarded and
rebuilt.

Keyed entries (:func:`load_casadi_keyed`, the generated kernels of ``compiled=True`` through
:func:`ctmm.generated_loop.compiled_time_loop`): ``kernels/<name>-k<key>/``, same files and the same
publishing, but ``key`` is computed by the caller BEFORE the functions and the C text are built
(serialized casadi functions, sizes, the code that builds the rest, versions; then the compiler and
flags), so a cached library loads by its functions' names without generating anything.  A caller that
keys on a description of its inputs (:mod:`ctmm.model_description`) before building any symbol lets the
entry store the names too (``<name>.names``).

Optimization level (``$CTMM_OPTIMIZATION_LEVEL``, read at every build): unset or empty, each kernel is built with the
flags its caller gives (:data:`DEFAULT_FLAGS`, :data:`STRAIGHT_LINE_FLAGS`, chosen by measurement for the kernel's
speed); set to one of ``0 1 2 3 s g``, every ``-O`` flag of every build of this module is replaced by ``-O<level>``
(:func:`effective_flags`; FMU builds keep their own).  The effective flags are part of the cache key, so the two
builds are two entries.  The numbers agree to round-off at every level (no value-changing flag is ever added: no
``-ffast-math``; on processors with fused multiply-add the optimizer may contract ``a*b + c``), the speeds do not: gcc's time on generated straight-line code is ~3x shorter at ``-O0`` and
the kernel runs ~2-5x slower per step, the trade of a test suite or of a short exploratory run that compiles many
kernels and runs each briefly (``tests/conftest.py`` sets ``0``).
"""
from __future__ import annotations

import ctypes
import functools
import hashlib
import os
import re
import shutil
import subprocess
import tempfile
from dataclasses import dataclass
from pathlib import Path
from typing import Any, Callable, Iterable, Sequence

from .errors import ModelError

__all__ = ["CompiledLibrary", "DEFAULT_FLAGS", "LINK_FLAGS", "OPTIMIZATION_LEVEL_VARIABLE", "OPTIMIZATION_LEVELS",
           "STRAIGHT_LINE_FLAGS", "cache_directory", "cache_key", "casadi_source", "compiler_identity", "effective_flags",
           "find_compiler", "hoisted_input_reads", "load_casadi", "load_casadi_keyed", "load_ctypes",
           "run_compiler", "shared_library"]

DEFAULT_FLAGS = ("-O2", "-shared", "-fPIC")
"""Compiler flags of :func:`shared_library` unless others are given."""
STRAIGHT_LINE_FLAGS = ("-O1", "-shared", "-fPIC")
"""Compiler flags of generated kernels whose step is straight-line code of scalar temporaries (RK4 of spatial
models, of planar scenes without folds, of planar and spatial kinematic loops): gcc's time there goes to register
allocation, and ``-O1`` compiles in 0.55-0.69x the CPU of ``-O2`` while the kernel's CPU per step stays within the
measurement's spread (``benchmarks/generated_flags.py``, best of 9-15 interleaved runs, load 9-15 on 2 cores, where two
identical ``-O1`` builds differ by up to 15-20 %): ``-O1`` / ``-O2`` 0.98-1.16 on planar RK4 (pendulum N = 10 with and
without loops, four-bar) and 0.81-1.09 on spatial RK4 (revolute N = 6, four-bar).  Not for chains (RK4 1.5-1.8x,
Newmark 1.3x slower at ``-O1``) nor the Newton steps of planar DT-TMM schemes (Newmark 1.23-1.26x): they keep
:data:`DEFAULT_FLAGS`."""
LINK_FLAGS = ("-lm",)
"""Flags placed after the source file (libraries to link)."""
OPTIMIZATION_LEVEL_VARIABLE = "CTMM_OPTIMIZATION_LEVEL"
"""Environment variable that, when set, replaces the ``-O`` flag of every kernel build (:func:`effective_flags`)."""
OPTIMIZATION_LEVELS = ("0", "1", "2", "3", "s", "g")
"""Allowed values of ``$CTMM_OPTIMIZATION_LEVEL`` (gcc's and clang's ``-O0`` ... ``-Og``)."""
_OPTIMIZATION_FLAG = re.compile(r"-O(\d+|s|g|z|fast)?")
_KEY_FORMAT = b"ctmm.codegen/1"
_KEYED_FORMAT = b"ctmm.codegen.keyed/1"
_CODEGEN_TEXT = Path(__file__).read_bytes()     # casadi_source's options: part of every keyed entry's key
_COMPILE_TIMEOUT_S = 600.0


@dataclass(frozen=True)
class CompiledLibrary:
    """A shared library in the cache.

    Attributes
    ----------
    path : pathlib.Path
        The library file.
    key : str
        SHA-256 (hex) of the C text, the compiler and the flags; names the cache entry.
    built : bool
        True when this call compiled it (cache miss), False when it was found in the cache.
    """

    path: Path
    key: str
    built: bool


def cache_directory(folder: str | os.PathLike | None = None, *, subfolder: str = "") -> Path:
    """The cache folder (created if missing), checked to be writable.

    Parameters
    ----------
    folder : path, optional
        Explicit folder; default ``$CTMM_CACHE``, else ``$XDG_CACHE_HOME/ctmm``, else
        ``~/.cache/ctmm``, else (default not writable) ``<temp>/ctmm-<uid>``.
    subfolder : str, optional
        Subfolder inside it (``"kernels"``, ``"fmu"``).

    Raises
    ------
    ModelError
        The explicit folder (argument or ``$CTMM_CACHE``) cannot be created or written, or no
        default candidate can.
    """
    explicit = folder if folder is not None else (os.environ.get("CTMM_CACHE") or None)
    if explicit is not None:
        if not isinstance(explicit, (str, os.PathLike)) or str(explicit) == "":
            raise ModelError(f"cache folder must be a path, got {explicit!r}")
        source = "cache folder" if folder is not None else "$CTMM_CACHE"
        path = Path(explicit) / subfolder
        problem = _writable(path)
        if problem:
            raise ModelError(f"{source} {str(explicit)!r} is not usable: {problem}; allowed: a writable "
                             "folder (or unset $CTMM_CACHE for the per-user default)")
        return path
    base = os.environ.get("XDG_CACHE_HOME") or os.path.join(os.path.expanduser("~"), ".cache")
    uid = getattr(os, "getuid", lambda: 0)()
    candidates = (Path(base) / "ctmm", Path(tempfile.gettempdir()) / f"ctmm-{uid}")
    problems = []
    for candidate in candidates:
        problem = _writable(candidate / subfolder)
        if not problem:
            return candidate / subfolder
        problems.append(f"{candidate}: {problem}")
    raise ModelError("no writable cache folder (" + "; ".join(problems) + "); set $CTMM_CACHE or pass a "
                     "cache folder")


def cache_key(key_format: bytes, parts: Iterable[tuple[str, bytes]]) -> str:
    """SHA-256 (hex) of labelled inputs of a build: the cache key of :func:`shared_library` and
    :func:`ctmm.control.fmu_build.build_fmu`.

    Each part enters as ``label \\0 length payload`` (length: 8 bytes, little-endian), so no two
    different lists of parts give the same byte stream.

    Parameters
    ----------
    key_format : bytes
        Version tag of the key layout (changing it invalidates every entry built with another).
    parts : iterable of (str, bytes)
        ``(label, payload)`` in a fixed order: sources, compiler identity, flags, headers...
    """
    digest = hashlib.sha256(key_format)
    for label, payload in parts:
        digest.update(label.encode() + b"\0" + len(payload).to_bytes(8, "little") + payload)
    return digest.hexdigest()


def _writable(path: Path) -> str:
    """Empty string when ``path`` exists (or was created) and is writable, else the reason."""
    try:
        path.mkdir(parents=True, exist_ok=True)
    except OSError as exc:
        return f"cannot create it ({exc.strerror or exc})"
    if not os.access(path, os.W_OK | os.X_OK):
        return "not writable"
    return ""


def find_compiler(compiler: str | os.PathLike | None = None) -> str:
    """Full path of the C compiler: ``compiler`` (a command or a path), default ``gcc`` then ``cc``.

    Raises
    ------
    ModelError
        No such compiler on ``PATH``.
    """
    if compiler is None:
        for candidate in ("gcc", "cc"):
            found = shutil.which(candidate)
            if found:
                return found
        raise ModelError("no C compiler found: neither 'gcc' nor 'cc' is on PATH; install one or pass compiler=")
    if not isinstance(compiler, (str, os.PathLike)) or not str(compiler).strip():
        raise ModelError(f"compiler must be a C compiler command or path such as 'cc' or 'gcc', got {compiler!r}")
    found = shutil.which(str(compiler))
    if found is None:
        raise ModelError(f"compiler {str(compiler)!r} not found on PATH; pass compiler='gcc' or a full path")
    return found


def compiler_identity(compiler_path: str) -> bytes:
    """Resolved path and ``--version`` output of a compiler (part of every cache key).

    The ``--version`` output is remembered per process, keyed on the path, the resolved path and that
    file's modification time [ns], size [bytes], inode and device: a compiler replaced or re-linked
    (another resolved file, or the same file rewritten) is asked again; a failed run is not remembered.
    A wrapper script whose own file is unchanged while the compiler it calls changes is not detected.
    """
    real_path = os.path.realpath(compiler_path)
    try:
        status = os.stat(real_path)
        version = _remembered_version_output(compiler_path, real_path, status.st_mtime_ns, status.st_size,
                                             status.st_ino, status.st_dev)
    except (OSError, subprocess.TimeoutExpired):   # not runnable now: no version, nothing remembered
        version = b""
    return real_path.encode() + b"\0" + version


@functools.lru_cache(maxsize=32)
def _remembered_version_output(compiler_path: str, real_path: str, modified_ns: int, size: int, inode: int,
                               device: int) -> bytes:
    """``<compiler> --version`` standard output, once per compiler file state (the arguments after the
    first are the key); raises (and so remembers nothing) when the compiler cannot run."""
    return subprocess.run([compiler_path, "--version"], capture_output=True, timeout=60).stdout


def run_compiler(command: Sequence[str], what: str) -> None:
    """Run one compiler command; :class:`ModelError` with the command and the compiler's message.

    Parameters
    ----------
    command : sequence of str
        Full command, compiler path first.
    what : str
        What is compiled, for messages (``"the planar kernel"``, ``"FMU 'pd'"``).
    """
    try:
        completed = subprocess.run(list(command), capture_output=True, text=True, timeout=_COMPILE_TIMEOUT_S)
    except (OSError, subprocess.TimeoutExpired) as exc:
        raise ModelError(f"compiling {what} failed to run {command[0]!r}: {exc}") from exc
    if completed.returncode != 0:
        raise ModelError(f"compiling {what} failed (exit {completed.returncode}):\n$ {' '.join(command)}\n"
                         f"{(completed.stderr or completed.stdout).strip()}")


def shared_library(source: str, name: str, *, flags: Sequence[str] = DEFAULT_FLAGS,
                   compiler: str | os.PathLike | None = None,
                   cache_dir: str | os.PathLike | None = None) -> CompiledLibrary:
    """The shared library compiled from the C text ``source``, from the cache or built now.

    Parameters
    ----------
    source : str
        The whole C translation unit.
    name : str
        File stem of the library (letters, digits, ``_``, ``-``); part of the cache entry name.
    flags : sequence of str, optional
        Compiler flags before the source file (default ``-O2 -shared -fPIC``); ``-lm`` follows it.
    compiler : str or path, optional
        Compiler command or path (default ``gcc``, then ``cc``).
    cache_dir : path, optional
        Cache folder (see :func:`cache_directory`); entries go to its ``kernels/`` subfolder.

    Returns
    -------
    CompiledLibrary

    Raises
    ------
    ModelError
        Bad ``source`` or ``name``, no compiler, a compile error (with the compiler's message),
        an unusable cache folder.
    """
    if not isinstance(source, str) or not source.strip():
        raise ModelError(f"source must be non-empty C text, got {type(source).__name__} {source!r:.60}")
    _check_name(name)
    flags = _checked_flags(flags)
    compiler_path = find_compiler(compiler)
    key = cache_key(_KEY_FORMAT, (("source", source.encode()), ("compiler", compiler_identity(compiler_path)),
                                  ("flags", "\0".join(flags + list(LINK_FLAGS)).encode())))
    folder = cache_directory(cache_dir, subfolder="kernels")
    library = folder / f"{name}-{key[:24]}" / f"{name}.so"
    if _intact(library):
        return CompiledLibrary(library, key, built=False)
    return CompiledLibrary(library, key, built=_publish(source, library, compiler_path, flags))


def _check_name(name: str) -> None:
    if not isinstance(name, str) or not name or not all(c.isalnum() or c in "_-" for c in name):
        raise ModelError(f"name must be a non-empty file stem of letters, digits, '_' and '-', got {name!r}")


def _checked_flags(flags: Sequence[str]) -> list[str]:
    if isinstance(flags, (str, bytes)) or not all(isinstance(flag, str) for flag in flags):
        raise ModelError(f"flags must be a sequence of strings such as ('-O2', '-shared', '-fPIC'), got {flags!r}")
    return effective_flags(flags)


def effective_flags(flags: Sequence[str]) -> list[str]:
    """The compiler flags a kernel build uses: ``flags`` as given when ``$CTMM_OPTIMIZATION_LEVEL`` is unset or
    empty, else with every ``-O`` flag replaced by ``-O<level>`` (put first when ``flags`` has none).

    Parameters
    ----------
    flags : sequence of str
        The caller's flags (e.g. :data:`DEFAULT_FLAGS`).

    Raises
    ------
    ModelError
        ``$CTMM_OPTIMIZATION_LEVEL`` holds another value than one of :data:`OPTIMIZATION_LEVELS`.
    """
    level = os.environ.get(OPTIMIZATION_LEVEL_VARIABLE, "").strip()
    if not level:
        return list(flags)
    if level not in OPTIMIZATION_LEVELS:
        raise ModelError(f"${OPTIMIZATION_LEVEL_VARIABLE} = {level!r} is not an optimization level; allowed: one of "
                         f"{', '.join(OPTIMIZATION_LEVELS)} (or unset: each kernel's own flags)")
    kept = [flag for flag in flags if not _OPTIMIZATION_FLAG.fullmatch(flag)]
    return [f"-O{level}", *kept]


def _publish(source: str, library: Path, compiler_path: str, flags: list[str], names: Sequence[str] = ()) -> bool:
    """Compile ``source`` into the cache entry ``library.parent`` (built in a private temporary folder,
    published by one atomic rename, with ``names`` (the functions, one per line) in ``<name>.names`` when given);
    False when another process published an intact entry first."""
    entry, folder, name = library.parent, library.parent.parent, library.stem
    _discard(entry, folder)
    try:
        work = Path(tempfile.mkdtemp(prefix=f".{name}-", dir=folder))
    except OSError as exc:
        raise ModelError(f"cache folder {str(folder)!r} is not writable: {exc}") from exc
    try:
        source_file = work / f"{name}.c"
        source_file.write_text(source)
        built = work / library.name
        run_compiler([compiler_path, *flags, "-o", str(built), str(source_file), *LINK_FLAGS],
                     f"{name!r} ({source_file})")
        if names:
            (work / f"{name}.names").write_text("".join(label + "\n" for label in names))
        built.with_name(built.name + ".sha256").write_text(_file_digest(built) + "\n")
        try:
            os.rename(work, entry)          # atomic publish; fails when another process won the race
        except OSError:
            if not _intact(library):
                raise ModelError(f"cannot publish the compiled library {name!r} into {str(entry)!r}") from None
            return False
    finally:
        shutil.rmtree(work, ignore_errors=True)
    return True


def _file_digest(path: Path) -> str:
    return hashlib.sha256(path.read_bytes()).hexdigest()


def _intact(library: Path) -> bool:
    """True when the library and its checksum file exist and agree."""
    try:
        expected = library.with_name(library.name + ".sha256").read_text().strip()
        return expected == _file_digest(library)
    except OSError:
        return False


def _discard(entry: Path, folder: Path) -> None:
    """Remove a damaged entry: rename it away first (atomic), then delete it."""
    if not entry.exists():
        return
    try:
        trash = Path(tempfile.mkdtemp(prefix=".discard-", dir=folder))
    except OSError as exc:
        raise ModelError(f"cache folder {str(folder)!r} is not writable: {exc}") from exc
    try:
        os.rename(entry, trash / "entry")
    except OSError:
        pass                                  # another process moved or replaced it already
    shutil.rmtree(trash, ignore_errors=True)


def _load(source: str, name: str, options: dict[str, Any], loader: Any, errors: tuple[type, ...]) -> Any:
    """``loader(path)`` of the cached library; one rebuild and retry when loading fails (an entry
    discarded by another process between lookup and load)."""
    for attempt in (0, 1):
        library = shared_library(source, name, **options)
        try:
            return loader(str(library.path))
        except errors as exc:
            if attempt:
                raise ModelError(f"the compiled library {str(library.path)!r} cannot be loaded: {exc}") from exc
            _discard(library.path.parent, library.path.parent.parent)


def load_ctypes(source: str, name: str, **options: Any) -> ctypes.CDLL:
    """Compile (or find in the cache) and load C text with :mod:`ctypes`.

    ``options`` are those of :func:`shared_library`.  Set ``argtypes``/``restype`` on the result.
    """
    return _load(source, name, options, ctypes.CDLL, (OSError,))


def casadi_source(functions: Sequence[Any], name: str) -> str:
    """C text of casadi :class:`casadi.Function` objects (one ``casadi.CodeGenerator`` file), each function's
    input reads taken through one pointer per input (:func:`hoisted_input_reads`)."""
    import casadi as ca

    generator = ca.CodeGenerator(name, {"with_header": False})
    for function in functions:
        generator.add(function)
    with tempfile.TemporaryDirectory() as tmp:
        generator.generate(tmp + os.sep)
        return hoisted_input_reads(_empty_copies_removed(Path(tmp, f"{name}.c").read_text()))


# Each pattern of the text passes starts with its literal name, the word boundary checked behind it: the regex engine
# then scans the text for that name (a pattern opening with ``\b`` is tried at every character, ~30x the CPU).
_EMPTY_COPY = re.compile(r"casadi_copy(?<!\wcasadi_copy)\(0, 0, 0\+ \w+\*0\);")


def _empty_copies_removed(text: str) -> str:
    """Casadi C ``text`` without its copies of no number, ``casadi_copy(0, 0, 0+ i*0);`` (casadi 3.8 writes one per
    column of an empty input repeated over a ``fold`` / ``mapaccum``: a time loop without inputs ``u`` or numbers
    ``p``).  Their third argument is an integer expression passed as a pointer: GCC 14 and later refuse it (C99
    ``-Wint-conversion`` is an error there), so the kernel would not compile; copying nothing, they are removed."""
    return _EMPTY_COPY.sub("", text)


_INPUT_READ = re.compile(r"arg(?<!\warg)\[(\d+)\]\? arg\[\1\]\[(\d+)\] : 0")
_FUNCTION_START = re.compile(r"static int casadi_f(?<![^\n]static int casadi_f)\d+\(const casadi_real\*\* arg, "
                             r"casadi_real\*\* res, casadi_int\* iw, casadi_real\* w, int mem\) \{\n")


def hoisted_input_reads(text: str) -> str:
    """Casadi C ``text`` with every read ``arg[i]? arg[i][k] : 0`` of a function's input (casadi's
    straight-line code: one branch per number read) replaced by ``ctmm_in<i>[k]`` through one pointer per
    input set at the function's start, ``arg[i]`` or, for an absent input, a static array of zeros: the
    same numbers.  The branches made gcc's time grow faster than the code (a 1000-mass chain's step of
    4000 reads: ``-O2`` 24 -> 16 s of CPU, same speed)."""
    starts = [match.end() for match in _FUNCTION_START.finditer(text)]
    pieces, largest = [text[:starts[0]] if starts else text], 0
    for start, following in zip(starts, starts[1:] + [len(text)]):
        end = text.index("\n}\n", start)
        body = text[start:end]
        reads = _INPUT_READ.findall(body)                       # [(input, index)] as digit strings
        largest = max([largest] + [int(k) + 1 for k in {k for _, k in reads}])
        pieces.append("".join(f"  const casadi_real *ctmm_in{i} = arg[{i}] ? arg[{i}] : ctmm_zeros;\n"
                              for i in sorted({int(i) for i, _ in reads})))
        pieces.append(_INPUT_READ.sub(r"ctmm_in\1[\2]", body) + text[end:following])
    if not largest:
        return text
    return "".join(pieces).replace("static int casadi_f", f"static const casadi_real ctmm_zeros[{largest}];\n"
                                   "static int casadi_f", 1)


def load_casadi(functions: Sequence[Any], name: str, **options: Any) -> tuple[Any, ...]:
    """Generate C for casadi functions, compile (cached) and load them with ``casadi.external``.

    Parameters
    ----------
    functions : sequence of casadi.Function
        Functions to generate; the result holds, in the same order, the compiled functions of the
        same names.
    name : str
        Library name (see :func:`shared_library`).
    **options
        ``flags``, ``compiler``, ``cache_dir`` of :func:`shared_library`.
    """
    import casadi as ca

    names = [function.name() for function in functions]
    return _load(casadi_source(functions, name), name, options,
                 lambda path: tuple(ca.external(label, path) for label in names), (RuntimeError, OSError))


def load_casadi_keyed(key_parts: Iterable[tuple[str, bytes]], names: Sequence[str] | None,
                      build: Callable[[], Sequence[Any]],
                      name: str, *, flags: Sequence[str] = DEFAULT_FLAGS, compiler: str | os.PathLike | None = None,
                      cache_dir: str | os.PathLike | None = None) -> tuple[Any, ...]:
    """Casadi functions ``names`` loaded with ``casadi.external`` from the library cached under a key
    the caller computes BEFORE building them; ``build()`` (the functions, C generation and the
    compiler) runs only when no intact entry has that key.

    The key is the SHA-256 of ``key_parts``, ``names``, this module's text (how the C is generated),
    the casadi version, the compiler (resolved path and ``--version``) and the flags: the caller's
    parts must determine the generated code entirely (serialized casadi functions, the code that
    builds the rest from them, sizes), so a change of any number gives a new entry.  Entry
    ``kernels/<name>-k<key[:24]>/`` (``k``: never a C-text key of :func:`shared_library`),
    published atomically as there.

    Parameters
    ----------
    key_parts : iterable of (str, bytes)
        Labelled inputs that determine the functions (see :func:`cache_key`).
    names : sequence of str or None
        Names of the functions, in the order returned; ``build()`` must return functions of exactly
        these names in this order.  ``None``: the names are those ``build()`` returns, stored in the
        entry (``<name>.names``) and read from it when the library is cached (then ``key_parts`` must
        determine them too).
    build : callable
        ``build() -> [casadi.Function]``, called on a cache miss only.
    name : str
        Library name (see :func:`shared_library`).
    flags, compiler, cache_dir
        As in :func:`shared_library`.

    Raises
    ------
    ModelError
        Bad ``name`` or ``flags``, no compiler, a compile error, an unusable cache folder, a library
        that cannot be loaded after one rebuild, or ``build()`` returning other names than ``names``.
    """
    import casadi as ca

    _check_name(name)
    flags, stored = _checked_flags(flags), names is None
    names = [] if names is None else list(names)
    compiler_path = find_compiler(compiler)
    key = cache_key(_KEYED_FORMAT, (*key_parts, ("names", "\0".join(names).encode() if names else b"\0stored"),
                                    ("codegen", _CODEGEN_TEXT),
                                    ("casadi", ca.__version__.encode()),
                                    ("compiler", compiler_identity(compiler_path)),
                                    ("flags", "\0".join(flags + list(LINK_FLAGS)).encode())))
    folder = cache_directory(cache_dir, subfolder="kernels")
    library = folder / f"{name}-k{key[:24]}" / f"{name}.so"
    for attempt in (0, 1):
        if not _intact(library) or (stored and not library.with_suffix(".names").is_file()):
            functions = list(build())
            built_names = [function.name() for function in functions]
            if stored:
                names = built_names
            elif built_names != names:
                raise ModelError(f"library {name!r}: build() returned the functions {built_names}, the key names "
                                 f"{names}; they must be the same, in the same order")
            _publish(casadi_source(functions, name), library, compiler_path, flags, names if stored else ())
        elif stored:
            names = library.with_suffix(".names").read_text().split()
        try:
            return tuple(ca.external(label, str(library)) for label in names)
        except (RuntimeError, OSError) as exc:
            if attempt:
                raise ModelError(f"the compiled library {str(library)!r} cannot be loaded: {exc}") from exc
            _discard(library.parent, folder)
    raise AssertionError("unreachable")
