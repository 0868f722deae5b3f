"""The run's progress files: rows written one frame at a time, a constant-size state, resume as before."""

from __future__ import annotations

import json

import numpy as np
import pytest

from swarmpose.errors import FormatError
from swarmpose.track.progress import RunProgress


def _save(store, i, rng):
    store.save(i, params=np.full(3, i + 0.5), score=-i, evaluations=100 + i, seconds=0.1 * i,
               recovered=np.array([i % 2 == 0, False]), x_prev=np.full(3, i + 0.5),
               rng_state=rng.bit_generator.state, carry=(np.ones((4, 3)) * i, np.full(4, 0.25)))


def test_rows_round_trip_and_the_state_does_not_grow(tmp_path):
    rng = np.random.default_rng(0)
    store = RunProgress(tmp_path, 1000, 3, 2)
    store.start(None)
    sizes = []
    for i in range(5):
        rng.random()
        _save(store, i, rng)
        sizes.append(store.state_file.stat().st_size)
    assert max(sizes) - min(sizes) < 64  # the same size per frame (the generator state as text varies a little)
    store.close()
    state = RunProgress(tmp_path, 1000, 3, 2).load()
    assert state.done == 5
    np.testing.assert_array_equal(state.params[:, 0], np.arange(5) + 0.5)
    np.testing.assert_array_equal(state.evaluations, 100 + np.arange(5))
    np.testing.assert_array_equal(state.recovered[:, 0], [True, False, True, False, True])
    assert state.rng_state == rng.bit_generator.state
    np.testing.assert_array_equal(state.carry[0], np.full((4, 3), 4.0))


def test_a_frame_written_but_not_counted_is_tracked_again(tmp_path):
    rng = np.random.default_rng(0)
    store = RunProgress(tmp_path, 10, 3, 2)
    store.start(None)
    _save(store, 0, rng)
    state_before = store.state_file.read_bytes()
    _save(store, 1, rng)
    store.state_file.write_bytes(state_before)  # as if the process died after row 1, before its state
    assert RunProgress(tmp_path, 10, 3, 2).load().done == 1


def test_the_earlier_single_file_layout_is_read(tmp_path):
    T, D = 6, 3
    np.savez(tmp_path / "progress.npz", done=2, params=np.arange(T * D, dtype=float).reshape(T, D),
             scores=np.arange(T, dtype=float), evaluations=np.arange(T), seconds=np.ones(T), x_prev=np.zeros(D),
             rng_state=np.array(json.dumps(np.random.default_rng(1).bit_generator.state)))
    store = RunProgress(tmp_path, T, D, 4)
    state = store.load()
    assert state.done == 2 and state.carry is None
    np.testing.assert_array_equal(state.params, [[0, 1, 2], [3, 4, 5]])
    assert not state.recovered.any()
    store.start(state)  # the new layout from here on, the two frames copied
    store.close()
    assert RunProgress(tmp_path, T, D, 4).load().done == 2


def test_damaged_or_foreign_files_are_named(tmp_path):
    rng = np.random.default_rng(0)
    store = RunProgress(tmp_path, 10, 3, 2)
    store.start(None)
    _save(store, 0, rng)
    store.close()
    with pytest.raises(FormatError, match="progress_frames.npy holds"):
        RunProgress(tmp_path, 12, 3, 2).load()  # another run's length
    store.frames_file.write_bytes(b"garbage")
    with pytest.raises(FormatError, match="progress_frames.npy cannot be read"):
        RunProgress(tmp_path, 10, 3, 2).load()
    store.state_file.write_bytes(b"not an archive")
    with pytest.raises(FormatError, match="progress.npz.*delete it"):
        RunProgress(tmp_path, 10, 3, 2).load()


@pytest.mark.skipif(not __import__("os").path.exists("/proc/self/maps"), reason="reads /proc/self/maps (Linux)")
def test_the_rows_file_is_not_kept_mapped(tmp_path):
    """A long recording's rows are written in place, not through a mapping that would keep them in the
    process's memory; a resumed run reads them and lets the mapping go."""
    rng = np.random.default_rng(0)
    store = RunProgress(tmp_path, 50, 3, 2)
    store.start(None)
    for i in range(3):
        _save(store, i, rng)

    def mapped() -> bool:
        return str(store.frames_file) in open("/proc/self/maps").read()

    assert not mapped()
    again = RunProgress(tmp_path, 50, 3, 2)
    state = again.load()
    again.start(state)
    _save(again, 3, rng)
    assert not mapped()
    again.close()
    store.close()
    assert RunProgress(tmp_path, 50, 3, 2).load().done == 4
