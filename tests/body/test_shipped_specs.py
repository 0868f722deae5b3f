"""The shipped body-model specs are what scripts/make_model_specs.py writes (no hand edits that the next
run of the script would undo, as the torso's x1.05 once was)."""

from __future__ import annotations

import json
from pathlib import Path

import pytest

MODELS = Path(__file__).resolve().parents[2] / "src" / "swarmpose" / "models"


@pytest.mark.parametrize("name", ["balan31", "full45"])
def test_shipped_spec_is_the_generators(name, load_script):
    gen = load_script("make_model_specs")
    path = MODELS / f"{name}.json"
    built = gen.with_derived_sigmas(getattr(gen, name)(), path)
    assert json.dumps(built, indent=1) + "\n" == path.read_text()
