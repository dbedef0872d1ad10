"""The version of the ctmm package (a leaf module: importing it imports nothing else of ctmm).

Kept apart from ``ctmm/__init__.py`` so that library modules (e.g. :mod:`ctmm.results`, which
records it in every result's provenance) read it without importing the whole package.  Keep it
equal to ``version`` in ``pyproject.toml`` (checked by ``tests/test_architecture.py``).
"""
from __future__ import annotations

__version__: str = "0.1.0"
