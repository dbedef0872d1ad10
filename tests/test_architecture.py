"""Architecture rules of the code base, checked by an AST scan (issue 12, step S0).

The scan reads every ``.py`` file of ``ctmm/``, ``controllers/`` (installed as ``ctmm.controllers``)
and ``scenarios/`` (``ctmm.scenarios``) without importing anything, and reports:

* ``cycle`` — an import edge ``a -> b`` that lies on an import cycle made of module-level imports
  only (the cycle exists at import time);
* ``lazy cycle`` — an import made inside a function or under ``if TYPE_CHECKING`` that closes a
  cycle (the cycle is hidden by deferring the import; the module-level edges of that cycle are
  not listed separately);
* ``package cycle`` — an import from one subpackage (``ctmm.planar``) into another that lies on a
  cycle between subpackages which no module-level cycle above already reports;
* ``private import`` — ``from m import _name`` (or ``import m._name``) across modules;
* ``reference import`` — a ``ctmm/`` module outside ``ctmm/reference/`` importing ``ctmm.reference``
  (the independent validation models are for tests, scenarios and benchmarks only);
* ``reference dependency`` — a ``ctmm/reference/`` module importing library code other than
  :data:`REFERENCE_MAY_IMPORT` (the validation models stay independent of what they validate);
* ``star import`` — ``from m import *``;
* ``long module`` — a file over :data:`MAX_LINES` lines.

Today's violations are listed in :data:`ALLOWED`, one entry per violation with a one-line reason.
The list may only shrink: a new violation fails :func:`test_no_new_violations`, and an entry that no
longer matches a violation fails :func:`test_allowlist_has_no_stale_entries` (delete the entry in
the commit that removes the violation).  An allowlisted long module may not grow beyond the line
count recorded in :data:`LONG_MODULES`.  The plan that removes these entries is
``docs/plans/one_core.md``; ``docs/architecture.md`` describes the code as it is.
"""
from __future__ import annotations

import ast
import textwrap
from dataclasses import dataclass
from pathlib import Path

import pytest

ROOT = Path(__file__).resolve().parents[1]
SOURCES = (("ctmm", ROOT / "ctmm"), ("ctmm.controllers", ROOT / "controllers"),
           ("ctmm.scenarios", ROOT / "scenarios"))
REFERENCE = "ctmm.reference"
#: What the independent validation models may import from the library (besides each other).
REFERENCE_MAY_IMPORT = ("ctmm.errors", "ctmm.validation")
MAX_LINES = 600


@dataclass(frozen=True)
class Violation:
    """One rule broken at one place: ``kind`` and ``key`` identify it, ``where`` locates it."""

    kind: str
    key: str
    where: str


@dataclass(frozen=True)
class Edge:
    """An import of module ``target`` by module ``source`` (``lazy``: inside a function or TYPE_CHECKING)."""

    source: str
    target: str
    lazy: bool
    where: str


# --------------------------------------------------------------------------------------------------
# The scanner
# --------------------------------------------------------------------------------------------------
def module_files(sources=SOURCES) -> dict[str, Path]:
    """Module name -> file, for every ``.py`` file under the given (package name, folder) pairs."""
    modules = {}
    for package, folder in sources:
        for path in sorted(folder.rglob("*.py")):
            parts = list(path.relative_to(folder).with_suffix("").parts)
            if parts[-1] == "__init__":
                parts = parts[:-1]
            modules[".".join([package, *parts])] = path
    return modules


def _is_package(path: Path) -> bool:
    return path.name == "__init__.py"


def _resolve_from(module: str, path: Path, node: ast.ImportFrom) -> str:
    """Absolute name of the module named by a ``from ... import`` statement."""
    if not node.level:
        return node.module or ""
    package = module if _is_package(path) else module.rpartition(".")[0]
    for _ in range(node.level - 1):
        package = package.rpartition(".")[0]
    return f"{package}.{node.module}" if node.module else package


def _known(name: str, modules) -> str | None:
    """The longest prefix of ``name`` that is a scanned module (None for outside modules)."""
    while name:
        if name in modules:
            return name
        name = name.rpartition(".")[0]
    return None


