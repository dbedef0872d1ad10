"""Import ``ctmm.controllers`` in tests, also before the package-dir mapping is installed.

The repository folder ``controllers/`` is installed as ``ctmm.controllers`` (pyproject
``[tool.setuptools.package-dir]``).  In a checkout without that mapping this helper loads the
folder by path and registers it under the same name, so tests never import a top-level
``controllers`` package.
"""
from __future__ import annotations

import importlib
import importlib.util
import sys
from pathlib import Path
from types import ModuleType

_NAME = "ctmm.controllers"


def load_controllers() -> ModuleType:
    """Return the ``ctmm.controllers`` module (installed mapping first, repository folder otherwise)."""
    try:
        return importlib.import_module(_NAME)
    except ModuleNotFoundError as exc:
        if exc.name != _NAME:  # a real missing dependency inside the package: do not mask it
            raise
    import ctmm

    folder = Path(__file__).resolve().parents[1] / "controllers"
    spec = importlib.util.spec_from_file_location(_NAME, folder / "__init__.py",
                                                  submodule_search_locations=[str(folder)])
    if spec is None or spec.loader is None:
        raise ImportError(f"cannot load {_NAME} from {folder}")
    module = importlib.util.module_from_spec(spec)
    sys.modules[_NAME] = module
    try:
        spec.loader.exec_module(module)
    except BaseException:
        sys.modules.pop(_NAME, None)
        raise
    ctmm.controllers = module  # type: ignore[attr-defined]
    return module
