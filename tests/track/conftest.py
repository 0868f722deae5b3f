"""A short synthesised sequence shared by the tracking tests."""

from __future__ import annotations

from pathlib import Path

import pytest


@pytest.fixture(scope="session")
def short_sequence(tmp_path_factory, mocap_dir: Path) -> Path:
    """The first 0.2 s (12 frames at 60 fps) of the walking clip, synthesised once per session."""
    from swarmpose.synth.synthesize import synthesize

    out = tmp_path_factory.mktemp("seq") / "walk12"
    synthesize(mocap_dir / "cmu_16_16_walk.bvh", out, fps=60, seed=0, max_frames=12, measure=False,
               progress=False)
    return out
