"""Fixtures of the synthesis tests: the walking clip, its observation body and rig, one short synthesis."""

from __future__ import annotations

from pathlib import Path

import pytest

from swarmpose.io.mocap import MocapClip, load_clip
from swarmpose.synth.body import ObservationBody
from swarmpose.synth.rig import default_rig
from swarmpose.synth.synthesize import SynthReport, synthesize

SHORT_FRAMES = 24
FS_STRIDE = 4


@pytest.fixture(scope="session")
def walk_clip(walk_clip_path: Path) -> MocapClip:
    return load_clip(walk_clip_path, fps=60)


@pytest.fixture(scope="session")
def walk_body(walk_clip: MocapClip) -> ObservationBody:
    return ObservationBody.from_clip(walk_clip)


@pytest.fixture(scope="session")
def walk_rig(walk_clip: MocapClip):
    return default_rig(walk_clip)


@pytest.fixture(scope="session")
def short_walk(walk_clip_path: Path, tmp_path_factory: pytest.TempPathFactory) -> SynthReport:
    """The first 24 frames (0.4 s) of the walking clip, synthesised with default settings, seed 3."""
    out = tmp_path_factory.mktemp("synth") / "walk24"
    return synthesize(walk_clip_path, out, fps=60, seed=3, max_frames=SHORT_FRAMES, fs_stride=FS_STRIDE,
                      progress=False)