def _is_type_checking(test: ast.expr) -> bool:
    return (isinstance(test, ast.Name) and test.id == "TYPE_CHECKING") or (
        isinstance(test, ast.Attribute) and test.attr == "TYPE_CHECKING")


#: The fields that hold statements (``ast.stmt`` lists, and the ``except`` / ``case`` clauses holding them).  An
#: import is a statement, so the scan descends only these: expressions (most of the tree) hold no import.
STATEMENT_FIELDS = ("body", "orelse", "finalbody", "handlers", "cases")


def _imports(tree: ast.AST):
    """Every import statement with a flag: made lazily (in a function body or under TYPE_CHECKING)."""
    stack = [(tree, False)]
    while stack:
        node, lazy = stack.pop()
        if isinstance(node, (ast.Import, ast.ImportFrom)):
            yield node, lazy
            continue
        if isinstance(node, ast.If) and _is_type_checking(node.test):
            stack.extend((child, True) for child in node.body)
            stack.extend((child, lazy) for child in node.orelse)
            continue
        inner = lazy or isinstance(node, (ast.FunctionDef, ast.AsyncFunctionDef))
        for field in STATEMENT_FIELDS:
            children = getattr(node, field, None)
            if isinstance(children, list):       # a Lambda's or an IfExp's ``body`` is an expression: no import
                stack.extend((child, inner) for child in children)


def _within(module: str, package: str) -> bool:
    return module == package or module.startswith(package + ".")


def _private(name: str) -> bool:
    return name.startswith("_") and not (name.startswith("__") and name.endswith("__"))


def scan(modules: dict[str, Path], *, max_lines: int = MAX_LINES,
         reference: str = REFERENCE, library: str = "ctmm",
         reference_may_import: tuple[str, ...] = REFERENCE_MAY_IMPORT) -> tuple[list[Violation], list[Edge], dict]:
    """Scan ``modules`` (name -> file): violations other than cycles, import edges, line counts."""
    violations, edges, lines = [], [], {}
    library_folder = modules[library].parent if library in modules else None
    for module, path in modules.items():
        text = path.read_text(encoding="utf-8")
        relative = path.relative_to(ROOT) if path.is_relative_to(ROOT) else path
        lines[module] = len(text.splitlines())
        if lines[module] > max_lines:
            violations.append(Violation("long module", module, f"{relative}: {lines[module]} lines"))
        in_library = library_folder is not None and path.is_relative_to(library_folder)
        in_reference = _within(module, reference)
        for node, lazy in _imports(ast.parse(text, filename=str(path))):
            where = f"{relative}:{node.lineno}"
            if isinstance(node, ast.Import):
                targets = [(alias.name, alias.name) for alias in node.names]
            else:
                base = _resolve_from(module, path, node)
                targets = [(f"{base}.{alias.name}", base) for alias in node.names]
                for alias in node.names:
                    if alias.name == "*":
                        violations.append(Violation("star import", f"{module}: from {base} import *", where))
                    elif _private(alias.name) and f"{base}.{alias.name}" not in modules:
                        violations.append(Violation("private import", f"{module}: {alias.name} from {base}", where))
            for full, base in targets:
                target = _known(full, modules) or _known(base, modules)
                named = full if isinstance(node, ast.Import) else (target or "")
                if target != module and any(_private(part) for part in named.split(".")):
                    violations.append(Violation("private import", f"{module}: {named}", where))
                if in_library and not in_reference and _within(full, reference):
                    violations.append(Violation("reference import", f"{module}: {full}", where))
                if in_reference and target is not None and not _within(target, reference) \
                        and target not in reference_may_import:
                    violations.append(Violation("reference dependency", f"{module}: {target}", where))
                if target is not None and target != module:
                    edges.append(Edge(module, target, lazy, where))
    return violations, edges, lines


