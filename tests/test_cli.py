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
    written = (tmp_path / "fit.npz").stat().st_mtime_ns
    again = CliRunner().invoke(app, ["ik", str(clip), "--out", str(tmp_path / "fit"), "--json"])
    assert again.exit_code == 2 and "fit.npz and" in json.loads(again.stdout)["error"]  # names both files
    assert "--force" in json.loads(again.stdout)["error"] and (tmp_path / "fit.npz").stat().st_mtime_ns == written
    (tmp_path / "fit.npz").unlink()  # the .subject.json alone is refused too
    again = CliRunner().invoke(app, ["ik", str(clip), "--out", str(tmp_path / "fit.npz"), "--json"])
    assert again.exit_code == 2 and "fit.subject.json exists" in json.loads(again.stdout)["error"]
    forced = CliRunner().invoke(app, ["ik", str(clip), "--out", str(tmp_path / "fit.npz"), "--force", "--json"])
    assert forced.exit_code == 0, forced.output
    assert (tmp_path / "fit.npz").is_file()
    bad = CliRunner().invoke(app, ["ik", str(clip), "--out", str(tmp_path)])
    assert bad.exit_code == 2 and "is a folder" in " ".join(bad.output.split())
    bad = CliRunner().invoke(app, ["ik", str(clip), "--out", str(tmp_path / "new") + "/"])  # a folder meant
    assert bad.exit_code == 2 and "is a folder" in " ".join(bad.output.split()) and not (tmp_path / "new").exists()


def test_help_keeps_the_bracketed_forms():
    text = " ".join(CliRunner().invoke(app, ["track", "--help"], env={"COLUMNS": "250"}).output.split())
    assert "SeedSequence([seed, k])" in text and "constant-velocity[:D][@GROUP+...]" in text
    assert "pip install 'swarmpose[torch]'" in text and "pip install 'swarmpose[dask]'" in text


def test_no_help_text_has_a_bracket_that_rich_would_take_for_a_style_tag():
    """Rich reads ``[word]`` in a help text as markup and drops it (``pip install 'swarmpose[torch]'`` came
    out as ``'swarmpose'``); such brackets must be written ``\\[word]``."""
    import re

    import click
    import typer

    tag = re.compile(r"(?<!\\)\[[a-zA-Z#/@]")

    def texts(cmd: click.Command, path: str):
        yield path, cmd.help or ""
        for p in cmd.params:
            yield f"{path} {p.name}", getattr(p, "help", None) or ""
        for name, sub in getattr(cmd, "commands", {}).items():
            yield from texts(sub, f"{path} {name}")

    bad = [(where, t) for where, t in texts(typer.main.get_command(app), "swarmpose") if tag.search(t)]
    assert not bad


def test_errors_under_json_print_one_error_object(tmp_path: Path):
    """--json promises one JSON object on stdout: a failing command prints {"error", "exit_code"} there
    (and the message on stderr); without --json stdout stays empty."""
    runner = CliRunner()
    missing = tmp_path / "none.bvh"
    for args in (["info", str(missing)], ["report", str(tmp_path)]):
        res = runner.invoke(app, [*args, "--json"])
        assert res.exit_code == 2, res.output
        data = json.loads(res.stdout)
        assert set(data) == {"error", "exit_code"} and data["exit_code"] == 2
        assert str(tmp_path) in data["error"] and "error:" in res.stderr
        plain = runner.invoke(app, args)
        assert plain.exit_code == 2 and plain.stdout == ""


def test_info_warns_about_an_implausible_unit(mocap_dir: Path):
    """--unit m on a CMU clip (about 25 units tall) makes a 25 m person: info says so."""
    clip = str(mocap_dir / "cmu_16_16_walk.bvh")
    runner = CliRunner()
    ok = json.loads(runner.invoke(app, ["info", clip, "--json"]).stdout)
    assert 1300 < ok["rest_height_mm"] < 1600 and ok["warnings"] == []
    bad = runner.invoke(app, ["info", clip, "--unit", "m", "--json"])
    assert bad.exit_code == 0
    data = json.loads(bad.stdout)
    assert data["rest_height_mm"] > 20_000 and "is --unit right?" in data["warnings"][0]
    plain = runner.invoke(app, ["info", clip, "--unit", "m"])
    assert "not a person's height" in " ".join(plain.stderr.split())
    inch = json.loads(runner.invoke(app, ["info", clip, "--unit", "inch", "--json"]).stdout)  # CMU units are 1/0.45 inch
    assert 600 < inch["rest_height_mm"] < 700 and "is --unit right?" in inch["warnings"][0]


