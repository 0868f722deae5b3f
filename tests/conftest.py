"""Shared test fixtures: paths to the shared motion-capture clips, and the repository's scripts as modules."""

from __future__ import annotations

from pathlib import Path

import pytest

REPO = Path(__file__).resolve().parents[1]
SHARED = REPO.parent / "shared"
MOCAP = SHARED / "data" / "mocap"


def _load_script(name: str):
    import importlib.util

    spec = importlib.util.spec_from_file_location(name, REPO / "scripts" / f"{name}.py")
    module = importlib.util.module_from_spec(spec)
    spec.loader.exec_module(module)
    return module


@pytest.fixture(scope="session")
def load_script():
    """``load_script(name)``: ``scripts/<name>.py`` imported as a module (the scripts are not a package)."""
    return _load_script


@pytest.fixture(scope="session")
def mocap_dir() -> Path:
    if not MOCAP.is_dir():
        pytest.skip(f"shared motion capture not found at {MOCAP} (../shared beside the repo)")
    return MOCAP


@pytest.fixture(scope="session")
def walk_clip_path(mocap_dir: Path) -> Path:
    return mocap_dir / "cmu_16_16_walk.bvh"


@pytest.fixture()
def no_mediapipe(monkeypatch):
    """MediaPipe made unimportable for one test (whether or not this environment has it)."""
    import builtins
    import sys

    real_import = builtins.__import__

    def refuse(name, *args, **kwargs):
        if name == "mediapipe" or name.startswith("mediapipe."):
            raise ModuleNotFoundError(f"No module named {name!r}")
        return real_import(name, *args, **kwargs)

    monkeypatch.setattr(builtins, "__import__", refuse)
    for name in [n for n in sys.modules if n == "mediapipe" or n.startswith("mediapipe.")]:
        monkeypatch.delitem(sys.modules, name)
