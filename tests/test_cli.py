"""Command-line details a user meets first: ``python -m swarmpose``, output paths as printed."""

from __future__ import annotations

import json
import subprocess
import sys
from pathlib import Path

from typer.testing import CliRunner

from swarmpose.cli.app import app


def test_python_dash_m_runs_the_command():
    out = subprocess.run([sys.executable, "-m", "swarmpose", "--help"], capture_output=True, text=True, check=False)
    assert out.returncode == 0 and "track" in out.stdout


def test_ik_reports_the_file_it_wrote(mocap_dir: Path, tmp_path: Path):
    clip = mocap_dir / "cmu_16_35_jog.bvh"
    out = CliRunner().invoke(app, ["ik", str(clip), "--out", str(tmp_path / "fit"), "--json"])
    assert out.exit_code == 0, out.output
    assert json.loads(out.stdout)["out"] == str(tmp_path / "fit.npz") and (tmp_path / "fit.npz").is_file()
    bad = CliRunner().invoke(app, ["ik", str(clip), "--out", str(tmp_path)])
    assert bad.exit_code == 2 and "is a folder" in " ".join(bad.output.split())


def test_help_keeps_the_bracketed_forms():
    text = " ".join(CliRunner().invoke(app, ["track", "--help"], env={"COLUMNS": "250"}).output.split())
    assert "SeedSequence([seed, k])" in text and "constant-velocity[:D][@GROUP+...]" in text
