"""Fixture datasets written once per session in the real HumanEva / Lee walk formats (tiny, synthetic)."""

from __future__ import annotations

import shutil
from pathlib import Path

import pytest
from he_fixtures import Fixture, make_humaneva_i, make_humaneva_ii, make_leewalk


@pytest.fixture(scope="session")
def he1(tmp_path_factory: pytest.TempPathFactory) -> Fixture:
    return make_humaneva_i(tmp_path_factory.mktemp("humaneva_i"))


@pytest.fixture(scope="session")
def he2(tmp_path_factory: pytest.TempPathFactory) -> Fixture:
    return make_humaneva_ii(tmp_path_factory.mktemp("humaneva_ii"))


@pytest.fixture(scope="session")
def he1_clean(tmp_path_factory: pytest.TempPathFactory) -> Fixture:
    """HumanEva-I with an action outside the official partition tables (nothing for check to flag)."""
    return make_humaneva_i(tmp_path_factory.mktemp("humaneva_i_clean"), action="Dance")


@pytest.fixture(scope="session")
def he2_clean(tmp_path_factory: pytest.TempPathFactory) -> Fixture:
    return make_humaneva_ii(tmp_path_factory.mktemp("humaneva_ii_clean"), trial="5")


@pytest.fixture(scope="session")
def leewalk_root(tmp_path_factory: pytest.TempPathFactory) -> Path:
    root = tmp_path_factory.mktemp("leewalk")
    make_leewalk(root)
    return root


@pytest.fixture()
def he1_copy(he1: Fixture, tmp_path: Path) -> Fixture:
    """A private copy of the HumanEva-I fixture that a test may damage."""
    root = tmp_path / "release"
    shutil.copytree(he1.root, root)
    return Fixture(root, root / "S1", he1.action, he1.trial, he1.cameras, he1.offsets, he1.video_frames,
                   he1.backgrounds)
