"""The feature store: a run that reads its frames' binary features from disk tracks exactly as one that computes them."""

from __future__ import annotations

import numpy as np
import pytest

from swarmpose.errors import DataError
from swarmpose.features import compute_features
from swarmpose.io.sequence import open_sequence
from swarmpose.track.feature_store import FeatureStore
from swarmpose.track.observation import frame_observation
from swarmpose.track.tracker import TrackConfig, prepare_track, run_tracker


def test_runs_read_from_the_store_track_exactly_as_runs_that_compute(short_sequence, tmp_path, monkeypatch):
    cfg = TrackConfig(algo="sppso", fps=20.0, seed=3)
    setup = prepare_track(short_sequence, cfg, None)
    plain = run_tracker(setup, 0, None)
    assert plain.feature_store is None
    first = run_tracker(setup, 0, None, feature_cache=tmp_path / "features")
    T = len(setup.frame_indices)
    assert first.feature_store["computed"] == T and first.feature_store["read"] == 0
    stored = sorted((tmp_path / "features").glob("*/*.bits"))
    assert len(stored) == T

    def no_images(self, k):  # a run from the store never decodes an image
        raise AssertionError(f"frame {k} decoded although it is stored")

    probe = open_sequence(short_sequence)
    probe.close()
    monkeypatch.setattr(type(probe), "images", no_images)
    second = run_tracker(setup, 0, None, feature_cache=tmp_path / "features")
    assert second.feature_store["read"] == T and second.feature_store["computed"] == 0
    for res in (first, second):
        np.testing.assert_array_equal(res.params, plain.params)
        np.testing.assert_array_equal(res.scores, plain.scores)


def test_the_store_gives_the_computed_features_and_recomputes_a_damaged_frame(short_sequence, tmp_path):
    seq = open_sequence(short_sequence)
    try:
        bgs = seq.backgrounds()
        cams = seq.cameras
        shape = (len(cams), cams[0].height, cams[0].width)
        opts = ({"threshold": 30}, {"sigma_px": 1.5})
        store = FeatureStore.for_sequence(tmp_path, short_sequence, [c.name for c in cams], opts, shape)
        want = compute_features(seq.images(4), bgs, cams, silhouette_options=opts[0], edge_options=opts[1])
        for _ in range(2):  # computed and stored, then read back
            got = frame_observation(seq, 4, "silhouette_edge", 1, bgs, opts, None, None, store)
            np.testing.assert_array_equal(got.silhouettes, want.silhouettes)
            np.testing.assert_array_equal(got.edges, want.edges)
        assert (store.computed, store.read) == (1, 1)
        f = store.folder / "0000004.bits"
        f.write_bytes(f.read_bytes()[:-9])  # a file cut short reads as missing: computed and replaced
        assert store.get(4) is None
        got = frame_observation(seq, 4, "silhouette_edge", 1, bgs, opts, None, None, store)
        np.testing.assert_array_equal(got.edges, want.edges)
        assert store.computed == 2 and store.get(4) is not None
        # other options, other views: another store; the same ones: the same store
        again = FeatureStore.for_sequence(tmp_path, short_sequence, [c.name for c in cams], opts, shape)
        other = FeatureStore.for_sequence(tmp_path, short_sequence, [c.name for c in cams], ({}, {}), shape)
        fewer = FeatureStore.for_sequence(tmp_path, short_sequence, [cams[0].name], opts, (1, *shape[1:]))
        assert again.folder == store.folder and len({store.folder, other.folder, fewer.folder}) == 3
        with pytest.raises(DataError, match="shape"):
            store.put(5, np.zeros((1, 2, 2)), np.zeros((1, 2, 2)))
    finally:
        seq.close()


def test_a_dataset_spec_gets_no_store_and_an_unwritable_root_is_named(short_sequence, tmp_path):
    assert FeatureStore.for_sequence(tmp_path, "humaneva:S1/Walking_1", ["C1"], ({}, {}), (1, 4, 4)) is None
    blocker = tmp_path / "file"
    blocker.write_text("not a folder")
    with pytest.raises(DataError, match="feature store .*file"):
        FeatureStore.for_sequence(blocker, short_sequence, ["BW1"], ({}, {}), (1, 4, 4))
