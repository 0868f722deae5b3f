"""Command-line details a user meets first: ``python -m swarmpose``, output paths as printed."""

from __future__ import annotations

import json
import os
import subprocess
import sys
from pathlib import Path

import numpy as np
import pytest
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


def test_compare_help_names_every_suite():
    from swarmpose.experiments.suites import SUITES

    text = " ".join(CliRunner().invoke(app, ["compare", "--help"], env={"COLUMNS": "250"}).output.split())
    assert [name for name in SUITES if name not in text] == []


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
    """A bad option value, an unknown option or a missing argument (typer's own checks) also gives the error
    object under --json; the last two keep the usual usage box."""
    for args, field in ((["compare", "thesis-apf", "--runs", "0"], "--runs"), (["info"], "clip"),
                        (["compare", "thesis-apf", "--rns", "3"], "--rns")):
        out = subprocess.run([sys.executable, "-m", "swarmpose", *args, "--json"], capture_output=True, text=True,
                             check=False)
        assert out.returncode == 2, out.stderr
        data = json.loads(out.stdout)
        assert data["exit_code"] == 2 and field in data["error"], data
        assert ("Error" in out.stderr) == (field != "--runs")  # the usage box, but for a bad value (one line)
    plain = subprocess.run([sys.executable, "-m", "swarmpose", "info"], capture_output=True, text=True, check=False)
    assert plain.returncode == 2 and plain.stdout == ""


def test_a_bad_option_value_is_one_line_naming_the_option():
    """`--runs 0` printed typer's whole usage box; it is one line naming the option and the value given, exit code
    2, and under --json the usual error object."""
    for args, line in ((["track", "x", "--runs", "0"], "error: --runs 0: must be at least 1"),
                       (["compare", "thesis-apf", "--runs=0"], "error: --runs 0: must be at least 1"),
                       (["track", "x", "--seed", "-1"], "error: --seed -1: must be at least 0"),
                       (["track", "x", "--fps", "abc"], "error: --fps abc: not a valid number")):
        out = subprocess.run([sys.executable, "-m", "swarmpose", *args], capture_output=True, text=True, check=False,
                             env={**os.environ, "COLUMNS": "80"})
        assert out.returncode == 2 and out.stdout == "", out
        assert out.stderr.strip() == line, out.stderr
        js = subprocess.run([sys.executable, "-m", "swarmpose", *args, "--json"], capture_output=True, text=True,
                            check=False)
        assert js.returncode == 2 and json.loads(js.stdout) == {"error": line.removeprefix("error: "), "exit_code": 2}


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

    monkeypatch.setattr("swarmpose.track.provenance.source_revision", lambda: "b" * 40)
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


# --------------------------------------------------------------------------- an 80-column terminal

_BOX = "│╭╮╰╯─┃━┏┓┗┛┡┩╇┳┻╋┣┫└┘┌┐├┤┼┬┴"


def _flat(text: str) -> str:
    """The text without the table and panel lines and without whitespace: what rich wrapped over several lines
    reads as one string again."""
    import re

    return re.sub(rf"[\s{_BOX}]", "", text)


def _commands(cmd, path: list[str]):
    yield path, cmd
    for name, sub in getattr(cmd, "commands", {}).items():
        yield from _commands(sub, [*path, name])


