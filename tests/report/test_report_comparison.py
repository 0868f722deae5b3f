"""The report of a `swarmpose compare` folder: the table, two figures drawn from the entries' own results
folders, the page; `swarmpose report COMPARE_DIR`; bad comparison files named."""

from __future__ import annotations

import json
import shutil
from pathlib import Path

import pytest
from typer.testing import CliRunner

from swarmpose.cli.app import app
from swarmpose.errors import DataError, FormatError
from swarmpose.report.comparison import comparison_table, entry_folder, load_comparison, write_comparison
from swarmpose.report.results import load_results


def _row(res_dir: Path, label: str, fps: float, out_dir: str) -> dict:
    s = json.loads((res_dir / "summary.json").read_text())
    return {"label": label, "algo": label.split()[0], "fps": fps, "variant": "", "sequence": "walk", "runs": 2,
            "frames": 6, "evals_per_frame": 1000, "d_mean_mm": s["d_mean_mm"], "d_max_mm": s["d_max_mm"],
            "d_mean_std_over_runs_mm": 1.0, "worst_d_mean_mm": s["worst"]["d_mean_mm"], "ik_floor_mm": s["ik_floor_mm"],
            "mmta": s["mmta"], "mmtp_mm": s["mmtp_mm"], "frames_per_s": 3.0, "reference": "thesis", "out_dir": out_dir}


@pytest.fixture()
def comparison(fake_results, tmp_path: Path) -> Path:
    """A comparison folder of two entries (copies of the fake results), recorded under another working
    directory's relative path, as `compare` writes it."""
    root = tmp_path / "cmp"
    rows = []
    for label in ("sppso 20fps", "apf 20fps"):
        cell = root / "walk" / label.replace(" ", "_")
        shutil.copytree(fake_results[0], cell, ignore=shutil.ignore_patterns("report"))
        rows.append(_row(cell, label, 20.0, f"results/compare/x/walk/{label.replace(' ', '_')}"))
    report = {"suite": "thesis-apf", "runs": 2, "seed": 0, "max_frames": None, "lowest_fps": 20.0, "rows": rows}
    (root / "comparison.json").write_text(json.dumps(report))
    return root


def test_the_figures_and_the_page_are_written_from_the_entries(comparison: Path):
    paths = write_comparison(comparison)
    assert paths["figures"] == [str(comparison / "comparison_over_time.png"), str(comparison / "comparison_d_mean.png")]
    for p in paths["figures"]:
        assert Path(p).stat().st_size > 10_000
    md = (comparison / "comparison.md").read_text()
    report = load_comparison(comparison)
    assert md.startswith(comparison_table(report))
    assert "](comparison_over_time.png)" in md and "](comparison_d_mean.png)" in md
    page = Path(paths["html"]).read_text()
    assert page.count('<img src="data:image/png;base64,') == 2 and "<td>sppso 20fps</td>" in page
    assert entry_folder(comparison, report["rows"][1]) == comparison / "walk" / "apf_20fps"


def test_report_cli_redraws_a_comparison_and_refuses_run_options(comparison: Path):
    res = CliRunner().invoke(app, ["report", str(comparison), "--json"])
    assert res.exit_code == 0, res.output
    out = json.loads(res.stdout)
    assert out["html"] == str(comparison / "comparison.html") and len(out["figures"]) == 2
    res = CliRunner().invoke(app, ["report", str(comparison), "--video", "--run", "1", "--json"])
    assert res.exit_code == 2
    msg = json.loads(res.stdout)["error"]
    assert "--video, --run apply to one results folder" in msg and "walk/sppso_20fps" in msg


def test_a_missing_entry_or_a_bad_comparison_file_is_named(comparison: Path):
    shutil.rmtree(comparison / "walk" / "apf_20fps")
    with pytest.raises(DataError, match="apf_20fps: no such results folder"):
        write_comparison(comparison)
    data = json.loads((comparison / "comparison.json").read_text())
    del data["rows"][0]["out_dir"]
    (comparison / "comparison.json").write_text(json.dumps(data))
    with pytest.raises(FormatError, match=r"comparison.json.*rows\[0\] has no 'out_dir'"):
        load_comparison(comparison)
    with pytest.raises(DataError, match="not a `swarmpose compare` folder|is .* a `swarmpose compare` folder"):
        load_comparison(comparison / "walk")