def _strongly_connected(nodes, successors) -> list[set]:
    """Tarjan's strongly connected components (iterative)."""
    index, low, on_stack, stack, components, counter = {}, {}, set(), [], [], [0]
    for root in nodes:
        if root in index:
            continue
        work = [(root, iter(successors.get(root, ())))]
        index[root] = low[root] = counter[0]
        counter[0] += 1
        stack.append(root)
        on_stack.add(root)
        while work:
            node, children = work[-1]
            advanced = False
            for child in children:
                if child not in index:
                    index[child] = low[child] = counter[0]
                    counter[0] += 1
                    stack.append(child)
                    on_stack.add(child)
                    work.append((child, iter(successors.get(child, ()))))
                    advanced = True
                    break
                if child in on_stack:
                    low[node] = min(low[node], index[child])
            if advanced:
                continue
            work.pop()
            if work:
                low[work[-1][0]] = min(low[work[-1][0]], low[node])
            if low[node] == index[node]:
                component = set()
                while True:
                    member = stack.pop()
                    on_stack.discard(member)
                    component.add(member)
                    if member == node:
                        break
                components.append(component)
    return components


def _cyclic(edges: list[Edge]) -> set[tuple[str, str]]:
    """The (source, target) pairs of ``edges`` that lie on a cycle of the graph they form."""
    successors = {}
    for edge in edges:
        successors.setdefault(edge.source, set()).add(edge.target)
    component_of = {}
    for number, component in enumerate(_strongly_connected(sorted(successors), successors)):
        for member in component:
            component_of[member] = number
    return {(e.source, e.target) for e in edges
            if e.source in component_of and component_of.get(e.target) == component_of[e.source]}


def _subpackage(module: str, packages: set[str]) -> str:
    """The subpackage of the library that holds ``module`` (``module`` itself at the top level)."""
    parts = module.split(".")
    return ".".join(parts[:2]) if len(parts) > 2 and ".".join(parts[:2]) in packages else module


def cycle_violations(edges: list[Edge], packages: set[str] = frozenset()) -> list[Violation]:
    """Import cycles, one violation per edge that closes one.

    ``cycle``: an edge on a cycle of module-level imports (the cycle exists at import time).
    ``lazy cycle``: a deferred import (in a function or under TYPE_CHECKING) on a cycle of the
    whole graph; the module-level edges of such a cycle are not listed, the deferred one hides it.
    ``package cycle``: an import from one subpackage into another (``packages``, e.g. ``ctmm.planar``)
    on a cycle of the graph whose nodes are subpackages and top-level modules, when no module cycle
    above already contains it.
    """
    eager = _cyclic([e for e in edges if not e.lazy])
    every = _cyclic(edges)
    collapsed = [Edge(_subpackage(e.source, packages), _subpackage(e.target, packages), e.lazy, e.where)
                 for e in edges]
    between = _cyclic([e for e in collapsed if e.source != e.target])
    found = {}
    for edge, short in zip(edges, collapsed):
        pair = (edge.source, edge.target)
        if pair in eager:
            kind, key = "cycle", f"{edge.source} -> {edge.target}"
        elif edge.lazy and pair in every:
            kind, key = "lazy cycle", f"{edge.source} -> {edge.target}"
        elif (short.source, short.target) in between and short.source in packages and short.target in packages \
                and pair not in every:
            kind, key = "package cycle", f"{short.source} -> {short.target}"
        else:
            continue
        found.setdefault((kind, key), Violation(kind, key, edge.where))
    return list(found.values())


def all_violations(sources=SOURCES, **options) -> tuple[list[Violation], dict]:
    """Every violation of the scanned folders and the line count of every module."""
    modules = module_files(sources)
    violations, edges, lines = scan(modules, **options)
    packages = {name for name, path in modules.items() if _is_package(path) and name.count(".") == 1}
    return violations + cycle_violations(edges, packages), lines


# --------------------------------------------------------------------------------------------------
# Today's violations: this list may only shrink (issue 12, docs/plans/one_core.md §1.5-1.7, §5)
# --------------------------------------------------------------------------------------------------
ALLOWED: dict[tuple[str, str], str] = {
    # import cycles (plan §1.5; frequency <-> natural and results -> ctmm removed in S1d)
    # private names imported across modules (plan §1.6; removed by S1c/S1d)
    # modules over MAX_LINES lines (plan §4 splits or deletes each)
    ("long module", "ctmm.flexible.beam"): "modal beam description and its terms in one file (S: elements/modal_beam)",
    ("long module", "ctmm.natural"): "natural frequencies, counting and mode shapes in one file (S: counting.py)",
    ("long module", "ctmm.planar.model"): "planar model description and its array compilation in one file",
    ("long module", "ctmm.reference.chain"): "independent global-matrix chain model (reference: split when touched)",
    ("long module", "ctmm.reference.dde"): "independent DDE references (reference: split when touched)",
    ("long module", "ctmm.roots"): "characteristic-root search (moves into stability/ in the plan)",
    ("long module", "ctmm.stability"): "margins, roots wrappers and cross-checks in one file (stability/ package)",
    ("long module", "ctmm.stability_chart"): "chart construction, boundary tracing and verification (stability/chart)",
}

