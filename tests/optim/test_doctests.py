"""Run the docstring examples of every module that has them (they must stay true)."""

from __future__ import annotations

import doctest
import importlib

import pytest

#: Every swarmpose module with runnable ``>>>`` examples (the HumanEva one needs the dataset: +SKIP).
MODULES = ["swarmpose.optim", "swarmpose.optim.base", "swarmpose.optim.operators", "swarmpose.optim.pso",
           "swarmpose.optim.apf", "swarmpose.optim.registry", "swarmpose.fitness.image", "swarmpose.render",
           "swarmpose.export.bvh_export"]


@pytest.mark.parametrize("name", MODULES)
def test_docstring_examples(name):
    result = doctest.testmod(importlib.import_module(name), optionflags=doctest.ELLIPSIS)
    assert result.attempted > 0 and result.failed == 0


def test_every_module_with_examples_is_listed():
    from pathlib import Path

    import swarmpose

    root = Path(swarmpose.__file__).parent
    have = set()
    for path in root.rglob("*.py"):
        lines = [ln for ln in path.read_text(encoding="utf-8").splitlines() if ln.strip().startswith(">>>")]
        if lines and not all("doctest: +SKIP" in ln for ln in lines):
            parts = path.relative_to(root.parent).with_suffix("").parts
            have.add(".".join(parts[:-1] if parts[-1] == "__init__" else parts))
    assert have == set(MODULES)
