"""The installed package holds every subpackage and data file the repository has (a wheel, not only an editable
install).

Found at the end of session 6: ``ctmm.spatial`` and ``ctmm.fem`` were missing from ``[tool.setuptools] packages``, so
``pip install .`` (a wheel) installed a ctmm without them while the editable install of the test suite worked.  The
first test keeps the list complete without building anything; the second builds the wheel and reads its contents.
"""
from __future__ import annotations

import subprocess
import sys
import zipfile
from pathlib import Path

import pytest

try:
    import tomllib
except ModuleNotFoundError:             # python < 3.11
    import tomli as tomllib

ROOT = Path(__file__).resolve().parents[1]


def _configuration() -> dict:
    return tomllib.loads((ROOT / "pyproject.toml").read_text())["tool"]["setuptools"]


def _repository_packages() -> set[str]:
    """Every folder with an ``__init__.py`` below ``ctmm/``, ``controllers/`` and ``scenarios/``, as an import name."""
    found = set()
    for package, folder in _configuration()["package-dir"].items():
        base = ROOT / folder
        for init in base.rglob("__init__.py"):
            relative = init.parent.relative_to(base)
            found.add(".".join((package, *relative.parts)) if relative.parts else package)
    return found


def _data_folders() -> set[str]:
    """Every folder holding a file that ``[tool.setuptools.package-data]`` installs, as an import name (setuptools
    treats such a folder as a namespace package and warns "Package would be ignored" unless it is listed)."""
    configuration = _configuration()
    found = set()
    for package, patterns in configuration["package-data"].items():
        base = ROOT / configuration["package-dir"][package] if package in configuration["package-dir"] else \
            ROOT / configuration["package-dir"]["ctmm"] / Path(*package.split(".")[1:])
        for pattern in patterns:
            for path in base.glob(pattern):
                relative = path.parent.relative_to(base)
                if relative.parts:
                    found.add(".".join((package, *relative.parts)))
    return found


def test_every_subpackage_is_listed_in_pyproject():
    listed = set(_configuration()["packages"])
    expected = _repository_packages() | _data_folders()
    assert sorted(expected - listed) == []
    assert sorted(listed - expected) == []


def test_every_installed_data_folder_is_listed_so_the_build_does_not_warn():
    """The data folders (FMU sources, scene files) are listed as packages; the wheel build warned 12 times
    ("Python recognizes 'ctmm.controllers.fmu.pd_controller' as an importable package ... absent from packages")."""
    folders = _data_folders()
    assert {"ctmm.scenarios.files", "ctmm.controllers.fmu_common", "ctmm.controllers.fmu.pd_controller.sources"} <= folders
    assert sorted(folders - set(_configuration()["packages"])) == []


@pytest.mark.skipif(not (ROOT / ".git").exists(), reason="builds the wheel from the repository checkout")
def test_the_wheel_holds_every_module_of_the_repository(tmp_path):
    """``pip wheel`` (no dependencies, isolated build) of a fresh copy of the checkout's files (no stale ``build/``
    folder can fill the gaps) and compare its ``ctmm/**/*.py`` with the tree's."""
    import shutil

    listed = subprocess.run(["git", "ls-files", "-co", "--exclude-standard"], cwd=ROOT, capture_output=True, text=True)
    if listed.returncode != 0:
        pytest.skip(f"git cannot list the checkout: {listed.stderr.strip()[-200:]}")
    source = tmp_path / "source"
    for name in listed.stdout.splitlines():
        origin = ROOT / name
        if origin.is_file():
            (source / name).parent.mkdir(parents=True, exist_ok=True)
            shutil.copy2(origin, source / name)
    built = subprocess.run([sys.executable, "-m", "pip", "wheel", "--quiet", "--no-deps", "-w", str(tmp_path / "wheel"),
                            str(source)], capture_output=True, text=True)
    if built.returncode != 0:
        pytest.skip(f"the wheel cannot be built here: {built.stderr.strip()[-300:]}")
    wheel = next((tmp_path / "wheel").glob("ctmm-*.whl"))
    with zipfile.ZipFile(wheel) as archive:
        inside = {name for name in archive.namelist() if name.endswith(".py") and name.startswith("ctmm/")}
    expected = set()
    for package, folder in _configuration()["package-dir"].items():
        base = ROOT / folder
        prefix = package.replace(".", "/")
        for path in base.rglob("*.py"):
            if any(part.startswith(".") or part in ("build", "__pycache__") for part in path.relative_to(base).parts):
                continue
            if (path.parent / "__init__.py").exists():
                expected.add(f"{prefix}/{path.relative_to(base).as_posix()}")
    missing = sorted(expected - inside)
    assert missing == [], f"modules missing from the wheel: {missing[:20]}"