def test_per_run_dots_are_the_runs_d_mean(comparison: Path):
    """The dot chart's numbers: each run's D_mean as its summary has it (checked against the joints)."""
    res = load_results(comparison / "walk" / "sppso_20fps")
    import numpy as np

    for run in res.runs:
        assert run.summary["d_mean"] == pytest.approx(float(np.nanmean(run.d_per_frame)), abs=1e-9)


def test_an_entry_with_a_missing_run_is_noted_and_drawn_from_the_runs_there_are(comparison: Path):
    (comparison / "walk" / "apf_20fps" / "run_001" / "joints.npz").unlink()
    paths = write_comparison(comparison)
    (note,) = paths["notes"]
    assert note.startswith("walk / apf 20fps: 1 of 2 runs finished") and "run_001" in note
    assert f"> Note: {note}" in (comparison / "comparison.md").read_text()
    res = CliRunner().invoke(app, ["report", str(comparison)])
    assert res.exit_code == 0 and "1 of 2 runs finished" in " ".join(res.stderr.split())


def test_one_colour_per_entry_whatever_the_rate():
    from swarmpose.report.comparison import _entry_key

    keys = {_entry_key({"label": x}) for x in ("aapso 25fps reprojection", "aapso 12fps reprojection")}
    assert keys == {"aapso reprojection"}
    assert _entry_key({"label": "sppso 20fps"}) == _entry_key({"label": "sppso 60fps"}) == "sppso"
    assert _entry_key({"label": "sppso stage 2 10x80 20fps"}) == "sppso stage 2 10x80"


def test_an_entry_with_more_runs_than_its_table_is_noted(comparison: Path):
    """A resume that adds runs, interrupted: the entry has a finished run the table does not count."""
    cell = comparison / "walk" / "apf_20fps"
    shutil.copytree(cell / "run_001", cell / "run_002")
    config = json.loads((cell / "config.json").read_text())
    (cell / "config.json").write_text(json.dumps({**config, "runs": 3}))
    paths = write_comparison(comparison)
    (note,) = paths["notes"]
    assert note.startswith("walk / apf 20fps: 3 runs finished, the comparison's table has 2")
    assert f"> Note: {note}" in (comparison / "comparison.md").read_text()
    assert len(load_results(cell).runs) == 3


def test_the_error_over_time_figure_says_how_many_runs_each_entry_has(comparison: Path, monkeypatch):
    """Its title says "mean of 2 runs" only while every entry has them; an entry with another count says
    its own in the legend."""
    from matplotlib.figure import Figure

    seen: dict[str, tuple[str, list[str]]] = {}
    save = Figure.savefig

    def record(fig, path, *args, **kwargs):
        legends = [t.get_text() for ax in fig.axes if ax.get_legend() for t in ax.get_legend().get_texts()]
        seen[Path(path).name] = (fig._suptitle.get_text() if fig._suptitle else "", legends)
        return save(fig, path, *args, **kwargs)

    monkeypatch.setattr(Figure, "savefig", record)
    write_comparison(comparison)
    title, legend = seen["comparison_over_time.png"]
    assert "mean of 2 runs per entry" in title and not any(" run" in t for t in legend)

    (comparison / "walk" / "apf_20fps" / "run_001" / "joints.npz").unlink()
    write_comparison(comparison)
    title, legend = seen["comparison_over_time.png"]
    assert "mean of 2 runs" not in title and "finished runs" in title
    (apf,) = [t for t in legend if t.startswith("apf 20fps")]
    (sppso,) = [t for t in legend if t.startswith("sppso 20fps")]
    assert apf.endswith(", 1 run") and " run" not in sppso


