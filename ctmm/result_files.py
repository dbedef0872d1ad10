"""ctmm result files: HDF5 storage of named arrays with attributes, versioned and written atomically.

This module knows the file format, not the result classes (:mod:`ctmm.results` maps its objects
onto it). A file holds:

* root attributes ``format = "ctmm-result"``, ``format_version`` (an integer, see
  :data:`FORMAT_VERSION`), ``kind`` (what the file holds, e.g. ``"simulation"``) and further
  provenance attributes;
* datasets and groups named by slash-separated paths (``"time"``, ``"signals/m6.x"``), each with
  its own attributes (``unit``, ...). Every non-empty dataset carries a Fletcher-32 checksum, so
  corrupted data raise an error on reading instead of returning wrong numbers.

The file is first written to a temporary file in the target folder, then moved onto the target
with :func:`os.replace`: a reader never sees a half-written file and a failed save leaves any
previous file untouched. h5py is an optional dependency (``pip install 'ctmm[data]'``).
"""
from __future__ import annotations

import json
import os
import uuid
from pathlib import Path
from typing import Any, Mapping

import numpy as np

from .errors import ModelError

FORMAT_NAME = "ctmm-result"
"""Value of the root attribute ``format`` of every ctmm result file."""

FORMAT_VERSION = 1
"""Format version written by this ctmm; files with a larger version are refused on loading."""

SUFFIXES = (".h5", ".hdf5", ".hdf")
"""Accepted file name endings."""


class ResultFileError(ModelError):
    """A result file cannot be written or read (bad path, not a ctmm file, corrupted, too new)."""


def require_h5py(what: str):
    """Import h5py, or raise an ImportError naming the optional extra that provides it."""
    try:
        import h5py
    except ImportError as exc:
        raise ImportError(f"{what} needs h5py, an optional dependency of ctmm: "
                          "pip install 'ctmm[data]' (or pip install h5py)") from exc
    return h5py


def _check_path(path: str | os.PathLike, *, for_writing: bool) -> Path:
    try:
        target = Path(path)
    except TypeError:
        raise ResultFileError(f"path must be a str or os.PathLike, got {path!r} "
                              f"({type(path).__name__})") from None
    if target.suffix.lower() not in SUFFIXES:
        raise ResultFileError(f"path {str(target)!r}: a ctmm result file is HDF5 and its name must end with "
                              f"one of {', '.join(SUFFIXES)}, got suffix {target.suffix!r}")
    if target.is_dir():
        raise ResultFileError(f"path {str(target)!r} is a folder; give a file name ending with .h5")
    if for_writing and not target.parent.is_dir():
        raise ResultFileError(f"path {str(target)!r}: the folder {str(target.parent)!r} does not exist")
    if not for_writing and not target.is_file():
        raise ResultFileError(f"path {str(target)!r}: no such result file")
    return target


def _attribute(value: Any) -> Any:
    """An HDF5-storable attribute value: scalars and strings as such, anything else as JSON text."""
    if isinstance(value, (bool, np.bool_)):
        return np.bool_(value)
    if isinstance(value, str) and not value.startswith("json:"):
        return value
    if isinstance(value, (int, float, np.integer, np.floating)):
        return value
    return "json:" + json.dumps(value, default=_jsonable)


def _jsonable(value: Any) -> Any:
    if isinstance(value, np.ndarray):
        return value.tolist()
    if isinstance(value, (np.integer, np.floating, np.bool_)):
        return value.item()
    if isinstance(value, (tuple, set, frozenset)):
        return list(value)
    return repr(value)


def _read_attribute(value: Any) -> Any:
    if isinstance(value, bytes):
        value = value.decode()
    if isinstance(value, str) and value.startswith("json:"):
        return json.loads(value[5:])
    if isinstance(value, np.generic):
        return value.item()
    if isinstance(value, np.ndarray):
        return value.tolist()
    return value


