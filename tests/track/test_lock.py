"""One writer per results folder: a second track or compare on a folder in use is refused, naming the pid."""

from __future__ import annotations

import os

import pytest

from swarmpose.errors import ConfigError
from swarmpose.experiments.run import run_suite
from swarmpose.io.lock import LOCK_NAME, folder_lock
from swarmpose.track import runner
from swarmpose.track.runner import track_runs
from swarmpose.track.tracker import TrackConfig

pytest.importorskip("fcntl")


def test_the_lock_is_held_for_the_block_and_released_after(tmp_path):
    with folder_lock(tmp_path / "res") as path:
        assert path == tmp_path / "res" / LOCK_NAME and path.read_text().strip() == str(os.getpid())
        with pytest.raises(ConfigError, match=rf"being written by another swarmpose process \(pid {os.getpid()}\)"):
            with folder_lock(tmp_path / "res"):
                pass
    with folder_lock(tmp_path / "res"):  # released: taken again
        pass


def test_track_and_compare_refuse_a_folder_in_use(short_sequence, tmp_path, monkeypatch):
    cfg = TrackConfig(algo="sppso", fps=30.0, seed=5, max_frames=2)
    with folder_lock(tmp_path / "res"), pytest.raises(ConfigError, match="being written by another"):
        track_runs(short_sequence, cfg, 1, tmp_path / "res", resume=True, workers=1, progress=False)
    assert sorted(p.name for p in (tmp_path / "res").iterdir()) == [LOCK_NAME]  # nothing else written
    with folder_lock(tmp_path / "cmp"), pytest.raises(ConfigError, match="being written by another"):
        run_suite("thesis-apf", [short_sequence], tmp_path / "cmp", runs=1, workers=1, progress=False, max_frames=2)
    assert sorted(p.name for p in (tmp_path / "cmp").iterdir()) == [LOCK_NAME]
    # free again: the run goes ahead, and a fresh folder whose setting fails is removed with its lock file
    out = track_runs(short_sequence, cfg, 1, tmp_path / "res", resume=True, workers=1, progress=False)
    assert out["frames"] == 2
    def fails(*_args, **_kwargs):
        assert (tmp_path / "new" / LOCK_NAME).is_file()  # failing while the folder is locked
        raise ConfigError("a setting that fails")

    monkeypatch.setattr(runner, "prepare_track", fails)
    with pytest.raises(ConfigError, match="a setting that fails"):
        track_runs(short_sequence, cfg, 1, tmp_path / "new", workers=1, progress=False)
    assert not (tmp_path / "new").exists()
