"""Every ``>>>`` example in a docstring of the package runs and prints what it shows.

``tests/test_docs.py`` executes the Markdown pages' code blocks; this test is its counterpart for the
numpy-style ``Examples`` sections of the modules (``doctest`` with ``ELLIPSIS`` and
``NORMALIZE_WHITESPACE``), so that a quoted value cannot drift from what the code returns.
"""
from __future__ import annotations

import doctest
import importlib
from pathlib import Path

import pytest

ROOT = Path(__file__).resolve().parents[1]
#: folders of the installed package and their dotted prefix (``controllers/`` is ``ctmm.controllers``)
FOLDERS = ((ROOT / "ctmm", ("ctmm",)), (ROOT / "controllers", ("ctmm", "controllers")))


def modules_with_examples() -> list[str]:
    """Dotted names of the package's modules whose source holds a ``>>>`` example."""
    names = []
    for folder, prefix in FOLDERS:
        for path in sorted(folder.rglob("*.py")):
            if ">>> " not in path.read_text(encoding="utf-8"):
                continue
            parts = prefix + path.relative_to(folder).with_suffix("").parts
            if parts[-1] == "__init__":
                parts = parts[:-1]
            names.append(".".join(parts))
    return names


@pytest.mark.parametrize("module_name", modules_with_examples())
def test_docstring_examples_print_what_they_show(module_name):
    module = importlib.import_module(module_name)
    result = doctest.testmod(module, optionflags=doctest.ELLIPSIS | doctest.NORMALIZE_WHITESPACE,
                             report=False)
    assert result.failed == 0, f"{module_name}: {result.failed} of {result.attempted} examples fail"
