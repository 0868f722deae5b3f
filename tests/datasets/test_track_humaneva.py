"""`swarmpose track humaneva:...` end to end on the small HumanEva-I fixture."""

from __future__ import annotations

import json

import numpy as np
import pytest
from he_fixtures import Fixture
from typer.testing import CliRunner

from swarmpose.cli.app import app


def test_track_accepts_humaneva_sources(he1: Fixture, tmp_path):
    out = tmp_path / "res"
    res = CliRunner().invoke(app, ["track", he1.spec + "?split=all&cams=C1,C2,C3", "--algo", "apf", "--fps", "30",
                                   "--runs", "1", "--workers", "1", "--out", str(out), "--json"])
    assert res.exit_code == 0, res.output
    data = json.loads(res.stdout.strip().splitlines()[-1])
    assert data["algo"] == "apf" and data["frames"] >= 2
    with np.load(out / "run_000" / "joints.npz", allow_pickle=False) as z:  # frames with valid ground truth
        ok = np.isfinite(z["gt_joints"]).all(axis=(1, 2))
        assert data["frames_scored"] == int(ok.sum()) >= 1
        d = np.linalg.norm(z["joints"][ok] - z["gt_joints"][ok], axis=2).mean(axis=1)
    assert data["d_mean_mm"] == pytest.approx(float(d.mean()), rel=1e-9)  # recomputed from joints.npz
    assert data["d_mean_mm"] < 100.0  # measured 49.8 mm on these 3 cameras and few frames
    assert data["ik_floor_mm"] < 1e-6  # the fixture's ground truth is the model's own joints
    # the subject was measured from the 15-joint ground truth (no BVH skeleton for HumanEva)
    subject = json.loads((out / "subject.json").read_text())
    assert "15-joint ground truth" in subject["source"]
    # ... and its cones from the dataset's measurements (static-trial markers + .mp), head included
    assert "cones from measurements" in subject["source"] and "reference" not in subject["source"]