def test_every_help_wraps_at_80_columns_and_cuts_nothing():
    """At 80 columns rich cut `track --help`'s syntax with "…" (`results/<sequence>-…`, `terms=silhouette|ed…`,
    `constant-velocity[:…`). Every command's help now wraps instead: no "…", every option name whole, every word
    of every help text there, and the syntax a user types there in one piece."""
    from swarmpose.cli.app import command

    seen = 0
    for path, cmd in _commands(command(), []):
        res = CliRunner().invoke(app, [*path, "--help"], env={"COLUMNS": "80"})
        assert res.exit_code == 0, (path, res.output)
        assert "…" not in res.output, (path, [ln for ln in res.output.splitlines() if "…" in ln])
        assert max(len(ln) for ln in res.output.splitlines()) <= 80, path
        flat = _flat(res.output)
        for param in cmd.params:
            for name in [*getattr(param, "opts", ()), *getattr(param, "secondary_opts", ())]:
                assert not name.startswith("--") or name in flat, (path, name)
            words = (getattr(param, "help", None) or "").replace("\\[", "[").split()
            missing = [w for w in words if _flat(w) not in flat]
            assert not missing, (path, param.name, missing)
        seen += 1
    assert seen >= 14  # the root, every command and the sub-commands of bench and datasets
    track = _flat(CliRunner().invoke(app, ["track", "--help"], env={"COLUMNS": "80"}).output)
    for syntax in ("results/<sequence>-<algo>-<fps>fps", "terms=silhouette|edge", "edge_cones=all|torso|torso+upper",
                   "constant-velocity[:D][@GROUP+...]", "humaneva:PATH/S1/Walking_1[?cams=...]",
                   "pip install 'swarmpose[torch]'", "SeedSequence([seed, k])"):
        assert _flat(syntax) in track, syntax
    synth = _flat(CliRunner().invoke(app, ["synth", "--help"], env={"COLUMNS": "80"}).output)
    assert "--marker-noise-px" in synth and "material=value[,...]" in synth


def test_every_suite_listing_wraps_at_80_columns_and_keeps_the_algorithm_names_whole():
    """`compare thesis-apf --list` cut `apf-adaptive` to `apf-adap…` at 80 columns."""
    import re

    from swarmpose.experiments.suites import SUITES, suite

    for name in SUITES:
        res = CliRunner().invoke(app, ["compare", name, "--list"], env={"COLUMNS": "80"})
        assert res.exit_code == 0, res.output
        assert "…" not in res.output, name
        # the table fits the width; the lines under it are not broken (the terminal wraps them)
        assert max(len(ln) for ln in res.output.splitlines() if ln[:1] in _BOX) <= 80, name
        rows = [[c.strip() for c in re.split(rf"[{_BOX}]", ln)[1:-1]] for ln in res.output.splitlines()
                if ln.startswith("│")]
        labels = _flat("".join(r[0] for r in rows))  # the entry column read down: a long word may fold there
        for entry in suite(name):
            assert any(r[1] == entry.algo for r in rows), (name, entry.algo)  # one cell, never folded
            assert _flat(entry.label) in labels, entry


# --------------------------------------------------------------------------- swarmpose algorithms


