"""Reading FMU model descriptions (shared by :mod:`ctmm.control.fmu` and :mod:`ctmm.control.fmu_build`).

Every failure becomes a :class:`~ctmm.errors.ModelError` naming the file and what is wrong; the
FMI version is read from the XML root before any schema validation so that an FMI 1.0 file gets a
clear "unsupported version" message instead of a schema error.
"""
from __future__ import annotations

import zipfile
from pathlib import Path
from types import ModuleType
from typing import Any

from ..errors import ModelError

__all__ = ["require_fmpy", "fmi_headers_dir", "peek_fmi_version", "fmi_major_version",
           "read_description", "SUPPORTED_FMI_VERSIONS"]

SUPPORTED_FMI_VERSIONS = ("2.0", "3.0")
"""FMI versions ctmm runs and builds."""


def require_fmpy() -> ModuleType:
    """Import fmpy, or raise a :class:`ModelError` saying how to install it."""
    try:
        import fmpy
    except ImportError as exc:  # pragma: no cover - fmpy is a dependency of ctmm
        raise ModelError("FMU support needs the 'fmpy' package (pip install fmpy)") from exc
    return fmpy


def fmi_headers_dir() -> Path:
    """Folder holding the FMI 1/2/3 C headers shipped with fmpy (``fmpy/c-code``)."""
    return Path(require_fmpy().__file__).resolve().parent / "c-code"


def peek_fmi_version(path: Path) -> str:
    """The ``fmiVersion`` attribute of ``modelDescription.xml`` in an FMU, folder or XML file.

    Raises
    ------
    ModelError
        The file is not a ZIP archive (e.g. truncated), has no ``modelDescription.xml`` or the XML
        cannot be parsed; the message names the file.
    """
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
    except zipfile.BadZipFile as exc:
        raise ModelError(f"{str(path)!r} is not a valid FMU: not a ZIP archive or truncated ({exc})") from exc
    except KeyError as exc:
        raise ModelError(f"{str(path)!r} is not a valid FMU: it has no modelDescription.xml") from exc
    except (OSError, ElementTree.ParseError, EOFError, zipfile.LargeZipFile) as exc:
        raise ModelError(f"cannot read modelDescription.xml from {str(path)!r}: {exc}") from exc
    return ""


def fmi_major_version(version: str, what: str) -> int:
    """The FMI major version (2 or 3) of ``version``; ``what`` names the FMU in the error."""
    major = str(version).split(".")[0]
    if major not in ("2", "3"):
        raise ModelError(f"{what} declares fmiVersion={version!r}; supported: "
                         f"{', '.join(repr(v) for v in SUPPORTED_FMI_VERSIONS)} (FMI 1.0 has a different C API; "
                         "re-export the model as FMI 2.0 or 3.0)")
    return int(major)


def read_description(path: Path, what: str, validate: bool = True) -> Any:
    """Read and schema-validate the model description of an FMU file, extracted folder or XML file.

    Parameters
    ----------
    path : pathlib.Path
        ``.fmu`` archive, folder of an extracted FMU, or ``modelDescription.xml``.
    what : str
        How the FMU is named in error messages, e.g. ``"FMU '/path/model.fmu'"``.
    validate : bool, optional
        Check the XML against the FMI schema (default).  ``False`` accepts descriptions with
        schema violations that fmpy can still read (at the user's risk).

    Returns
    -------
    fmpy.model_description.ModelDescription

    Raises
    ------
    ModelError
        Unreadable or corrupt file, unsupported FMI version, or schema violations (listed).
    """
    fmpy = require_fmpy()
    fmi_major_version(peek_fmi_version(path), what)
    try:
        return fmpy.read_model_description(str(path), validate=validate)
    except Exception as exc:  # fmpy raises ValidationError, lxml errors, zip errors ...
        problems = getattr(exc, "problems", None)
        detail = "; ".join(problems) if problems else str(exc)
        hint = " (validate=False accepts schema violations that can still be read, at your own risk)" \
            if validate else ""
        raise ModelError(f"cannot read the model description of {what}: {detail}{hint}") from exc
