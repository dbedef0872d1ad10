"""The sympy derivations behind docs/ (docs/derivations/*.py) agree with the code.

Each script derives element, boundary, scheme or Riccati relations from first principles and
compares them with what ctmm computes; every ``check_*`` function listed in a script's
``CHECKS`` becomes one test here.
"""
from __future__ import annotations

import importlib.util
from pathlib import Path

import pytest

DERIVATIONS = Path(__file__).resolve().parents[1] / "docs" / "derivations"
SCRIPTS = tuple(sorted(p.stem for p in DERIVATIONS.glob("*.py") if not p.stem.startswith("_")))
EXPECTED = {"lumped", "boundary", "schemes", "riccati"}


def _load(name: str):
    spec = importlib.util.spec_from_file_location(f"ctmm_docs_derivation_{name}", DERIVATIONS / f"{name}.py")
    module = importlib.util.module_from_spec(spec)
    spec.loader.exec_module(module)
    return module


_MODULES: dict = {}


def _module(name: str):
    if name not in _MODULES:
        _MODULES[name] = _load(name)
    return _MODULES[name]


def _cases():
    cases = []
    for name in SCRIPTS:
        for check in _module(name).CHECKS:
            cases.append(pytest.param(name, check.__name__, id=f"{name}.{check.__name__}"))
    return cases


def test_scripts_present_and_checked():
    """The derivation scripts behind the docs exist and each defines at least one check."""
    assert EXPECTED <= set(SCRIPTS), f"missing derivation scripts: {sorted(EXPECTED - set(SCRIPTS))}"
    for name in SCRIPTS:
        assert _module(name).CHECKS, f"docs/derivations/{name}.py defines no CHECKS"


@pytest.mark.parametrize("script, check", _cases())
def test_derivation(script: str, check: str) -> None:
    getattr(_module(script), check)()