def test_algorithms_show_the_measured_walk_numbers_and_the_default():
    """`swarmpose algorithms` had no accuracy or speed and did not say which one `track` runs by default."""
    import re

    from swarmpose.cli.track_commands import DEFAULT_ALGO
    from swarmpose.experiments.measured import CLIP, MEASURED
    from swarmpose.optim.registry import describe

    res = CliRunner().invoke(app, ["algorithms", "--json"])
    assert res.exit_code == 0, res.output
    data = json.loads(res.stdout)
    rows = {r["name"]: r for r in data["algorithms"]}
    assert list(rows) == [r["name"] for r in describe()] and data["default"] == DEFAULT_ALGO == "refined-heading"
    assert [n for n, r in rows.items() if r["default"]] == ["refined-heading"] and data["walk_clip"] == CLIP
    assert set(MEASURED) <= set(rows)  # nothing measured for a name the registry does not have
    for name, r in rows.items():
        m = MEASURED.get(name)
        assert r["walk"] == (None if m is None else {"clip": CLIP, **m._asdict()})
    sppso, dr05, aapso = rows["sppso"]["walk"], rows["apf-dr05"]["walk"], rows["aapso"]["walk"]
    assert (sppso["d_mean_mm"], sppso["fps"], sppso["frames_per_s"], sppso["runs"]) == (72.4, 20.0, 8.6, 5)
    assert (dr05["d_mean_mm"], dr05["frames_per_s"]) == (30.6, 5.6) and (aapso["d_mean_mm"], aapso["fps"]) == (14.8, 25)
    assert sppso["command"].startswith("swarmpose track ") and "--algo sppso --fps 20 --runs 5" in sppso["command"]
    # the default of `track` is the one marked
    import inspect

    from swarmpose.cli.track_commands import track
    assert inspect.signature(track).parameters["algo"].default.default == DEFAULT_ALGO
    text = CliRunner().invoke(app, ["algorithms"], env={"COLUMNS": "80"}).stdout
    assert "…" not in text and max(len(ln) for ln in text.splitlines() if ln[:1] in _BOX) <= 80
    assert "walk D_mean" in " ".join(text.split()) and "frames/s" in text
    lines = [[c.strip() for c in re.split(rf"[{_BOX}]", ln)[1:-1]] for ln in text.splitlines() if ln.startswith("│")]
    starts = {cells[0]: i for i, cells in enumerate(lines) if cells[0]}
    assert set(rows) <= set(starts) and [c for c in (lines[starts["refined-heading"] + 1][0],) if c] == ["(default)"]
    for name, r in rows.items():  # D_mean and the rate below it, frames/s, or dashes
        first, second = lines[starts[name]], lines[starts[name] + 1]
        m = MEASURED.get(name)
        if m is None:
            assert first[3:] == ["–", "–"]
        else:
            fps = "–" if m.frames_per_s is None else f"{m.frames_per_s:.1f}"
            assert first[3:] == [f"{m.d_mean_mm:.1f} mm", fps] and second[3] == f"at {m.fps:g} fps", (name, first)
        assert first[2] == str(r["evals_per_frame"])


def test_every_measured_number_is_in_the_results_page():
    """The numbers `swarmpose algorithms` shows are the ones docs/results.md reports: each algorithm's D_mean (and
    frames/s, where measured) on one line or paragraph of the page that names it."""
    from swarmpose.experiments.measured import MEASURED

    page = Path(__file__).resolve().parents[1] / "docs" / "results.md"
    text = page.read_text(encoding="utf-8")
    places = text.splitlines() + [" ".join(p.split()) for p in text.split("\n\n")]
    for name, m in MEASURED.items():
        found = [p for p in places if (f"`{name}`" in p or f"--algo {name} " in p) and f"{m.d_mean_mm:.1f} mm" in p
                 and (m.frames_per_s is None or f"| {m.frames_per_s:.1f} |" in p)]
        assert found, (name, m)


# --------------------------------------------------------------------------- messages


@pytest.fixture()
def small_sequence(tmp_path: Path) -> Path:
    """A 4-frame sequence folder at 30 fps with one small camera (enough to open; nothing is tracked)."""
    from swarmpose.camera import Camera
    from swarmpose.io.sequence import SequenceWriter

    cam = Camera.look_at("C1", eye=(4000.0, 0.0, 1500.0), target=(0.0, 0.0, 900.0), f=60.0, width=64, height=48)
    w = SequenceWriter(tmp_path / "seq", [cam], 30.0, 4, streams=("image",))
    for k in range(4):
        w.write_frame(k, image=np.full((1, 48, 64), 100, np.uint8))
    return w.finish(gt_joints=np.zeros((4, 15, 3)), frame_times=np.arange(4) / 30.0)


def _track_error(args: list[str], out: Path) -> tuple[str, str]:
    res = CliRunner().invoke(app, ["track", *args, "--out", str(out), "--json"], env={"COLUMNS": "300"})
    assert res.exit_code == 2, res.output
    assert not out.exists()
    return json.loads(res.stdout)["error"], res.stderr