def test_info_and_ik_read_an_exported_file(mocap_dir: Path, tmp_path: Path):
    """`swarmpose export` output goes back into `info` and `ik` (skeleton mapped by name); CMU clips stay CMU."""
    import numpy as np

    from swarmpose.body.model import load_model
    from swarmpose.export import export_bvh

    model = load_model("balan31")
    P = np.tile(model.zero_pose(), (4, 1))
    P[:, model.param_index("pelvis_tz")] = 950.0
    P[:, model.param_index("pelvis_ty")] = np.linspace(0.0, 60.0, 4)
    P[:, model.param_index("l_knee_flex")] = 0.4
    bvh = export_bvh(model, P, 30.0, tmp_path / "m.bvh")
    runner = CliRunner()
    info = json.loads(runner.invoke(app, ["info", str(bvh), "--json"]).stdout)
    assert info["skeleton"] == "swarmpose" and info["unit"] == "mm" and info["frames"] == 4
    assert info["joints15"]["l_knee"]["bvh_joint"] == "l_knee"
    ik = runner.invoke(app, ["ik", str(bvh), "--fps", "30", "--json"])
    assert ik.exit_code == 0, ik.output
    assert json.loads(ik.stdout)["ik_floor_mm"]["mean"] < 0.5  # the model fits its own motion (0.11 mm: the IK's rest prior)
    cmu = json.loads(runner.invoke(app, ["info", str(mocap_dir / "cmu_16_35_jog.bvh"), "--json"]).stdout)
    assert cmu["skeleton"] == "cmu"
    assert cmu["joints15"]["head_top"]["bvh_joint"] == "Head (end site)"  # the point is the Head's end site
    assert cmu["joints15"]["l_knee"]["bvh_joint"] == "LeftLeg"


def test_usage_errors_under_json_print_one_error_object():
    """A bad option value or a missing argument (typer's own checks) also gives the error object under --json."""
    for args, field in ((["compare", "thesis-apf", "--runs", "0"], "--runs"), (["info"], "clip")):
        out = subprocess.run([sys.executable, "-m", "swarmpose", *args, "--json"], capture_output=True, text=True,
                             check=False)
        assert out.returncode == 2, out.stderr
        data = json.loads(out.stdout)
        assert data["exit_code"] == 2 and field in data["error"], data
        assert "Error" in out.stderr  # the usual error box is still shown
    plain = subprocess.run([sys.executable, "-m", "swarmpose", "info"], capture_output=True, text=True, check=False)
    assert plain.returncode == 2 and plain.stdout == ""


def test_paths_with_brackets_and_file_system_errors_are_reported_as_they_are(mocap_dir: Path, tmp_path: Path):
    """Square brackets in a path are not Rich markup; a file where a folder is needed is a clear error (exit 2,
    the JSON error object), not a traceback; a silly --scale is refused before any work."""
    runner = CliRunner()
    odd = tmp_path / "walk[bold]take2.bvh"
    res = runner.invoke(app, ["info", str(odd)])
    assert res.exit_code == 2 and "walk[bold]take2.bvh" in "".join(res.stderr.split())
    blocker = tmp_path / "a_file"
    blocker.write_text("x")
    res = runner.invoke(app, ["ik", str(mocap_dir / "cmu_16_35_jog.bvh"), "--fps", "10",
                              "--out", str(blocker / "fit.npz"), "--json"])
    assert res.exit_code == 2, res.output
    assert json.loads(res.stdout)["error"].startswith(str(blocker))
    for scale in ("1e-4", "inf"):
        res = runner.invoke(app, ["show", str(tmp_path), "--scale", scale])
        assert res.exit_code == 2 and "--scale must lie in [0.05, 8]" in " ".join(res.stderr.split())


