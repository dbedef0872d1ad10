"""Build the HTML API reference of ctmm from its numpy-style docstrings with pdoc.

Usage::

    pip install -e ".[docs]"              # pdoc
    python docs/build_api.py              # -> docs/_build/api/index.html
    python docs/build_api.py --output DIR

Every module of the package is documented (``ctmm.__main__`` excepted: importing it runs the
command line), also the subpackages' modules that their ``__all__`` does not re-export, and the
validation models of ``ctmm.reference``.  The build fails (exit status 1) on any warning pdoc
raises except one known, harmless kind: pdoc cannot evaluate the string annotations of a
``typing.NamedTuple``'s generated ``__new__`` (its globals are not the module's) and shows them as
written.  ``tests/test_api_reference.py`` runs this build without the "View Source" listings and the
search index (two thirds of the build's CPU time; they raise no warning of their own, see
:func:`build`).
"""
from __future__ import annotations

import argparse
import os
import pkgutil
import re
import sys
import warnings
from pathlib import Path

#: Warnings that do not mean a defect of the documentation (see the module docstring).
HARMLESS = (
    # a package spec that also lists its submodules: the page is generated once
    re.compile(r"The module specification '.*' adds a module named .*, but a module with this name has already"),
    # string annotations of NamedTuple.__new__, evaluated by pdoc outside their module
    re.compile(r"Error parsing type annotation .* for ctmm\..*\.__init__\. Import of .* failed: name '.*' is not "
               r"defined"),
)


def module_names() -> list[str]:
    """Every importable module of ctmm, packages first, ``ctmm.__main__`` excluded."""
    import ctmm

    names = ["ctmm"] + [info.name for info in pkgutil.walk_packages(ctmm.__path__, "ctmm.")]
    return [name for name in names if not name.endswith(".__main__")]


def build(output: Path, *, show_source: bool = True, search: bool = True) -> list[str]:
    """Write the reference into ``output`` and return the messages of the warnings that are defects.

    Parameters
    ----------
    output : Path
        Folder for the HTML pages (created; existing pages are overwritten).
    show_source : bool
        Include each object's highlighted source ("View Source").  Its cost is pygments and
        ``inspect.getsource``; pdoc looks sources up silently (an empty listing, never a warning).
    search : bool
        Write the search index ``search.js``.  It converts the same docstrings, with the same
        cached conversion, as the pages, so it raises no warning the pages do not.

    Returns
    -------
    list of str
        Warnings raised during the build that are not in :data:`HARMLESS` (empty: a clean build).
    """
    os.environ.setdefault("MPLBACKEND", "Agg")
    import pdoc
    import pdoc.render

    pdoc.render.configure(docformat="numpy", show_source=show_source, search=search)
    with warnings.catch_warnings(record=True) as caught:
        warnings.simplefilter("always")
        pdoc.pdoc(*module_names(), output_directory=Path(output))
    messages = [str(item.message) for item in caught]
    return [text for text in messages if not any(pattern.search(text) for pattern in HARMLESS)]


def main(argv: list[str] | None = None) -> int:
    """Command line: build, print defects, exit 1 if there are any."""
    parser = argparse.ArgumentParser(description=__doc__.splitlines()[0])
    parser.add_argument("--output", default=str(Path(__file__).resolve().parent / "_build" / "api"),
                        help="output folder (default: docs/_build/api)")
    arguments = parser.parse_args(argv)
    defects = build(Path(arguments.output))
    for text in defects:
        print(f"warning: {text}", file=sys.stderr)
    print(f"API reference: {Path(arguments.output) / 'index.html'}"
          + (f" ({len(defects)} warning(s))" if defects else ""))
    return 1 if defects else 0


if __name__ == "__main__":
    sys.exit(main())