def test_fps_errors_name_the_option(small_sequence: Path, tmp_path: Path):
    """`--fps 0` and a rate above the sequence's said "fps must be positive" / "fps must be in (0, 30.0]": the
    option is named, and the sequence's rate with the rates it can be tracked at."""
    for fps, message in (("0", "--fps: 0 is not a tracking rate; give one above 0"),
                         ("-5", "--fps: -5 is not a tracking rate"),
                         ("60", "--fps: 60 is above the sequence's 30 fps (tracking takes the sequence's frames and "
                                "makes no new ones: 30, 15, 10, ...)")):
        error, stderr = _track_error([str(small_sequence), "--fps", fps], tmp_path / "out")
        assert error.startswith(message), error
        assert f"error: {message}" in stderr


def test_fps_above_a_clips_synthesis_rate_is_refused_before_it_is_synthesised(walk_clip_path: Path, tmp_path: Path,
                                                                             monkeypatch):
    import importlib

    synthesize = importlib.import_module("swarmpose.synth.synthesize")  # the package names a function so too

    def no_synthesis(*args, **kwargs):
        raise AssertionError("synthesised before --fps was checked")

    monkeypatch.setattr(synthesize, "cached_sequence", no_synthesis)
    monkeypatch.setattr("swarmpose.cli.track_commands.synthesis_rate", lambda: 60.0)
    error, _ = _track_error([str(walk_clip_path), "--fps", "120"], tmp_path / "out")
    assert error.startswith("--fps: 120 is above the sequence's 60 fps (cmu_16_16_walk.bvh is synthesised at that "
                            "rate"), error
    res = CliRunner().invoke(app, ["demo", "--clip", str(walk_clip_path), "--fps", "120", "--out",
                                   str(tmp_path / "demo"), "--json"])
    assert res.exit_code == 2 and json.loads(res.stdout)["error"].startswith("--fps: 120 is above the sequence's 60")


def test_the_synthesis_rate_is_the_one_bvh_sources_are_synthesised_at():
    import inspect

    from swarmpose.cli.track_commands import synthesis_rate
    from swarmpose.synth.synthesize import cached_sequence

    assert synthesis_rate() == inspect.signature(cached_sequence).parameters["fps"].default == 60.0


def test_ctrl_c_says_what_was_saved(small_sequence: Path, tmp_path: Path, monkeypatch):
    """Ctrl-C said "the frames tracked so far are saved: run ... --resume" even when nothing was saved; now it says
    how many frames are saved, or that none is."""
    import swarmpose.track.runner as runner_module

    saved = {"frames": 0}

    def interrupted(sequence, config, runs, out_dir, **kwargs):
        run_dir = Path(out_dir) / "run_000"
        run_dir.mkdir(parents=True, exist_ok=True)
        if saved["frames"]:
            np.savez(run_dir / "progress.npz", done=saved["frames"], params=np.zeros((3, 2)))
        raise KeyboardInterrupt

    monkeypatch.setattr(runner_module, "track_runs", interrupted)
    out = tmp_path / "res"
    res = CliRunner().invoke(app, ["track", str(small_sequence), "--algo", "sppso", "--out", str(out), "--json"], env={"COLUMNS": "300"})
    assert res.exit_code == 130
    message = json.loads(res.stdout)["error"]
    assert message.startswith("interrupted before any frame was saved: nothing to resume") and "--resume" not in message
    saved["frames"] = 3
    res = CliRunner().invoke(app, ["track", str(small_sequence), "--algo", "sppso", "--out", str(out), "--json"], env={"COLUMNS": "300"})
    assert res.exit_code == 130
    assert json.loads(res.stdout)["error"] == (f"interrupted; 3 frames tracked so far are saved in {out}: run the same "
                                               "command with --resume to continue")
    assert "3 frames tracked so far are saved" in res.stderr

    def synthesising(*args, **kwargs):
        raise KeyboardInterrupt

    monkeypatch.setattr(runner_module, "resolve_sequence", synthesising)  # Ctrl-C while a clip is synthesised
    res = CliRunner().invoke(app, ["track", str(small_sequence), "--algo", "sppso", "--json"])
    assert res.exit_code == 130 and "nothing to resume" in json.loads(res.stdout)["error"]


