"""The fitness batch's threads: every item run once, by whichever thread claims it, whatever the timing."""

from __future__ import annotations

import threading
import time

import numba as nb
import numpy as np
import pytest

from swarmpose.fitness.threads import BatchThreads, fetch_add, store_release, wait_for_newer, wait_until_equal


@nb.njit(nogil=True)
def _square_into(idx, x, out, tid, me):
    for i in idx:
        out[i] = x[i] * x[i]
        tid[i] = me


@nb.njit(nogil=True)
def _square_into_go(go, seq, idx, x, out, tid, me):
    store_release(go, 0, seq)
    _square_into(idx, x, out, tid, me)


def _map(bt, x, out, tid, delay=0.0):
    def run(idx):
        if delay:
            time.sleep(delay)
        _square_into(idx, x, out, tid, threading.get_ident() % 1000 + 1)

    bt.map(x.shape[0], run, lambda idx, go, seq: _square_into_go(go, seq, idx, x, out, tid, 0))


def _map_batch(bt, x, out, tid, slow):
    _map(bt, x, out, tid, delay=0.002 if slow else 0.0)


def _share_batch(bt, x, out, tid, slow):
    done = _share(bt, x, out, tid, 200_000 if slow else 2000)  # every item a few µs, now and then much slower
    assert done[0] == x.shape[0]


@pytest.mark.parametrize("n", [2, 3])
@pytest.mark.parametrize("dispatch", [_map_batch, _share_batch], ids=["chunks", "items claimed"])
def test_every_item_once_over_many_batches(n, dispatch):
    """``map`` (a chunk per thread) and ``share`` (items claimed one at a time with an atomic counter): each
    item runs exactly once, by one thread, also when the workers come late or fall asleep between batches."""
    bt = BatchThreads(n)
    rng = np.random.default_rng(n)
    by_worker = 0
    try:
        for k in range(600):
            size = int(rng.integers(1, 60))
            x = rng.normal(size=size)
            out = np.full(size, np.nan)
            tid = np.full(size, -1, np.int64)
            # now and then the workers' items are slow, or the caller pauses (a worker falls asleep)
            dispatch(bt, x, out, tid, k % 50 == 7)
            if k % 100 == 99:
                time.sleep(0.02)
            np.testing.assert_array_equal(out, x * x)
            assert np.all(tid >= 0)
            by_worker += int(np.count_nonzero(tid > 0))
    finally:
        bt.close()
    assert by_worker > 0  # the workers did take part


def test_batches_from_two_threads_are_serialised():
    bt = BatchThreads(2)
    errors = []

    def client(seed):
        rng = np.random.default_rng(seed)
        for _ in range(200):
            x = rng.normal(size=int(rng.integers(1, 40)))
            out = np.full(x.shape, np.nan)
            _map(bt, x, out, np.zeros(x.shape, np.int64))
            if not np.array_equal(out, x * x):
                errors.append(seed)

    ts = [threading.Thread(target=client, args=(s,)) for s in range(2)]
    for t in ts:
        t.start()
    for t in ts:
        t.join(timeout=120)
    bt.close()
    assert not errors


def test_closed_workers_end():
    bt = BatchThreads(3)
    x = np.arange(10.0)
    _map(bt, x, np.empty(10), np.empty(10, np.int64))
    bt.close()
    for t in bt._threads:
        t.join(timeout=10)
        assert not t.is_alive()
    assert not bt.alive


def test_waits_see_a_flag_set_by_another_thread():
    flag, mark = np.zeros(1, np.int64), np.zeros(1, np.int64)
    assert not wait_for_newer(flag, 0, 50, mark, 7) and mark[0] == 7  # marks, then gives up
    assert not wait_until_equal(flag, 3, 50)
    threading.Timer(0.01, lambda: flag.__setitem__(0, 3)).start()
    assert wait_until_equal(flag, 3, 10**9)  # bounded by the looks, ended by the flag
    assert wait_for_newer(flag, 2, 1, np.zeros(0, np.int64), 0)


@nb.njit(nogil=True)
def _claim_squares(claim, done, x, out, tid, me, spin):
    while True:
        i = fetch_add(claim, 0, 1)
        if i >= x.shape[0]:
            return
        slow = 0.0
        for _ in range(spin):  # work that takes time (its result is used, so it is not optimised away)
            slow = slow * 0.5 + 1.0
        out[i] = x[i] * x[i] + (slow - slow)
        tid[i] = me
        fetch_add(done, 0, 1)


@nb.njit(nogil=True)
def _claim_squares_go(go, seq, claim, done, x, out, tid, me, spin):
    store_release(go, 0, seq)
    _claim_squares(claim, done, x, out, tid, me, spin)


def _share(bt, x, out, tid, spin):
    claim, done = np.zeros(1, np.int64), np.zeros(1, np.int64)  # one pair per batch, as the backend's
    bt.share(lambda: _claim_squares(claim, done, x, out, tid, 1, spin),
             lambda go, seq: _claim_squares_go(go, seq, claim, done, x, out, tid, 0, spin), done, x.shape[0])
    assert claim[0] >= x.shape[0]
    return done


def test_fetch_add_counts_every_claim_once_across_threads():
    counter, seen = np.zeros(1, np.int64), np.zeros(200_000, np.int64)

    @nb.njit(nogil=True)
    def take(counter, seen):
        while True:
            i = fetch_add(counter, 0, 1)
            if i >= seen.shape[0]:
                return
            seen[i] += 1

    ts = [threading.Thread(target=take, args=(counter, seen)) for _ in range(3)]
    for t in ts:
        t.start()
    for t in ts:
        t.join(timeout=60)
    assert np.all(seen == 1) and counter[0] >= seen.shape[0]
