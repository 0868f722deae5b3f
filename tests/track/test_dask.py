"""Jobs on a Dask cluster give exactly the results of local runs (issue 6: "results identical either way")."""

from __future__ import annotations

import json

import numpy as np
import pytest

from swarmpose.track.runner import track_runs
from swarmpose.track.tracker import TrackConfig

distributed = pytest.importorskip("dask.distributed")


def test_dask_cluster_gives_the_same_runs_as_local_processes(short_sequence, tmp_path):
    cfg = TrackConfig(algo="sppso", fps=30.0, seed=11)
    local = track_runs(short_sequence, cfg, 2, tmp_path / "local", workers=1, progress=False)
    # a real scheduler + worker process, reached by address as `--scheduler tcp://...` would be
    with distributed.LocalCluster(n_workers=1, threads_per_worker=1, processes=True, dashboard_address=None,
                                  silence_logs=40) as cluster:
        remote = track_runs(short_sequence, cfg, 2, tmp_path / "dask", scheduler=cluster.scheduler_address,
                            progress=False)
    assert remote["d_mean_mm"] == local["d_mean_mm"]
    for k in range(2):
        with (np.load(tmp_path / "local" / f"run_{k:03d}" / "track.npz", allow_pickle=False) as a,
              np.load(tmp_path / "dask" / f"run_{k:03d}" / "track.npz", allow_pickle=False) as b):
            assert np.array_equal(a["params"], b["params"])
            assert np.array_equal(a["scores"], b["scores"])
        sa = json.loads((tmp_path / "local" / f"run_{k:03d}" / "summary.json").read_text())
        sb = json.loads((tmp_path / "dask" / f"run_{k:03d}" / "summary.json").read_text())
        assert sa["d_mean"] == sb["d_mean"]


def test_unreachable_scheduler_fails_before_the_ik_fit(short_sequence, tmp_path, monkeypatch):
    """A wrong --scheduler is refused in seconds, before the (slow) IK fit and before anything is written."""
    from swarmpose.errors import ConfigError
    from swarmpose.track import runner

    def no_ik(*a, **k):
        raise AssertionError("prepare_track reached with an unreachable scheduler")

    connect = runner.connect_scheduler
    monkeypatch.setattr(runner, "prepare_track", no_ik)
    monkeypatch.setattr(runner, "connect_scheduler", lambda address: connect(address, timeout_s=2.0))
    with pytest.raises(ConfigError, match="cannot reach the Dask scheduler at 'tcp://127.0.0.1:1'"):
        track_runs(short_sequence, TrackConfig(algo="sppso", fps=30.0), 1, tmp_path / "r",
                   scheduler="tcp://127.0.0.1:1", progress=False)
    assert not (tmp_path / "r").exists()
