"""The tracker's read-ahead of the next frame's observation (swarmpose.track.observation.Prefetcher)."""

from __future__ import annotations

import threading

import numpy as np
import pytest

from swarmpose.errors import DataError
from swarmpose.track.observation import Prefetcher


def test_returns_each_position_and_reads_ahead_on_one_worker():
    calls, threads = [], set()

    def load(i):
        calls.append(i)
        threads.add(threading.get_ident())
        return np.full(3, i)

    with Prefetcher(load, 5) as p:
        got = [int(p.get(i)[0]) for i in range(5)]
    assert got == [0, 1, 2, 3, 4]
    assert calls == [0, 1, 2, 3, 4]  # each frame loaded once, in order, none past the end
    assert len(threads) == 1 and threading.get_ident() not in threads


def test_out_of_order_positions_are_loaded_as_asked():
    calls = []

    def load(i):
        calls.append(i)
        return i

    with Prefetcher(load, 10) as p:
        assert p.get(3) == 3  # (resuming at frame 3)
        assert p.get(7) == 7  # the read-ahead of 4 is dropped, 7 is loaded
        assert p.get(8) == 8
    assert calls[:3] == [3, 4, 7] and calls.count(8) == 1


def test_a_load_error_is_raised_by_the_get_of_that_position():
    def load(i):
        if i == 2:
            raise DataError(f"frame {i} has no images")
        return i

    with Prefetcher(load, 4) as p:
        assert p.get(0) == 0
        assert p.get(1) == 1  # frame 2 fails in the background: not raised here
        with pytest.raises(DataError, match="frame 2 has no images"):
            p.get(2)


def test_disabled_loads_in_the_calling_thread():
    threads = []
    p = Prefetcher(lambda i: threads.append(threading.get_ident()) or i, 3, enabled=False)
    assert [p.get(i) for i in range(3)] == [0, 1, 2]
    p.close()
    assert set(threads) == {threading.get_ident()}


def test_close_waits_for_the_load_in_flight_and_drops_its_error():
    started = threading.Event()

    def load(i):
        if i == 1:
            started.set()
            raise DataError("broken")
        return i

    p = Prefetcher(load, 3)
    assert p.get(0) == 0
    p.close()  # frame 1's error is not raised by close
    assert started.is_set()
