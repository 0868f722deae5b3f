"""Result files written whole: save_npz gives what numpy.savez gives, without a copy of the arrays."""

from __future__ import annotations

import tracemalloc

import numpy as np
import pytest

from swarmpose.io import files
from swarmpose.io.files import load_npz, save_npz


def test_save_npz_round_trips_every_kind_of_array_as_numpy_savez_does(tmp_path, monkeypatch):
    monkeypatch.setattr(files, "SAVE_PIECE_BYTES", 40)  # several pieces per array, a piece ending mid-item
    arrays = {"poses": np.arange(60.0).reshape(4, 15), "names": np.array(["pelvis_tx", "l_knee"]),
              "empty": np.zeros((0, 3)), "scalar": np.array(3.5), "fortran": np.asfortranarray(np.eye(3)),
              "strided": np.arange(40).reshape(4, 10)[:, ::3], "flags": np.array([True, False, True]),
              "rows": np.ones(3, dtype=[("params", "f8", (2,)), ("recovered", "?", (4,))])}
    save_npz(tmp_path / "mine.npz", **arrays)
    np.savez(tmp_path / "numpy.npz", **arrays)
    mine, theirs = load_npz(tmp_path / "mine.npz"), load_npz(tmp_path / "numpy.npz")
    assert list(mine) == list(theirs) == list(arrays)
    for name, want in arrays.items():
        assert mine[name].dtype == want.dtype and mine[name].shape == want.shape, name
        np.testing.assert_array_equal(mine[name], theirs[name])
    assert sorted(p.name for p in tmp_path.iterdir()) == ["mine.npz", "numpy.npz"]  # no temporary file left


def test_save_npz_holds_no_copy_of_a_long_track(tmp_path):
    joints = np.random.default_rng(0).normal(size=(20_077, 15, 3))  # 7 MB
    tracemalloc.start()
    try:
        save_npz(tmp_path / "track.npz", joints=joints)
        peak = tracemalloc.get_traced_memory()[1]
    finally:
        tracemalloc.stop()
    assert peak < 2 * files.SAVE_PIECE_BYTES < joints.nbytes / 3
    np.testing.assert_array_equal(load_npz(tmp_path / "track.npz")["joints"], joints)


def test_save_npz_refuses_objects_and_leaves_nothing_behind(tmp_path):
    (tmp_path / "track.npz").write_bytes(b"the previous file")
    with pytest.raises(ValueError, match="bad: an array of Python objects"):
        save_npz(tmp_path / "track.npz", good=np.zeros(3), bad=np.array([{}, None], dtype=object))
    assert (tmp_path / "track.npz").read_bytes() == b"the previous file"
    assert [p.name for p in tmp_path.iterdir()] == ["track.npz"]