#: Allowlisted long modules and their line count when they were listed: they may not grow.
LONG_MODULES: dict[str, int] = {
    "ctmm.flexible.beam": 644,
    "ctmm.natural": 708,
    "ctmm.planar.model": 671,
    "ctmm.reference.chain": 641,
    "ctmm.reference.dde": 611,
    "ctmm.roots": 605,
    "ctmm.stability": 617,
    "ctmm.stability_chart": 710,
}


# --------------------------------------------------------------------------------------------------
# Tests on the code base
# --------------------------------------------------------------------------------------------------
@pytest.fixture(scope="module")
def found():
    violations, lines = all_violations()
    return violations, lines


def _listing(violations) -> str:
    return "\n".join(f"  {v.kind}: {v.key}   ({v.where})" for v in sorted(violations, key=lambda v: (v.kind, v.key)))


def test_no_new_violations(found):
    violations, _ = found
    new = [v for v in violations if (v.kind, v.key) not in ALLOWED]
    assert not new, (
        "architecture rules broken (see tests/test_architecture.py and docs/architecture.md); fix the "
        "code, do not extend the allowlist:\n" + _listing(new))


def test_allowlist_has_no_stale_entries(found):
    violations, _ = found
    present = {(v.kind, v.key) for v in violations}
    stale = sorted(key for key in ALLOWED if key not in present)
    assert not stale, ("these allowlisted violations no longer exist; delete their entries from "
                       "ALLOWED in tests/test_architecture.py:\n" + "\n".join(f"  {k}: {v}" for k, v in stale))


def test_long_modules_do_not_grow(found):
    _, lines = found
    assert set(LONG_MODULES) == {key for kind, key in ALLOWED if kind == "long module"}
    grown = {m: (lines[m], limit) for m, limit in LONG_MODULES.items() if m in lines and lines[m] > limit}
    assert not grown, ("allowlisted long modules grew (split them instead; lower the recorded count when "
                       "they shrink): " + ", ".join(f"{m}: {n} > {limit} lines" for m, (n, limit) in grown.items()))


def test_version_module_matches_pyproject():
    """``ctmm.version`` (read by results' provenance without importing the package) is the packaged version."""
    import tomllib

    from ctmm.version import __version__
    import ctmm

    declared = tomllib.loads((ROOT / "pyproject.toml").read_text(encoding="utf-8"))["project"]["version"]
    assert __version__ == declared == ctmm.__version__


def test_every_allowlist_entry_has_a_reason():
    kinds = {"cycle", "lazy cycle", "package cycle", "private import", "reference import",
             "reference dependency", "star import", "long module"}
    for (kind, key), reason in ALLOWED.items():
        assert kind in kinds, (kind, key)
        assert isinstance(reason, str) and len(reason.strip()) > 10 and "\n" not in reason, (kind, key)


# --------------------------------------------------------------------------------------------------
# Tests of the scanner itself, on a small synthetic package (each rule must be able to fail)
# --------------------------------------------------------------------------------------------------
def _package(tmp_path: Path, files: dict[str, str]) -> list[tuple[str, Path]]:
    for name, text in files.items():
        path = tmp_path / "lib" / name
        path.parent.mkdir(parents=True, exist_ok=True)
        path.write_text(textwrap.dedent(text))
    return [("lib", tmp_path / "lib")]


def _kinds(tmp_path, files, **options) -> set[tuple[str, str]]:
    violations, _ = all_violations(_package(tmp_path, files), reference="lib.reference", library="lib",
                                   reference_may_import=("lib.errors",), **options)
    return {(v.kind, v.key) for v in violations}


