"""``swarmpose datasets check``: what it finds, what it reports, and its exit code."""

from __future__ import annotations

import json
import shutil
from pathlib import Path

import pytest
from typer.testing import CliRunner

from swarmpose.cli.app import app
from swarmpose.datasets.check import check_dataset


def _run(*args: str) -> tuple[int, dict]:
    res = CliRunner().invoke(app, ["datasets", "check", *args, "--json"])
    return res.exit_code, json.loads(res.stdout)


def test_good_release_and_subject(he1_clean):
    he1 = he1_clean
    code, out = _run(str(he1.root))
    assert code == 0, out["problems"]
    assert out["ok"] is True and out["kind"] == "humaneva-release" and out["problems"] == []
    assert out["cameras"] == ["C1", "C2", "C3", "BW1", "BW2", "BW3", "BW4"]
    assert out["sequences"] == ["S1/Dance_1"]
    code, out = _run(str(he1.subject_dir))
    assert code == 0 and out["kind"] == "humaneva-subject" and len(out["cameras"]) == 7


def test_humaneva_ii_subject(he2_clean, he2):
    code, out = _run(str(he2_clean.subject_dir))
    assert code == 0, out["problems"]
    assert out["cameras"] == ["C1", "C2", "C3", "C4"] and out["sequences"] == ["S4/Combo_5"]
    code, out = _run(str(he2.subject_dir))  # Combo_4 is the official test sequence: frames 2-1258
    assert code == 1 and out["problems"] == [
        "S4/Image_Data: Combo_4: the test partition needs synchronized frames 2-1258, but the video of C1 ends at "
        "synchronized frame 20 (truncated file, or sync offsets that do not match)"]


def test_broken_files_are_each_reported(he1_copy):
    sd = he1_copy.subject_dir
    lines = (sd / "Calibration_Data" / "C2.cal").read_text().splitlines()
    lines[4] = "skew?"
    (sd / "Calibration_Data" / "C2.cal").write_text("\n".join(lines))
    (sd / "Calibration_Data" / "BW4.cal").unlink()
    (sd / "Sync_Data" / "Walking_1_(C3).ofs").write_text("9 5")
    (sd / "Image_Data" / "Walking_1_(BW2).avi").unlink()
    (sd / "Mocap_Data" / "S1.mp").write_text("$LKneeWidth = 100\n")
    for f in (he1_copy.root / "Background").glob("*_(C1).avi"):
        f.unlink()
    code, out = _run(str(he1_copy.root))
    assert code == 1 and out["ok"] is False
    problems = out["problems"]

    def has(prefix: str, text: str) -> bool:
        return any(p.startswith(prefix) and text in p for p in problems)

    assert has("S1/Calibration_Data/C2.cal", "line 5, field 'alpha_c': not a number: 'skew?'"), problems
    assert has("S1/Calibration_Data/BW4.cal", "missing calibration of camera BW4")
    assert has("S1/Sync_Data/Walking_1_(C3).ofs", "truncated: 2 of 3 numbers")
    assert has("S1/Image_Data/Walking_1_(BW2).avi", "missing video of camera BW2")
    assert has("S1/Mocap_Data/S1.mp", "'RKneeWidth'")
    assert has("Background/Background_*_(C1).avi", "missing background footage of camera C1")
    assert "C2" not in out["cameras"] and "BW4" not in out["cameras"] and "C1" in out["cameras"]


def test_truncated_video_and_short_partition(he1_copy, tmp_path):
    sd = he1_copy.subject_dir
    data = (sd / "Image_Data" / "Walking_1_(C1).avi").read_bytes()
    (sd / "Image_Data" / "Walking_1_(C1).avi").write_bytes(data[: len(data) // 3])
    report = check_dataset(sd)
    assert not report.ok
    assert any(p.startswith("S1/Image_Data/Walking_1_(C1).avi") for p in report.problems), report.problems
    # the official Validate partition (frames 6-590) is far beyond the tiny fixture
    assert any("validate partition needs synchronized frames 6-590" in p for p in report.problems)
    # the fixture's offsets are not the published post-update values: a note, not a problem
    assert any("critical OFS update" in n for n in report.notes)


def test_mocap_problems(he1_copy):
    sd = he1_copy.subject_dir
    (sd / "Mocap_Data" / "Walking_1.mat").write_bytes(b"garbage")
    report = check_dataset(sd)
    assert any(p.startswith("S1/Mocap_Data/Walking_1.mat: not a readable MATLAB") for p in report.problems)
    (sd / "Mocap_Data" / "Walking_1.mat").unlink()
    (sd / "Mocap_Data" / "Walking_1.c3d").unlink()
    report = check_dataset(sd)
    assert any(p.startswith("S1/Mocap_Data/Walking_1.c3d: missing mocap") for p in report.problems)


def test_leewalk_and_unknown_folders(leewalk_root, tmp_path):
    code, out = _run(str(leewalk_root))
    assert code == 0, out["problems"]
    assert out["kind"] == "leewalk" and out["cameras"] == ["cam1", "cam2", "cam3", "cam4"]
    assert any("differ from the published 532" in n for n in out["notes"])
    broken = tmp_path / "lee"
    shutil.copytree(leewalk_root, broken)
    (broken / "calibration" / "cam2.cal").write_text("1 2 3")
    shutil.rmtree(broken / "images" / "cam4")
    shutil.rmtree(broken / "silhouettes" / "cam4")
    code, out = _run(str(broken))
    assert code == 1
    assert any(p.startswith("calibration/cam2.cal") and "truncated" in p for p in out["problems"])
    assert any(p.startswith("images of camera 4: missing") for p in out["problems"])
    (tmp_path / "empty").mkdir()
    code, out = _run(str(tmp_path / "empty"))
    assert code == 1 and out["kind"] == "unknown" and "not a HumanEva release" in out["problems"][0]
    code, out = _run(str(tmp_path / "absent"))
    assert code == 1 and out["problems"] == [f"{tmp_path / 'absent'}: no such folder"]


@pytest.mark.parametrize("as_json", [False, True])
def test_human_readable_output(he1_copy, as_json):
    (he1_copy.subject_dir / "Calibration_Data" / "C1.cal").write_text("[red]1 2[/red]")
    args = ["datasets", "check", str(he1_copy.root)] + (["--json"] if as_json else [])
    res = CliRunner().invoke(app, args)
    assert res.exit_code == 1
    if not as_json:
        assert "problem" in res.stdout and "S1/Calibration_Data/C1.cal" in res.stdout
        assert "[red]1" in res.stdout  # file content is shown literally, not as markup
        assert "(s)" not in res.stdout and res.stdout.rstrip().endswith(("1 problem", "problems"))


def test_relative_paths(he1_clean, monkeypatch):
    monkeypatch.chdir(he1_clean.root)
    report = check_dataset(Path("S1"))
    assert report.ok, report.problems
    (Path("S1") / "Sync_Data" / "Dance_1_(C1).ofs").rename(Path("S1") / "Sync_Data" / "x.ofs")
    try:
        report = check_dataset(Path("S1"))
        assert "S1/Sync_Data/Dance_1_(C1).ofs: missing sync file of camera C1" in report.problems
    finally:
        (Path("S1") / "Sync_Data" / "x.ofs").rename(Path("S1") / "Sync_Data" / "Dance_1_(C1).ofs")
