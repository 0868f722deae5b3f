"""The runs' consensus (``track --consensus K``, swarmpose.track.consensus)."""

from __future__ import annotations

import json
from pathlib import Path

import numpy as np
import pytest
from typer.testing import CliRunner

from swarmpose.body.model import load_model
from swarmpose.cli.app import app
from swarmpose.errors import ConfigError, DataError
from swarmpose.track.consensus import check_groups, consensus_params, run_hypotheses, write_consensus


@pytest.fixture(scope="module")
def body():
    model = load_model("balan31")
    rng = np.random.default_rng(4)
    T = 5
    truth = np.repeat(model.zero_pose()[None], T, axis=0)
    truth[:, 5] = 1000.0
    truth += rng.normal(0.0, 1.0, truth.shape) * model.sigma * 0.5  # a different pose per frame
    truth = np.clip(truth, model.lower, model.upper)
    return model, truth


def _limb_off(model, poses: np.ndarray, group: str, by: float) -> np.ndarray:
    """``poses`` with every parameter of ``group`` moved ``by`` of its range towards its far end."""
    out = poses.copy()
    g = model.group(group)
    lo, hi = model.lower[g], model.upper[g]
    mid = 0.5 * (lo + hi)
    out[:, g] = np.where(out[:, g] < mid, out[:, g] + by * (hi - lo), out[:, g] - by * (hi - lo))
    return np.clip(out, model.lower, model.upper)


def test_a_limb_lost_by_one_run_only_is_found_by_the_others(body):
    """Three hypotheses, each with another limb far off: each joint is right in two of the three, so its median
    is the truth's, and the model fitted to the medians is the truth's pose."""
    model, truth = body
    hyps = np.stack([_limb_off(model, truth, limb, 0.4) for limb in ("left_arm", "right_arm", "left_leg")])
    gt = model.joints15(truth)
    worst = [np.linalg.norm(model.joints15(h) - gt, axis=-1).max() for h in hyps]
    assert min(worst) > 100.0  # every hypothesis loses a limb by more than 100 mm
    fused = consensus_params(model, hyps)
    assert fused.fitted.all()
    assert np.linalg.norm(fused.joints - gt, axis=-1).max() < 5.0  # the fit to the medians, to a few mm
    assert np.allclose(fused.joints, model.joints15(fused.params))


def test_agreeing_runs_give_their_own_pose(body):
    model, truth = body
    fused = consensus_params(model, np.stack([truth, truth, truth]))
    assert np.linalg.norm(fused.joints - model.joints15(truth), axis=-1).max() < 1e-3
    two = consensus_params(model, np.stack([truth, _limb_off(model, truth, "right_arm", 0.4)]))
    assert not two.fitted.any()  # two hypotheses: the nearest one is kept as it is, never averaged
    assert np.array_equal(two.params, np.stack([truth, _limb_off(model, truth, "right_arm", 0.4)])[two.nearest,
                                                                                                    np.arange(len(truth))])


def test_a_fit_the_constraint_refuses_leaves_the_hypothesis_nearest_the_median(body):
    model, truth = body
    hyps = np.stack([truth, truth, _limb_off(model, truth, "left_arm", 0.4)])
    fused = consensus_params(model, hyps, constraint=lambda p: np.zeros(len(np.atleast_2d(p)), dtype=bool))
    assert not fused.fitted.any()
    assert np.all(fused.nearest < 2)  # the two that agree are nearest the median
    assert np.array_equal(fused.params, truth)


def test_a_run_s_hypotheses_are_its_track_or_its_two_passes():
    """Forwards: the track. With --backward: both passes' poses, not the track (which the path takes from one or
    the other, and would count twice); a folder from before the path: its track and the forward pass's."""
    fwd, back, track = np.zeros((4, 31)), np.ones((4, 31)), np.full((4, 31), 2.0)
    assert np.array_equal(run_hypotheses({"params": track}), track[None])
    both = run_hypotheses({"params": track, "forward_params": fwd, "backward_params": back})
    assert np.array_equal(both, np.stack([back, fwd]))
    assert np.array_equal(run_hypotheses({"params": track, "forward_params": fwd}), np.stack([track, fwd]))


def test_the_runs_must_split_into_tracks_of_k():
    check_groups(6, 3)
    for runs, k in ((4, 3), (3, 1), (2, 0)):
        with pytest.raises(ConfigError, match="--consensus"):
            check_groups(runs, k)
    with pytest.raises(ConfigError, match="shape"):
        consensus_params(load_model("balan31"), np.zeros((2, 3, 4)))


def test_track_writes_the_consensus_as_a_results_folder(short_sequence: Path, tmp_path: Path):
    """``--runs 4 --consensus 2``: two consensus tracks (runs 0-1, 2-3) in OUT/consensus, scored like runs, which
    the report and the exports read; their command line is reproduced; a bad K fails before anything is written."""
    from swarmpose.report.results import load_results
    from swarmpose.report.summary import _reproduce

    out = tmp_path / "r"
    res = CliRunner().invoke(app, ["track", str(short_sequence), "--algo", "sppso", "--runs", "4", "--max-frames",
                                   "3", "--consensus", "2", "--out", str(out), "--json"])
    assert res.exit_code == 0, res.output
    summary = json.loads(res.stdout)
    c = summary["consensus"]
    assert c["runs"] == 2 and c["runs_per_track"] == 2 and [r["fused_runs"] for r in c["per_run"]] == [[0, 1], [2, 3]]
    fused = load_results(out / "consensus")
    assert [r.run for r in fused.runs] == [0, 1]
    assert fused.summary["d_mean_mm"] == pytest.approx(c["d_mean_mm"])
    runs = load_results(out)
    for k, pair in enumerate(([0, 1], [2, 3])):
        nearest = np.load(out / "consensus" / f"run_{k:03d}" / "track.npz")["nearest"]
        hyps = np.stack([runs.run(r).params for r in pair])
        assert np.array_equal(fused.run(k).params, hyps[nearest, np.arange(3)])  # two runs: the nearest, as it is
    assert _reproduce(fused.config).endswith("--runs 4 --seed 0 --max-frames 3 --consensus 2")
    bvh = tmp_path / "c.bvh"
    assert CliRunner().invoke(app, ["export", str(out / "consensus"), "--out", str(bvh)]).exit_code == 0
    assert bvh.read_text().startswith("HIERARCHY")
    bad = CliRunner().invoke(app, ["track", str(short_sequence), "--runs", "3", "--consensus", "2", "--out",
                                   str(tmp_path / "bad"), "--json"])
    assert bad.exit_code != 0 and "--consensus" in bad.output and not (tmp_path / "bad").exists()
    (out / "run_003" / "track.npz").unlink()  # an unfinished run is named; the consensus written stays as it was
    with pytest.raises(DataError, match="run_003 not finished"):
        write_consensus(out, 2, fused.model)
    assert load_results(out / "consensus").summary["d_mean_mm"] == pytest.approx(c["d_mean_mm"])
