"""Loading a results folder: what is read, what is recomputed, and errors that name the missing file."""

from __future__ import annotations

import json
import re
import shutil
from pathlib import Path

import numpy as np
import pytest

from swarmpose.errors import DataError
from swarmpose.report import load_results


def test_loads_runs_ik_and_summary(fake_results):
    res_dir, seq_dir = fake_results
    res = load_results(res_dir)
    assert [r.run for r in res.runs] == [0, 1]
    assert res.frame_indices.tolist() == [0, 3, 6, 9, 12, 15]
    np.testing.assert_allclose(res.frame_times, res.frame_indices / 60.0)
    assert res.ik_joint_error_mm.shape == (6, 15)
    assert res.fps == 20.0
    assert res.sequence_path() == seq_dir
    assert res.model.n_params == res.runs[0].params.shape[1]
    # D per frame stored by the tracker equals the joints' error
    for r in res.runs:
        np.testing.assert_allclose(r.d_per_frame, r.joint_distances.mean(axis=1))


def test_missing_folder_and_config_are_named(tmp_path: Path):
    with pytest.raises(DataError, match="no such results folder"):
        load_results(tmp_path / "nope")
    with pytest.raises(DataError, match=r"config\.json not found: is this a swarmpose results folder\?"):
        load_results(tmp_path)


def test_a_file_is_named_a_file_not_a_missing_folder(fake_results, tmp_path: Path):
    summary = fake_results[0] / "summary.json"
    with pytest.raises(DataError, match=rf"^{re.escape(str(summary))} is a file, not a results folder \(its folder "
                                        rf"{re.escape(str(fake_results[0]))} is one\)$"):
        load_results(summary)
    other = tmp_path / "notes.txt"
    other.write_text("x")
    with pytest.raises(DataError, match="notes.txt is a file, not a results folder .give the folder"):
        load_results(other)


def test_no_finished_run(tmp_path: Path):
    (tmp_path / "config.json").write_text(json.dumps({"algo": "sppso"}))
    (tmp_path / "run_000").mkdir()
    (tmp_path / "run_000" / "progress.npz").write_bytes(b"")
    with pytest.raises(DataError, match=r"no finished run.*run_000 \(in progress\)"):
        load_results(tmp_path)


def test_summary_recomputed_when_missing(fake_results, tmp_path: Path):
    src, _ = fake_results
    dst = tmp_path / "res"
    shutil.copytree(src, dst, ignore=shutil.ignore_patterns("report"))
    stored = json.loads((dst / "summary.json").read_text())
    (dst / "summary.json").unlink()
    res = load_results(dst)
    assert res.summary["recomputed"]
    for key in ("d_mean_mm", "d_max_mm", "mmta", "mmtp_mm"):
        assert res.summary[key] == pytest.approx(stored[key])
    assert res.summary["per_joint_mm"] == pytest.approx(stored["per_joint_mm"])


def test_missing_sequence_and_subject(fake_results, tmp_path: Path):
    src, _ = fake_results
    dst = tmp_path / "res"
    shutil.copytree(src, dst, ignore=shutil.ignore_patterns("report"))
    cfg = json.loads((dst / "config.json").read_text())
    cfg["sequence"] = str(tmp_path / "gone")
    (dst / "config.json").write_text(json.dumps(cfg))
    (dst / "subject.json").unlink()
    res = load_results(dst)
    with pytest.raises(DataError, match="gone.*not found"):
        res.sequence_path()
    with pytest.raises(DataError, match=r"subject\.json not found"):
        _ = res.model


def test_a_summary_of_other_runs_is_recomputed_and_noted(results_builder, tmp_path: Path):
    """A resume that adds runs rewrites summary.json only at its end: an interrupted one leaves the
    folder with more finished runs than summary.json aggregates. The report must not show the old mean."""
    from swarmpose.metrics import aggregate_runs, track_errors
    from swarmpose.report.summary import write_summary

    res_dir, _ = results_builder(tmp_path / "three", runs=3)
    summary = json.loads((res_dir / "summary.json").read_text())
    two = aggregate_runs([track_errors(r.joints, r.gt_joints) for r in load_results(res_dir).runs[:2]])
    summary.update(runs=2, d_mean_mm=two["d_mean"], per_run=summary["per_run"][:2])  # as after runs 0-1
    (res_dir / "summary.json").write_text(json.dumps(summary))
    res = load_results(res_dir)
    three = aggregate_runs([track_errors(r.joints, r.gt_joints) for r in res.runs])
    assert three["d_mean"] != pytest.approx(two["d_mean"], abs=1e-3)
    assert res.summary["d_mean_mm"] == pytest.approx(three["d_mean"], rel=1e-12)
    assert res.summary["runs"] == 3 and res.summary["worst"]["run"] == three["worst"]["run"]
    assert "aggregates run(s) 0, 1; the folder has finished run(s) 0, 1, 2" in res.summary["recomputed_because"]
    assert res.summary["sequence"] == summary["sequence"]  # what does not depend on the runs is kept
    md = write_summary(res, out=tmp_path / "summary.md").read_text()
    assert "> Note: summary.json aggregates run(s) 0, 1" in md
    # the summary of the same runs is taken as stored
    assert "recomputed_because" not in load_results(results_builder(tmp_path / "two", runs=2)[0]).summary