def test_ctrl_c_in_compare_says_what_was_saved(small_sequence: Path, tmp_path: Path, monkeypatch):
    import swarmpose.experiments.run as run_module

    def interrupted(suite, seqs, out, **kwargs):
        if kwargs["resume"]:
            run_dir = Path(out) / "seq" / "sppso_20fps" / "run_001"
            run_dir.mkdir(parents=True)
            np.savez(run_dir / "progress.npz", done=1)
        raise KeyboardInterrupt

    monkeypatch.setattr(run_module, "run_suite", interrupted)
    out = tmp_path / "cmp"
    args = ["compare", "thesis-fitness", "--clip", str(small_sequence), "--out", str(out), "--json"]
    res = CliRunner().invoke(app, args)
    assert res.exit_code == 130 and json.loads(res.stdout)["error"].startswith("interrupted before any frame was saved")
    res = CliRunner().invoke(app, [*args, "--resume"])
    assert json.loads(res.stdout)["error"] == (f"interrupted; 1 frame tracked so far is saved in {out}: run the same "
                                               "command with --resume to continue")


# --------------------------------------------------------------------------- subject, bench track


def test_subject_from_height_writes_a_file_track_reads(tmp_path: Path):
    from swarmpose.body.spec import Subject
    from swarmpose.track.tracker import TrackConfig

    out = tmp_path / "me.json"
    res = CliRunner().invoke(app, ["subject", "--height", "1750", "--out", str(out), "--json"])
    assert res.exit_code == 0, res.output
    data = json.loads(res.stdout)
    assert data["out"] == str(out) and data["height_mm"] == 1750 and 300 < data["thigh_mm"] < 500
    assert Subject.load(out).offsets["l_thigh"][2] == pytest.approx(-data["thigh_mm"])
    again = CliRunner().invoke(app, ["subject", "--height", "1750", "--out", str(out)])
    assert again.exit_code == 2 and "--force" in again.output
    metres = CliRunner().invoke(app, ["subject", "--height", "1.75", "--out", str(tmp_path / "m.json")])
    assert metres.exit_code == 2 and "millimetres" in metres.output and not (tmp_path / "m.json").exists()
    assert TrackConfig(subject=str(out)).subject == str(out)
    from swarmpose.errors import ConfigError

    with pytest.raises(ConfigError, match="not both"):
        TrackConfig(subject=str(out), height_mm=1750.0)
    with pytest.raises(ConfigError, match="does not exist"):
        TrackConfig(subject=str(tmp_path / "nobody.json"))
    with pytest.raises(ConfigError, match="millimetres"):
        TrackConfig(height_mm=17.5)


def test_bench_track_reports_every_part(short_sequence_cli: Path):
    res = CliRunner().invoke(app, ["bench", "track", str(short_sequence_cli), "--algo", "sppso", "--max-frames", "2",
                                   "--json"])
    assert res.exit_code == 0, res.output
    data = json.loads(res.stdout)
    from swarmpose.track.timing import PARTS

    assert [p["part"] for p in data["parts"]] == list(PARTS) and data["frames"] == 2
    assert data["parts"][PARTS.index("fitness")]["seconds"] > 0 and data["evals_per_frame"] == 1000
    timed = sum(p["seconds"] for p in data["parts"] if p["part"] != "writing")
    assert timed <= data["seconds"] * 1.01  # exclusive times: no part is counted twice
    assert data["peak_rss_mb"] > 0
    import sys

    if sys.platform.startswith("linux"):  # memory sampled along the run, the last sample at the last frame
        assert [m["frame"] for m in data["memory"]] == [1, 2]
        assert all(0 < m["anon_mb"] < m["rss_mb"] <= data["peak_rss_mb"] + 1 for m in data["memory"])
    assert data["rss_growth_kb_per_frame"] is None  # too few samples for a slope


