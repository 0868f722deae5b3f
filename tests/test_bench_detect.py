"""``swarmpose bench detect``: MediaPipe Pose's time per frame, and the install hint without MediaPipe."""

from __future__ import annotations

import json
from pathlib import Path

import pytest
from typer.testing import CliRunner

from swarmpose.cli.app import app

VIDEO = Path(__file__).resolve().parents[2] / "shared" / "data" / "recordings" / "pose2sim-demo-single" / "videos" \
    / "cam01.mp4"
KEYS = {"source", "kind", "view", "frames", "width", "height", "ms_per_frame_median", "ms_per_frame_mean",
        "frames_per_s", "startup_ms", "found_rate", "detector", "mediapipe", "model_complexity", "segmentation",
        "cpu_count"}


def _check(data: dict, kind: str) -> None:
    assert set(data) == KEYS
    assert data["kind"] == kind and data["frames"] == 3 and data["model_complexity"] == 1
    for key in ("width", "height", "ms_per_frame_median", "ms_per_frame_mean", "frames_per_s", "startup_ms"):
        assert data[key] > 0, key
    assert 0 <= data["found_rate"] <= 1


def test_bench_detect_times_a_video():
    pytest.importorskip("mediapipe", reason="MediaPipe is not installed (pip install 'swarmpose[detect]')")
    if not VIDEO.is_file():
        pytest.skip(f"the Pose2Sim demo recording is not at {VIDEO} (../shared beside the repo)")
    res = CliRunner().invoke(app, ["bench", "detect", str(VIDEO), "--frames", "3", "--json"])
    assert res.exit_code == 0, res.output
    data = json.loads(res.stdout)
    _check(data, "video")
    assert data["view"] is None and data["found_rate"] == 1.0  # the person stands in the middle of cam01


def test_bench_detect_times_a_sequence_view(mocap_dir: Path, tmp_path: Path):
    pytest.importorskip("mediapipe", reason="MediaPipe is not installed (pip install 'swarmpose[detect]')")
    from swarmpose.synth.synthesize import synthesize

    seq = tmp_path / "walk"
    synthesize(mocap_dir / "cmu_16_16_walk.bvh", seq, fps=60, seed=0, max_frames=3, measure=False, progress=False)
    res = CliRunner().invoke(app, ["bench", "detect", str(seq), "--frames", "5", "--view", "1", "--json"])
    assert res.exit_code == 0, res.output
    data = json.loads(res.stdout)
    _check(data, "sequence")  # 5 asked, the sequence has 3
    assert data["view"] == "BW2" and (data["width"], data["height"]) == (644, 484)
    bad = CliRunner().invoke(app, ["bench", "detect", str(seq), "--view", "4", "--json"])
    assert bad.exit_code == 2 and "4 views" in json.loads(bad.stdout)["error"]


def test_bench_detect_without_mediapipe_says_how_to_install(no_mediapipe, tmp_path: Path):
    missing = tmp_path / "none.mp4"  # never read: the hint comes first
    res = CliRunner().invoke(app, ["bench", "detect", str(missing), "--frames", "3", "--json"])
    assert res.exit_code == 2, res.output
    error = json.loads(res.stdout)["error"]
    assert "pip install 'swarmpose[detect]'" in error and "mediapipe==0.10.14" in error
    plain = CliRunner().invoke(app, ["bench", "detect", str(missing)])
    assert plain.exit_code == 2 and "swarmpose[detect]" in " ".join(plain.output.split())
