"""The shared real recording: `swarmpose cameras` on its calibration files, and `swarmpose import` of a few frames
with the real detector (skipped where MediaPipe is not installed)."""

from __future__ import annotations

import json
from pathlib import Path

import numpy as np
import pytest
from typer.testing import CliRunner

from swarmpose.cli.app import app
from swarmpose.io.calibration import read_calibration

REC = Path(__file__).resolve().parents[3] / "shared" / "data" / "recordings" / "pose2sim-demo-single"
TOML = REC / "calibration" / "Calib_scene.toml"
QCA = REC / "calibration" / "Calib.qca.txt"

pytestmark = pytest.mark.skipif(not REC.is_dir(), reason=f"the shared recording is not at {REC}")


def test_cameras_prints_converts_and_draws(tmp_path: Path):
    res = CliRunner().invoke(app, ["cameras", str(TOML), "--json", "--picture", str(tmp_path / "rig.png"),
                                   "--convert", str(tmp_path / "intri.yml")])
    assert res.exit_code == 0, res.output
    data = json.loads(res.stdout)
    assert data["format"] == "toml" and [c["name"] for c in data["cameras"]] == [
        "int_cam01_img", "int_cam02_img", "int_cam03_img", "int_cam04_img"]
    first = data["cameras"][0]
    assert (first["width"], first["height"]) == (1088, 1920) and first["fx"] == pytest.approx(1671.5012, abs=1e-3)
    assert 1500 < np.linalg.norm(first["position_mm"]) < 4000 and 10 < first["looking_down_deg"] < 35
    assert (tmp_path / "rig.png").stat().st_size > 10_000
    back = read_calibration(tmp_path / "intri.yml")  # the EasyMocap pair, extri.yml beside it
    for a, b in zip(back.cameras, read_calibration(TOML).cameras, strict=True):
        assert np.allclose(a.R, b.R, atol=1e-9) and np.allclose(a.t, b.t, atol=1e-6) and a.fx == pytest.approx(b.fx)
    table = CliRunner().invoke(app, ["cameras", str(QCA)])
    assert table.exit_code == 0 and "qualisys, units mm (format), up +z (detected)" in table.output
    assert table.output.count("1088x1920") == 4


@pytest.mark.parametrize("calibration", [TOML, QCA], ids=["toml", "qualisys"])
def test_import_of_the_real_recording_agrees_with_its_calibration(calibration: Path, tmp_path: Path):
    pytest.importorskip("mediapipe")
    res = CliRunner().invoke(app, ["import", str(REC / "videos"), "-c", str(calibration), "-o", str(tmp_path / "seq"),
                                   "--stop", "12", "--step", "3", "--scale", "0.25", "--cache-dir",
                                   str(tmp_path / "cache"), "--json"])
    assert res.exit_code == 0, res.output
    data = json.loads(res.stdout.strip().splitlines()[-1])
    assert data["n_frames"] == 4 and data["frame_rate"] == 20 and data["image_size"] == [272, 480]
    assert data["cameras"] == ["cam01", "cam02", "cam03", "cam04"]
    assert all(v <= 25.0 for v in data["residual_px"].values()), data["residual_px"]  # px of the videos
    assert data["frame_residual_max_px"] < 60.0 and data["dropped_view_frames"] == 0
    assert sum("padded by 8 px on the right" in n for n in data["notes"]) == 2  # cam01 and cam02 are 1080 wide
    assert Path(data["page"]).is_file()
