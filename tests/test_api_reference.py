"""The API reference builds from the docstrings without defects (``docs/build_api.py``, pdoc).

One build into a temporary folder, in one test (so that it runs once per suite, see
:func:`test_build_pages_and_names`); then: no warning other than the known harmless kinds, one page
per module, every public name of ``ctmm`` on the package page, and the numpy ``Parameters``
sections rendered as such (the docstring format is understood, not shown raw).

The build leaves out the "View Source" listings and the search index: 30 s of CPU instead of 79 s
(316 modules).  Neither raises a warning of its own (pdoc looks sources up silently; the index
converts the same docstrings as the pages), so the defects found are the same: the full build and
this one raise the same 73 warning messages, all harmless, on the same modules.
"""
from __future__ import annotations

import importlib.util
import re
import sys
from pathlib import Path

import pytest

pytest.importorskip("pdoc")

ROOT = Path(__file__).resolve().parents[1]


def _builder():
    spec = importlib.util.spec_from_file_location("build_api", ROOT / "docs" / "build_api.py")
    module = importlib.util.module_from_spec(spec)
    sys.modules["build_api"] = module
    spec.loader.exec_module(module)
    return module


def test_build_pages_and_names(tmp_path: Path) -> None:
    """One build (about 22 s of CPU; 35 s before ``build_api.indexed_class_sources``, 27 s before
    ``build_api.paused_garbage_collection``), checked from three sides in
    one test: under ``--dist worksteal`` the tests of a module may run on different workers, and a module-scoped
    fixture shared by several tests would then build the reference once per worker.  Each check is reported, a
    failing one does not hide the others."""
    import ctmm

    builder = _builder()
    failures: list[str] = []
    output = tmp_path
    defects = builder.build(output, show_source=False, search=False)
    names = builder.module_names()
    # no defect: every warning of the build is of a known harmless kind
    if defects:
        failures.append(f"the build raised warnings that are defects: {defects}")
    # one page per module
    if not ("ctmm.spatial.body_forms" in names and "ctmm.reference.spatial_tree" in names):
        failures.append("module_names() misses ctmm.spatial.body_forms or ctmm.reference.spatial_tree")
    missing = [name for name in names if not (output / (name.replace(".", "/") + ".html")).is_file()]
    if missing:
        failures.append(f"modules without a page: {missing}")
    # every public name on the package page, numpy sections rendered (not shown raw)
    page = (output / "ctmm.html").read_text(encoding="utf-8")
    absent = [name for name in ctmm.__all__ if f'id="{name}"' not in page and f">{name}<" not in page]
    if absent:
        failures.append(f"public names absent from ctmm.html: {absent}")
    simulate = (output / "ctmm" / "simulation.html").read_text(encoding="utf-8")
    docstrings = "".join(re.findall(r'<div class="docstring">(.*?)</div>', simulate, flags=re.S))
    if "Parameters</h6>" not in docstrings:
        failures.append("ctmm/simulation.html: no rendered 'Parameters' section")
    if "----------" in docstrings:
        failures.append("ctmm/simulation.html: the underline of a numpy section is shown raw")
    assert failures == []


def test_defect_warnings_are_reported(tmp_path: Path) -> None:
    builder = _builder()
    texts = ["The module specification 'ctmm.x' adds a module named ctmm.x, but a module with this name has already "
             "been added.", "Error parsing type annotation ForwardRef('Any') for ctmm.a.B.__init__. Import of Any "
             "failed: name 'Any' is not defined", "Docstring section 'Parameters' could not be parsed"]
    kept = [t for t in texts if not any(p.search(t) for p in builder.HARMLESS)]
    assert kept == [texts[2]]


CLASSES = '''\
import dataclasses
from typing import NamedTuple


@dataclasses.dataclass(frozen=True)
class Decorated:
    """A decorated class: its source starts at the decorator."""
    value: float = 1.0

    class Nested:
        pass


class Point(NamedTuple):
    x: float
    y: float


def factory():
    class Local:
        def method(self):
            class Deeper:
                pass
            return Deeper
    return Local


if True:
    class Twice:
        first = True
else:
    pass


class Twice:                           # the second definition: inspect finds the first one by name
    first = False
    # a trailing comment at the body's indentation belongs to the block


Alias = Point
'''


def test_indexed_class_sources_are_inspects_own(tmp_path: Path) -> None:
    """While the build runs, a class's source comes from one walk of its module (``indexed_class_sources``):
    the lines and first line are those of :func:`inspect.findsource` itself, for decorated, nested, local,
    redefined and NamedTuple classes, for classes of ctmm, and for a class it cannot find (inspect's error); with the
module parsed by ``ast.parse`` or shared with pdoc's parse (as in the build)."""
    import inspect

    import ctmm.planar.elements

    builder = _builder()
    path = tmp_path / "ctmm_classes_sample.py"
    path.write_text(CLASSES, encoding="utf-8")
    spec = importlib.util.spec_from_file_location("ctmm_classes_sample", path)
    sample = importlib.util.module_from_spec(spec)
    sys.modules[spec.name] = sample
    try:
        spec.loader.exec_module(sample)
        local = sample.factory()
        gone = type("Gone", (), {"__module__": sample.__name__})        # defined nowhere in the file
        classes = [sample.Decorated, sample.Decorated.Nested, sample.Point, local, local().method(), sample.Twice,
                   sample.Alias, gone, *(value for value in vars(ctmm.planar.elements).values()
                                         if inspect.isclass(value) and value.__module__ == "ctmm.planar.elements")]

        def found(cls):
            try:
                lines, line = inspect.findsource(cls)
                return "".join(lines), line, inspect.getsource(cls)
            except OSError as error:
                return str(error)

        expected = [found(cls) for cls in classes]
        assert expected[7] == "could not find class definition" and len(classes) > 10
        original = inspect.findsource
        for parse in ([], [builder.pdoc_tree]):
            with builder.indexed_class_sources(*parse):
                assert (inspect.findsource is not original) is (sys.version_info < (3, 13))
                indexed = [found(cls) for cls in classes]
            assert inspect.findsource is original
            assert indexed == expected, parse
    finally:
        sys.modules.pop(spec.name, None)


def test_the_build_pauses_the_garbage_collector_and_restores_it() -> None:
    """``paused_garbage_collection`` (around pdoc in ``build``): the collector is off inside, on again after (also
    after an error), and left off if it was off before."""
    import gc

    builder = _builder()
    assert gc.isenabled()
    try:
        with builder.paused_garbage_collection():
            assert not gc.isenabled()
            raise KeyError("inside")
    except KeyError:
        pass
    assert gc.isenabled()
    gc.disable()
    try:
        with builder.paused_garbage_collection():
            assert not gc.isenabled()
        assert not gc.isenabled()
    finally:
        gc.enable()