def test_scanner_finds_every_rule(tmp_path):
    found = _kinds(tmp_path, {
        "__init__.py": "",
        "a.py": "from .b import value\n",
        "b.py": "from lib.a import other\n",
        "c.py": "def f():\n    from . import d\n",
        "d.py": "from typing import TYPE_CHECKING\nif TYPE_CHECKING:\n    from .e import x\nimport lib.c\n",
        "e.py": "from .d import _hidden\nfrom os.path import *\n",
        "long.py": "x = 1\n" * 12,
        "user.py": "def g():\n    import lib.reference.model\n",
        "reference/__init__.py": "",
        "reference/model.py": "from lib.reference import helper\n",
        "reference/helper.py": "from lib.a import value\nfrom lib.errors import Bad\n",
        "errors.py": "class Bad(Exception):\n    pass\n",
        "p/__init__.py": "", "p/one.py": "from lib.q.two import y\n", "p/three.py": "z = 1\n",
        "q/__init__.py": "", "q/two.py": "def h():\n    from lib.p.three import z\n",
    }, max_lines=10)
    assert found == {
        ("cycle", "lib.a -> lib.b"), ("cycle", "lib.b -> lib.a"),
        ("lazy cycle", "lib.c -> lib.d"), ("lazy cycle", "lib.d -> lib.e"),
        ("package cycle", "lib.p -> lib.q"), ("package cycle", "lib.q -> lib.p"),
        ("private import", "lib.e: _hidden from lib.d"), ("star import", "lib.e: from os.path import *"),
        ("long module", "lib.long"), ("reference import", "lib.user: lib.reference.model"),
        ("reference dependency", "lib.reference.helper: lib.a"),
    }


def test_import_scan_finds_imports_in_every_statement_context():
    """The scan descends statement fields only: on a module with an import in every place the grammar allows one,
    it finds each import that :func:`ast.walk` (every node) finds, with the right lazy flag."""
    source = textwrap.dedent("""
        import a0
        from typing import TYPE_CHECKING
        if TYPE_CHECKING:
            import lazy1
        else:
            import a2
        if a0:
            import a3
        elif a0:
            import a4
        else:
            import a5
        for _ in a0:
            import a6
        else:
            import a7
        while a0:
            import a8
        else:
            import a9
        with a0:
            import a10
        try:
            import a11
        except ImportError:
            import a12
        else:
            import a13
        finally:
            import a14
        try:
            import a15
        except* ImportError:
            import a16
        match a0:
            case 1:
                import a17
        class C:
            import a18
            def method(self):
                import lazy19
        def f(g=lambda: 0):
            import lazy20
            class Inner:
                import lazy21
        async def h():
            import lazy22
            async with a0:
                import lazy23
            async for _ in a0:
                import lazy24
    """)
    tree = ast.parse(source)
    walked = {node.names[0].name for node in ast.walk(tree) if isinstance(node, (ast.Import, ast.ImportFrom))}
    found = {node.names[0].name: lazy for node, lazy in _imports(tree)}
    assert set(found) == walked and len(walked) == 26
    assert {name for name, lazy in found.items() if lazy} == {name for name in walked if name.startswith("lazy")}


def test_scanner_accepts_clean_code(tmp_path):
    assert _kinds(tmp_path, {
        "__init__.py": "from .b import value\n__all__ = ['value']\n",
        "a.py": "import numpy as np\nfrom . import b\nfrom .b import __version__\n",
        "b.py": "value = 1\n__version__ = '1'\n",
        "errors.py": "class Bad(Exception):\n    pass\n",
        "reference/__init__.py": "from lib.errors import Bad\nfrom . import model\n",
        "reference/model.py": "import numpy\nfrom ..errors import Bad\n",
    }) == set()


def test_every_module_is_on_the_architecture_page():
    """``docs/architecture.md`` §2 names every module of the package (``planar/model`` for ``ctmm.planar.model``), so
    the page keeps matching the code: a new module gets its row (or a place in one) in the commit that adds it."""
    import pkgutil

    import ctmm

    text = (Path(__file__).resolve().parents[1] / "docs" / "architecture.md").read_text(encoding="utf-8")
    missing = [info.name for info in pkgutil.walk_packages(ctmm.__path__, "ctmm.")
               if not info.ispkg and info.name[len("ctmm."):].replace(".", "/") not in text]
    assert missing == [], f"modules not named on docs/architecture.md: {missing}"
