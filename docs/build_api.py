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

pdoc looks up the source of every class with :func:`inspect.getsource`; on Python < 3.13 that parses
and walks the class's whole module once per class (436 classes: 5 of the build's ~30 s of CPU).
:func:`class_lines` finds the same first line from one walk of the module's syntax tree that pdoc
parses anyway, and the build uses it while pdoc runs (:func:`indexed_class_sources`); the lines
returned are inspect's own, cut by :func:`inspect.getblock` as before.

pdoc keeps every module's documentation objects (and their cached members) alive for the whole build; the
cyclic garbage collector's full passes rescan that growing heap about a dozen times without much to free
(5 of the ~27 s of CPU): :func:`build` pauses the collector while pdoc runs (:func:`paused_garbage_collection`;
the peak memory grows by ~5 %, reference counting still frees everything that is not in a cycle).
"""
from __future__ import annotations

import argparse
import ast
import contextlib
import gc
import inspect
import linecache
import os
import pkgutil
import re
import sys
import types
import warnings
from collections.abc import Callable, Iterator
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


class _ClassLines(ast.NodeVisitor):
    """Qualified name -> 0-based first line (its first decorator's, if any) of every class of a module,
    visited as :func:`inspect.findsource` visits it (the first definition of a name wins)."""

    def __init__(self) -> None:
        self.stack: list[str] = []
        self.lines: dict[str, int] = {}

    def visit_FunctionDef(self, node: ast.FunctionDef | ast.AsyncFunctionDef) -> None:
        self.stack += [node.name, "<locals>"]
        self.generic_visit(node)
        del self.stack[-2:]

    visit_AsyncFunctionDef = visit_FunctionDef

    def visit_ClassDef(self, node: ast.ClassDef) -> None:
        self.stack.append(node.name)
        first = node.decorator_list[0].lineno if node.decorator_list else node.lineno
        self.lines.setdefault(".".join(self.stack), first - 1)
        self.generic_visit(node)
        self.stack.pop()


def class_lines(tree: ast.AST) -> dict[str, int]:
    """Qualified name -> 0-based first line of each class defined in a module's syntax ``tree``.

    The line :func:`inspect.findsource` returns for the class (Python 3.10-3.12), from one walk of the
    module instead of a parse and a walk per class.
    """
    finder = _ClassLines()
    finder.visit(tree)
    return finder.lines


def _parse(module: types.ModuleType | None, source: str) -> ast.AST:
    """``ast.parse(source)``."""
    return ast.parse(source)


@contextlib.contextmanager
def indexed_class_sources(parse: Callable[[types.ModuleType | None, str], ast.AST] = _parse) -> Iterator[None]:
    """While in the context, :func:`inspect.findsource` finds a class from :func:`class_lines` of its file
    (one walk per file of ``parse(module, source)``, which must return ``ast.parse(source)``); everything else,
    and a class the walk does not find, goes to inspect's own code.  The result is the same lines and line
    number.  Python 3.13 and later find a class by its ``__firstlineno__``: nothing is replaced there."""
    original = inspect.findsource
    if sys.version_info >= (3, 13):
        yield
        return
    indexes: dict[str, tuple[list[str], dict[str, int]]] = {}

    def findsource(obj: object) -> tuple[list[str], int]:
        if not inspect.isclass(obj):
            return original(obj)
        file = inspect.getsourcefile(obj)
        if file:
            linecache.checkcache(file)
        module = inspect.getmodule(obj, file) if file else None
        lines = linecache.getlines(file, module.__dict__) if module else linecache.getlines(file) if file else []
        if not lines:
            return original(obj)
        cached = indexes.get(file)
        if cached is None or cached[0] is not lines:
            cached = indexes[file] = (lines, class_lines(parse(module, "".join(lines))))
        line = cached[1].get(obj.__qualname__)
        return (lines, line) if line is not None else original(obj)

    inspect.findsource = findsource
    try:
        yield
    finally:
        inspect.findsource = original


def pdoc_tree(module: types.ModuleType | None, source: str) -> ast.AST:
    """``ast.parse(source)``, shared with pdoc's own (cached) parse of the module when that is of the same text."""
    import pdoc.doc_ast

    if module is not None and source[:1] not in (" ", "\t") and pdoc.doc_ast.get_source(module) == source:
        return pdoc.doc_ast.parse(module)
    return ast.parse(source)


@contextlib.contextmanager
def paused_garbage_collection() -> Iterator[None]:
    """While in the context the cyclic garbage collector does not run (reference counting still frees); it is
    enabled again afterwards if it was before."""
    enabled = gc.isenabled()
    gc.disable()
    try:
        yield
    finally:
        if enabled:
            gc.enable()


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
        with indexed_class_sources(pdoc_tree), paused_garbage_collection():
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
