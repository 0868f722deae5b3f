"""``bench track --repeat``: a long recording made of a short one, forwards and backwards, the clock running on."""

from __future__ import annotations

import numpy as np
import pytest

from swarmpose.errors import ConfigError
from swarmpose.track.bench import repeated
from swarmpose.track.tracker import TrackConfig, prepare_track


def test_repeated_frames_keep_an_even_clock(short_sequence):
    setup = prepare_track(short_sequence, TrackConfig(fps=20.0), None)
    long = repeated(setup, 3)
    n = len(setup.frame_indices)
    assert len(long.frame_indices) == 3 * n - 2  # each turn plays its frame once
    np.testing.assert_array_equal(long.frame_indices[:n], setup.frame_indices)
    np.testing.assert_array_equal(long.frame_indices[n - 1:2 * n - 1], setup.frame_indices[::-1])  # backwards
    np.testing.assert_array_equal(long.gt_joints[2 * n - 2:], setup.gt_joints)
    np.testing.assert_array_equal(long.ik_params[n:2 * n - 1], setup.ik_params[-2::-1])
    steps = np.diff(long.frame_times)
    np.testing.assert_allclose(steps, steps[0])  # the clock runs on at the tracking rate
    assert repeated(setup, 1) is setup
    with pytest.raises(ConfigError, match="--repeat"):
        repeated(setup, 0)