def test_a_comparison_written_before_the_spread_had_its_unit_still_reads(comparison: Path):
    """comparison.json files written before the key was named ``d_mean_std_over_runs_mm`` keep working."""
    path = comparison / "comparison.json"
    report = json.loads(path.read_text())
    for row in report["rows"]:
        row["d_mean_std_over_runs"] = row.pop("d_mean_std_over_runs_mm") + 1.5
    path.write_text(json.dumps(report))
    rows = load_comparison(comparison)["rows"]
    assert [r["d_mean_std_over_runs_mm"] for r in rows] == [2.5, 2.5]
    assert "± 2.5 |" in comparison_table(load_comparison(comparison))
    report = load_comparison(comparison)
    report["rows"][0]["runs"] = 1
    assert "(1 run) |" in comparison_table(report) and "± 2.5 |" in comparison_table(report)  # no "± 0.0"


def test_several_references_are_numbered_per_entry_and_one_is_said_once(comparison: Path):
    report = load_comparison(comparison)
    assert "Reference: thesis" in comparison_table(report) and "[1]" not in comparison_table(report)
    report["rows"][1]["reference"] = "HumanEva (Sigal et al. 2010; eq. 8)"  # a ';' inside one reference
    table = comparison_table(report)
    assert "| sppso 20fps [1] |" in table and "| apf 20fps [2] |" in table
    assert "1. thesis\n2. HumanEva (Sigal et al. 2010; eq. 8)" in table
    assert "Sequence: walk" in table and "| sequence |" not in table  # one sequence: said once
    report["rows"][1]["sequence"] = "jog"
    table = comparison_table(report)
    assert "Sequence:" not in table and "| sequence | entry |" in table and "| jog | apf 20fps [2] |" in table


def test_the_largest_d_of_an_entry_written_before_the_key_comes_from_its_own_summary(comparison: Path):
    """comparison.json rows without d_max_over_runs_mm: the table's '(largest)' is read from the entry's
    summary.json (its per_run maxima) instead of promised in the header and left out."""
    path = comparison / "comparison.json"
    report = json.loads(path.read_text())
    for row in report["rows"]:
        row.pop("d_max_over_runs_mm", None)
    path.write_text(json.dumps(report))
    entry = comparison / "walk" / "sppso_20fps" / "summary.json"
    s = json.loads(entry.read_text())
    s.pop("d_max_over_runs_mm", None)
    s["per_run"] = [{"run": 0, "d_max": 150.0}, {"run": 1, "d_max": 171.5}]  # as compare writes them
    entry.write_text(json.dumps(s))
    (comparison / "walk" / "apf_20fps" / "summary.json").unlink()
    rows = load_comparison(comparison)["rows"]
    assert rows[0]["d_max_over_runs_mm"] == 171.5 and rows[1]["d_max_over_runs_mm"] is None
    table = comparison_table(load_comparison(comparison))
    assert "mean of the runs (largest)" in table and " (171.5) |" in table and " (–) |" in table
    for row in rows:
        row["d_max_over_runs_mm"] = None
    assert "(largest)" not in comparison_table({**report, "rows": rows})


def test_every_cell_of_a_row_is_its_entry_s_number(comparison: Path):
    """Each row: label, evaluations, D_mean ± SD, the worst run's D_mean (not the mean), mean D_max with the
    largest, IK floor, MMTA in per cent, frames/s."""
    report = load_comparison(comparison)
    table = comparison_table(report)
    for r in report["rows"]:
        assert r["worst_d_mean_mm"] > r["d_mean_mm"] and 0.0 < r["mmta"] < 1.0  # cells that can be told apart
        largest = f" ({r['d_max_over_runs_mm']:.1f})" if r.get("d_max_over_runs_mm") is not None else ""
        line = (f"| {r['label']} | {r['evals_per_frame']} | {r['d_mean_mm']:.1f} ± {r['d_mean_std_over_runs_mm']:.1f} | "
                f"{r['worst_d_mean_mm']:.1f} | {r['d_max_mm']:.1f}{largest} | {r['ik_floor_mm']:.1f} | "
                f"{100 * r['mmta']:.1f} | {r['frames_per_s']:.2f} |")
        assert line in table