def write(path: str | os.PathLike, kind: str, attributes: Mapping[str, Any],
          datasets: Mapping[str, tuple[np.ndarray, Mapping[str, Any]]],
          groups: Mapping[str, Mapping[str, Any]] | None = None) -> Path:
    """Write a result file atomically.

    Parameters
    ----------
    path : str or os.PathLike
        Target file, ending with ``.h5``, ``.hdf5`` or ``.hdf``; its folder must exist. An existing
        file is replaced only once the new one is completely written.
    kind : str
        What the file holds (``"simulation"``, ``"frequency_response"``).
    attributes : mapping
        Root attributes (provenance). Numbers and strings are stored as HDF5 attributes; lists and
        dicts as JSON text prefixed ``"json:"``.
    datasets : mapping
        ``{path_in_file: (array, attributes)}``.
    groups : mapping, optional
        ``{group_path: attributes}`` for groups that carry attributes (created if needed).

    Returns
    -------
    Path
        The written file.

    Raises
    ------
    ResultFileError
        Bad path, a folder that cannot be written (read-only, full), or a dataset name that HDF5
        cannot hold.
    ImportError
        h5py is not installed.
    """
    h5py = require_h5py("saving a result")
    target = _check_path(path, for_writing=True)
    try:
        # O_EXCL on a unique name, mode 0666 filtered by the umask: an ordinary file (mkstemp would make it 0600)
        temporary = str(target.parent / f".{target.name}.{os.getpid()}.{uuid.uuid4().hex}.tmp")
        descriptor = os.open(temporary, os.O_CREAT | os.O_EXCL | os.O_WRONLY, 0o666)
    except (OSError, ValueError) as exc:   # read-only or special folder, NUL in the name
        raise ResultFileError(f"path {str(target)!r} cannot be written: {exc}") from None
    os.close(descriptor)
    try:
        with h5py.File(temporary, "w", track_order=True) as handle:
            handle.attrs["format"] = FORMAT_NAME
            handle.attrs["format_version"] = FORMAT_VERSION
            handle.attrs["kind"] = kind
            for key, value in attributes.items():
                handle.attrs[key] = _attribute(value)
            for name, group_attributes in (groups or {}).items():
                group = handle.require_group(name)
                for key, value in group_attributes.items():
                    group.attrs[key] = _attribute(value)
            for name, (data, data_attributes) in datasets.items():
                if not name or name.startswith("/") or "//" in name or name == ".":
                    raise ResultFileError(f"dataset name {name!r} cannot be stored in HDF5")
                array = np.asarray(data)
                options = {"fletcher32": True} if array.ndim and array.size else {}
                dataset = handle.create_dataset(name, data=array, **options)
                for key, value in data_attributes.items():
                    dataset.attrs[key] = _attribute(value)
        os.replace(temporary, target)
    except BaseException as exc:
        if os.path.exists(temporary):
            os.unlink(temporary)
        if isinstance(exc, OSError):       # disk full, folder removed meanwhile, ...
            raise ResultFileError(f"path {str(target)!r} cannot be written: {exc}") from exc
        raise
    return target


class Contents:
    """What :func:`read` returns: root attributes, datasets and group attributes of a result file.

    Attributes
    ----------
    path : Path
        The file read.
    kind : str
        Root attribute ``kind``.
    version : int
        Root attribute ``format_version``.
    attributes : dict
        Root attributes other than ``format``, ``format_version`` and ``kind`` (JSON decoded).
    datasets : dict
        ``{path_in_file: ndarray}`` of every dataset.
    dataset_attributes : dict
        ``{path_in_file: {key: value}}``.
    group_attributes : dict
        ``{group_path: {key: value}}`` of every group.
    """

    def __init__(self, path: Path, kind: str, version: int) -> None:
        self.path, self.kind, self.version = path, kind, version
        self.attributes: dict[str, Any] = {}
        self.datasets: dict[str, np.ndarray] = {}
        self.dataset_attributes: dict[str, dict[str, Any]] = {}
        self.group_attributes: dict[str, dict[str, Any]] = {}

    def dataset(self, name: str) -> np.ndarray:
        """A dataset that must exist (a missing one means a damaged or foreign file)."""
        if name not in self.datasets:
            raise ResultFileError(f"result file {str(self.path)!r} ({self.kind}) has no dataset {name!r}: "
                                  "the file is damaged or was not written by ctmm")
        return self.datasets[name]


