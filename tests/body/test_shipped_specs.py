"""The shipped body-model specs are what scripts/make_model_specs.py writes (no hand edits that the next
run of the script would undo, as the torso's x1.05 once was)."""

from __future__ import annotations

import importlib.util
import json
from pathlib import Path

import pytest

SCRIPT = Path(__file__).resolve().parents[2] / "scripts" / "make_model_specs.py"
MODELS = Path(__file__).resolve().parents[2] / "src" / "swarmpose" / "models"


@pytest.mark.parametrize("name", ["balan31", "full45"])
def test_shipped_spec_is_the_generators(name):
    spec_ = importlib.util.spec_from_file_location("make_model_specs", SCRIPT)
    gen = importlib.util.module_from_spec(spec_)
    spec_.loader.exec_module(gen)
    path = MODELS / f"{name}.json"
    built = gen.with_derived_sigmas(getattr(gen, name)(), path)
    assert json.dumps(built, indent=1) + "\n" == path.read_text()
