"""The examples in the docstrings run, so they cannot go stale."""

from __future__ import annotations

import doctest
import importlib
from pathlib import Path

import pytest

ROOT = Path(__file__).resolve().parents[1]
#: package folder -> import name (pyproject's package-dir)
PACKAGES = {"ipm": "ipm", "render": "ipm.render", "nets": "ipm.nets", "refine": "ipm.refine"}
MODULES = sorted(f"{name}.{path.stem}" if path.stem != "__init__" else name
                 for folder, name in PACKAGES.items()
                 for path in (ROOT / folder).glob("*.py") if ">>>" in path.read_text())


@pytest.mark.parametrize("module", MODULES)
def test_docstring_examples(module):
    result = doctest.testmod(importlib.import_module(module), optionflags=doctest.ELLIPSIS)
    assert result.attempted and not result.failed