def read(path: str | os.PathLike, kinds: tuple[str, ...]) -> Contents:
    """Read a whole result file, checking format, version and checksums.

    Parameters
    ----------
    path : str or os.PathLike
        The file.
    kinds : tuple of str
        The kinds the caller can rebuild.

    Raises
    ------
    ResultFileError
        No such file, not HDF5 (wrong or truncated file), not a ctmm result file, a newer format
        version, an unknown kind, or corrupted data (checksum mismatch).
    """
    h5py = require_h5py("loading a result")
    source = _check_path(path, for_writing=False)
    try:
        handle = h5py.File(source, "r")
    except OSError as exc:
        raise ResultFileError(f"result file {str(source)!r} is not a readable HDF5 file (wrong file type, "
                              f"truncated or corrupted): {exc}") from None
    with handle:
        try:
            attrs = {key: _read_attribute(value) for key, value in handle.attrs.items()}
        except ValueError as exc:          # JSON text of an attribute damaged
            raise ResultFileError(f"result file {str(source)!r} is corrupted (a root attribute is not "
                                  f"valid JSON): {exc}") from None
        if attrs.get("format") != FORMAT_NAME:
            raise ResultFileError(f"{str(source)!r} is an HDF5 file but not a ctmm result file "
                                  f"(root attribute format={attrs.get('format')!r}, expected {FORMAT_NAME!r})")
        version = attrs.get("format_version")
        if not isinstance(version, int) or version < 1:
            raise ResultFileError(f"{str(source)!r}: invalid format_version {version!r} (a positive integer)")
        if version > FORMAT_VERSION:
            raise ResultFileError(f"{str(source)!r} has format version {version}, newer than the versions "
                                  f"this ctmm reads (1 to {FORMAT_VERSION}); upgrade ctmm")
        kind = attrs.get("kind")
        if kind not in kinds:
            raise ResultFileError(f"{str(source)!r} holds kind={kind!r}; this loader reads {', '.join(kinds)}")
        contents = Contents(source, kind, version)
        contents.attributes = {k: v for k, v in attrs.items() if k not in ("format", "format_version", "kind")}

        def visit(name: str, item: Any) -> None:
            item_attrs = {key: _read_attribute(value) for key, value in item.attrs.items()}
            if isinstance(item, h5py.Dataset):
                contents.datasets[name] = item[()]
                contents.dataset_attributes[name] = item_attrs
            else:
                contents.group_attributes[name] = item_attrs

        try:
            handle.visititems(visit)
        except (OSError, ValueError) as exc:
            raise ResultFileError(f"result file {str(source)!r} is corrupted (an HDF5 checksum, read or "
                                  f"attribute decoding failed): {exc}") from None
    return contents


def check_time_grid(contents: Contents, signals: Mapping[str, np.ndarray]) -> None:
    """``ResultFileError`` when the arrays of a simulation file do not share its time grid.

    ``states``/``velocity``/``acceleration`` need one row per time; a stored signal either one
    value per time or rows ``(time, value)`` (controller outputs at their own rate).
    """
    time = contents.dataset("time")
    n = len(time) if np.ndim(time) == 1 else -1
    problems = [f"{name} has shape {np.shape(contents.dataset(name))}"
                for name in ("states", "velocity", "acceleration")
                if np.ndim(contents.dataset(name)) != 3 or np.shape(contents.dataset(name))[0] != n]
    problems += [f"signal {name!r} has shape {np.shape(values)}" for name, values in signals.items()
                 if not ((np.ndim(values) == 1 and len(values) == n)
                         or (np.ndim(values) == 2 and np.shape(values)[1] == 2))]
    if n < 0 or problems:
        raise ResultFileError(f"result file {str(contents.path)!r} is inconsistent: time has shape "
                              f"{np.shape(time)} but {'; '.join(problems) or 'it must be 1-D'} (damaged or "
                              "edited file)")


def check_response_shape(contents: Contents, n_outputs: int, n_inputs: int) -> None:
    """``ResultFileError`` when a frequency-response file's response does not match its names and omega."""
    shape = np.shape(contents.dataset("response"))
    expected = (n_outputs, n_inputs, len(contents.dataset("omega")))
    if shape != expected:
        raise ResultFileError(f"result file {str(contents.path)!r} is inconsistent: response has shape {shape}, "
                              f"expected (n_outputs, n_inputs, n_omega) = {expected}")