def test_bench_track_takes_the_tracked_views(short_sequence_cli: Path):
    """``--views`` as ``track`` takes it: a held-out camera stays out; a camera the sequence lacks is named."""
    from swarmpose.io.sequence import open_sequence

    names = open_sequence(short_sequence_cli).view_names
    three = ",".join(names[:3])
    res = CliRunner().invoke(app, ["bench", "track", str(short_sequence_cli), "--algo", "sppso", "--max-frames", "1",
                                   "--views", three, "--json"])
    assert res.exit_code == 0, res.output
    assert json.loads(res.stdout)["views"] == three
    bad = CliRunner().invoke(app, ["bench", "track", str(short_sequence_cli), "--max-frames", "1", "--views",
                                   "nocam", "--json"])
    assert bad.exit_code != 0 and "nocam" in bad.output


def test_bench_track_takes_the_downsampling(short_sequence_cli: Path):
    """``--downsample`` as ``track`` takes it: the run tracks the coarser images (another track than at full
    resolution, the factor in the JSON); a factor ``track`` refuses is refused here too, by name."""
    def bench(*extra: str) -> dict:
        res = CliRunner().invoke(app, ["bench", "track", str(short_sequence_cli), "--algo", "sppso", "--max-frames",
                                       "2", "--json", *extra])
        assert res.exit_code == 0, res.output
        return json.loads(res.stdout)

    full, half = bench(), bench("--downsample", "2")
    assert (full["downsample"], half["downsample"]) == (1, 2)
    assert half["d_mean_mm"] != full["d_mean_mm"]
    bad = CliRunner().invoke(app, ["bench", "track", str(short_sequence_cli), "--max-frames", "1", "--downsample",
                                   "3", "--json"])
    assert bad.exit_code != 0 and "downsample" in bad.output


def test_bench_track_times_the_backward_pass(short_sequence_cli: Path):
    """``--backward``: the run makes its offline second pass, so each frame costs its two searches (more
    evaluations and more time than forwards alone) and the track is the one ``track --backward`` gives."""
    def bench(*extra: str) -> dict:
        res = CliRunner().invoke(app, ["bench", "track", str(short_sequence_cli), "--algo", "sppso", "--max-frames",
                                       "3", "--json", *extra])
        assert res.exit_code == 0, res.output
        return json.loads(res.stdout)

    forwards, both = bench(), bench("--backward")
    assert (forwards["backward"], both["backward"]) == (False, True)
    assert forwards["frames"] == both["frames"] == 3
    assert forwards["evals_per_frame"] == 1000 and both["evals_per_frame"] > 1000
    assert both["parts"][0]["part"] == "features" and both["seconds"] > 0
    assert [m["frame"] for m in both["memory"]][-1] == 5  # progress over both passes: 2 * 3 - 1 frames
    table = CliRunner().invoke(app, ["bench", "track", str(short_sequence_cli), "--algo", "sppso", "--max-frames",
                                     "2", "--backward"])
    assert table.exit_code == 0 and "--backward" in table.output


def test_memory_growth_fits_the_run_after_its_first_quarter():
    from swarmpose.track.bench import memory_growth

    samples = [{"frame": f, "rss_mb": 300.0 + (50.0 if f < 250 else f / 1024.0)} for f in range(100, 1001, 100)]
    assert memory_growth(samples) == pytest.approx(1.0)  # 1 KB a frame; the first quarter's jump left out
    flat = [{"frame": f, "rss_mb": 250.0} for f in range(10, 101, 10)]
    assert memory_growth(flat) == pytest.approx(0.0, abs=1e-9)
    assert memory_growth([]) is None and memory_growth(flat, "anon_mb") is None


@pytest.fixture(scope="module")
def short_sequence_cli(tmp_path_factory, mocap_dir: Path) -> Path:
    from swarmpose.synth.synthesize import synthesize

    out = tmp_path_factory.mktemp("seq") / "walk9"
    synthesize(mocap_dir / "cmu_16_16_walk.bvh", out, fps=60, seed=0, max_frames=9, measure=False, progress=False)
    return out
