"""Run the examples in the optim docstrings (they must stay true)."""

from __future__ import annotations

import doctest
import importlib

import pytest

MODULES = ["base", "operators", "pso", "apf", "aapso", "registry", "staged", "schedules", "testfunctions"]


@pytest.mark.parametrize("name", MODULES)
def test_docstring_examples(name):
    module = importlib.import_module(f"swarmpose.optim.{name}")
    result = doctest.testmod(module, optionflags=doctest.ELLIPSIS)
    assert result.failed == 0
