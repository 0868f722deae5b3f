"""``scripts/miss_onsets.py``: miss episodes and their onsets on constructed tracks, and the results folder's
recorded settings it reads (``swarmpose.track.runner.recorded_config``)."""

from __future__ import annotations

from pathlib import Path

import numpy as np

from swarmpose.joints import JOINTS15


def test_a_jump_and_a_drift_are_told_apart(load_script):
    script = load_script("miss_onsets")
    rng = np.random.default_rng(0)
    T = 7
    truth = np.cumsum(rng.normal(0.0, 5.0, (T, 15, 3)), axis=0) + rng.normal(0.0, 300.0, (1, 15, 3))
    est = truth.copy()
    wrist, elbow = JOINTS15.index("l_wrist"), JOINTS15.index("r_elbow")
    est[3:5, wrist] += [300.0, 0.0, 0.0]  # the left wrist carried 300 mm off in one frame, for two frames
    est[:, elbow] += np.arange(T)[:, None] * [0.0, 30.0, 0.0]  # the right elbow drifting 30 mm a frame
    got = {e["joint"]: e for e in script.onsets(est, truth, 100.0)}
    assert set(got) == {"l_wrist", "r_elbow"}
    w, e = got["l_wrist"], got["r_elbow"]
    assert (w["frame"], w["frames"], e["frame"], e["frames"]) == (3, 2, 4, 3)
    true_move = np.linalg.norm((truth[3, wrist] - truth[3, JOINTS15.index("l_shoulder")])
                               - (truth[2, wrist] - truth[2, JOINTS15.index("l_shoulder")]))
    assert w["truth_moved_mm"] == np.float64(true_move) and script.sudden(w)
    assert not script.sudden(e) and e["moved_mm"] < 2 * e["truth_moved_mm"] + 60
    assert script.onsets(truth, truth, 100.0) == []


def test_a_results_folders_settings_are_read_back(short_sequence: Path, tmp_path: Path):
    from swarmpose.track.runner import recorded_config
    from swarmpose.track.tracker import TrackConfig, prepare_track, write_config

    cfg = TrackConfig(algo="refined", fps=10.0, seed=3, optim_variant="refine=50", max_frames=2)
    setup = prepare_track(short_sequence, cfg, tmp_path)
    write_config(tmp_path, setup, 2)
    record, back = recorded_config(tmp_path)
    assert back == cfg and record["runs"] == 2 and "sequence" in record
