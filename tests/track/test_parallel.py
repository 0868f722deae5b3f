"""Runs in local worker processes: the same results as in-process runs, and a progress bar by frames."""

from __future__ import annotations

import numpy as np

from swarmpose.track import runner
from swarmpose.track.runner import track_runs
from swarmpose.track.tracker import TrackConfig


def test_worker_processes_give_the_in_process_runs_and_report_every_frame(short_sequence, tmp_path,
                                                                          monkeypatch, capsys):
    cfg = TrackConfig(algo="sppso", fps=30.0, seed=5)
    local = track_runs(short_sequence, cfg, 2, tmp_path / "inproc", workers=1, progress=False)
    reports: list[tuple[int, int]] = []
    frame = runner._JobsBar.frame
    monkeypatch.setattr(runner._JobsBar, "frame",
                        lambda self, index, done: (reports.append((index, done)), frame(self, index, done)))
    pooled = track_runs(short_sequence, cfg, 2, tmp_path / "pool", workers=2, progress=True)
    assert pooled["d_mean_mm"] == local["d_mean_mm"]
    for k in range(2):
        with (np.load(tmp_path / "inproc" / f"run_{k:03d}" / "track.npz", allow_pickle=False) as a,
              np.load(tmp_path / "pool" / f"run_{k:03d}" / "track.npz", allow_pickle=False) as b):
            assert np.array_equal(a["params"], b["params"])
    # the workers report finished frames while they run (6 frames per run at 30 fps from 60)
    assert {i for i, _ in reports} == {0, 1}
    assert all(1 <= done <= 6 for _, done in reports)
    err = capsys.readouterr().err
    assert "tracking" in err and "12/12" in err and "2/2 runs done" in err


def test_a_resumed_run_counts_its_saved_frames_from_the_start(short_sequence, tmp_path):
    """The bar of a resumed run starts at the frames saved before, so its rate and ETA are this session's."""
    from dataclasses import asdict

    from swarmpose.track.tracker import prepare_track, run_tracker

    cfg = TrackConfig(algo="sppso", fps=30.0, seed=2)
    setup = prepare_track(short_sequence, cfg, tmp_path)
    run_tracker(setup, 0, tmp_path, stop_after=2)  # interrupted after 2 of 6 frames
    run_tracker(setup, 1, tmp_path)  # finished

    def job(run: int, resume: bool = True) -> runner.Job:
        return runner.Job(str(short_sequence), asdict(cfg), run, str(tmp_path), resume, 6)

    assert [runner._frames_saved(job(k)) for k in (0, 1, 2)] == [2, 6, 0]
    assert runner._frames_saved(job(0, resume=False)) == 0
    bar = runner._JobsBar([job(0), job(1), job(2)], enabled=False)
    assert bar.bar.n == 8 and bar.bar.total == 18