def test_compare_list_shows_the_entries_without_running(tmp_path: Path):
    """`compare SUITE --list` prints the suite's validated entries (with the optimiser's evaluations per frame)
    and the number of jobs, and writes nothing; without SUITE every suite; `compare` alone asks for one."""
    from swarmpose.experiments.suites import SUITES, suite

    runner = CliRunner()
    res = runner.invoke(app, ["compare", "thesis-partitions", "--list", "--runs", "3", "--out", str(tmp_path / "o"),
                              "--json"])
    assert res.exit_code == 0, res.output
    data = json.loads(res.stdout)
    (item,) = data["suites"]
    assert item["suite"] == "thesis-partitions" and item["jobs"] == 7 * 3
    assert [e["label"] for e in item["entries"]] == [e.label for e in suite("thesis-partitions")]
    evals = {(e["algo"], e["fps"]): e["evals_per_frame"] for e in item["entries"]}
    assert set(evals.values()) == {1000, 7200} and evals["hpso12", 60.0] == 7200  # thesis Fig. 6.14, at 60 fps
    assert not (tmp_path / "o").exists()
    budget = json.loads(runner.invoke(app, ["compare", "thesis-budget", "--list", "--json"]).stdout)
    assert [e["evals_per_frame"] for e in budget["suites"][0]["entries"]] == [1000, 2000, 4000]  # variants applied
    every = json.loads(runner.invoke(app, ["compare", "--list", "--json"]).stdout)
    assert [s["suite"] for s in every["suites"]] == list(SUITES)
    text = runner.invoke(app, ["compare", "markers", "--list"])
    assert text.exit_code == 0 and "Sharifi" in text.stdout and "apf-dr05" in text.stdout
    res = runner.invoke(app, ["compare", "--json"])
    assert res.exit_code == 2 and "name a suite" in json.loads(res.stdout)["error"]


def test_help_paragraphs_flow_and_flags_show_no_value_placeholder():
    """A docstring paragraph is one paragraph at any width (not re-broken where the source lines end), and on/off
    flags show no `<bool>` value, which they would refuse (`--json true` is an error)."""
    out = subprocess.run([sys.executable, "-m", "swarmpose", "ik", "--help"], capture_output=True, text=True,
                         check=False, env={**__import__("os").environ, "COLUMNS": "250"})
    assert out.returncode == 0
    assert "of the best fit of the model to the ground truth: the error no tracker" in out.stdout
    json_line = next(ln for ln in out.stdout.splitlines() if "--json" in ln)
    assert "<bool>" not in json_line and "<str>" in next(ln for ln in out.stdout.splitlines() if "--unit" in ln)


def test_info_gives_the_facts_of_a_skeleton_it_cannot_map(tmp_path: Path):
    bvh = tmp_path / "two_joints.bvh"
    bvh.write_text("HIERARCHY\nROOT Root\n{\n OFFSET 0 0 0\n CHANNELS 6 Xposition Yposition Zposition Zrotation "
                   "Xrotation Yrotation\n JOINT Arm\n {\n  OFFSET 0 10 0\n  CHANNELS 3 Zrotation Xrotation Yrotation\n"
                   "  End Site\n  {\n   OFFSET 0 5 0\n  }\n }\n}\nMOTION\nFrames: 1\nFrame Time: 0.04\n"
                   + " ".join(["0"] * 9) + "\n")
    res = CliRunner().invoke(app, ["info", str(bvh), "--json"])
    assert res.exit_code == 0, res.output
    data = json.loads(res.stdout)
    assert (data["frames"], data["frame_rate"], data["joints"], data["channels"]) == (1, 25.0, 2, 9)
    assert data["skeleton"] is None and "not CMU-style" in data["warnings"][0]
    plain = CliRunner().invoke(app, ["info", str(bvh)])
    assert "1 frame at 25 fps" in plain.stdout and "cannot be tracked" in " ".join(plain.stderr.split())


def test_ik_warns_about_an_implausible_unit(mocap_dir: Path):
    res = CliRunner().invoke(app, ["ik", str(mocap_dir / "cmu_16_35_jog.bvh"), "--fps", "5", "--unit", "m", "--json"])
    assert res.exit_code == 0, res.output
    assert "is --unit right?" in json.loads(res.stdout)["warnings"][0] and "not a person's height" in res.stderr


def test_negative_seeds_and_missing_clips_are_refused_before_any_work(tmp_path: Path):
    runner = CliRunner()
    for args in (["synth", str(tmp_path / "x.bvh"), "--out", str(tmp_path / "s"), "--seed", "-1"],
                 ["bench", "fitness", "--seed", "-1"],
                 ["compare", "thesis-apf", "--list", "--clip", str(tmp_path / "none.bvh")],
                 ["compare", "thesis-apf", "--list", "--clip", str(tmp_path)]):
        res = runner.invoke(app, [*args, "--json"])
        assert res.exit_code == 2, (args, res.output)
    listing = json.loads(runner.invoke(app, ["compare", "thesis-apf", "--list", "--max-frames", "4", "--json"]).stdout)
    assert listing["max_frames"] == 4
    assert {e["fps"]: e["max_frames"] for e in listing["suites"][0]["entries"]} == {20.0: 4, 60.0: 10}


def test_demo_names_other_code_when_it_reuses_a_folder(tmp_path: Path, monkeypatch):
    """A finished demo folder is reused; when it was tracked by another revision of the source, the reuse
    message says so (old numbers must not pass for the code's)."""
    from swarmpose.cli import demo as demo_module

    monkeypatch.setattr("swarmpose.track.tracker.source_revision", lambda: "b" * 40)
    (tmp_path / "config.json").write_text(json.dumps({"versions": {"swarmpose_git": "a" * 40}}))
    assert demo_module._made_by_other_code(tmp_path) == f"; they were tracked by source {'a' * 12}, this is {'b' * 12}"
    (tmp_path / "config.json").write_text(json.dumps({"versions": {"swarmpose_git": "b" * 40}}))
    assert demo_module._made_by_other_code(tmp_path) == ""
    (tmp_path / "config.json").write_text(json.dumps({"versions": {}}))
    assert "unknown revision" in demo_module._made_by_other_code(tmp_path)


def test_version():
    from swarmpose import __version__

    res = CliRunner().invoke(app, ["--version"])
    assert res.exit_code == 0 and res.stdout.startswith(f"swarmpose {__version__}")


def test_ik_fits_the_model_it_is_given(mocap_dir: Path, tmp_path: Path):
    """--model picks a shipped model or a spec file; full45 (more joints free) fits the joints closer than balan31;
    an unknown name says which models there are."""
    from importlib import resources

    clip = str(mocap_dir / "cmu_16_35_jog.bvh")
    runner = CliRunner()
    floors = {}
    spec_file = tmp_path / "my_model.json"
    spec = json.loads((resources.files("swarmpose.models") / "balan31.json").read_text())
    spec_file.write_text(json.dumps({**spec, "name": "my_balan"}))
    for model, name in (("balan31", "balan31"), ("full45", "full45"), (str(spec_file), "my_balan")):
        res = runner.invoke(app, ["ik", clip, "--model", model, "--fps", "5", "--json"])
        assert res.exit_code == 0, res.output
        data = json.loads(res.stdout)
        floors[model] = data["ik_floor_mm"]["mean"]
        assert data["frames"] == 7 and data["model"] == name
    assert floors["full45"] < 0.5 < floors["balan31"] < 3.0  # 0.10 and 1.29 mm at 10 fps
    assert floors[str(spec_file)] == floors["balan31"]  # the same tree and cones, read from a file
    bad = runner.invoke(app, ["ik", clip, "--model", "nosuch"])
    assert bad.exit_code == 2 and "balan31" in bad.output and "full45" in bad.output
