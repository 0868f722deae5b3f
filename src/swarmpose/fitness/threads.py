"""The fitness batch on several threads, with workers that wait spinning between batches.

A tracker scores 20-odd poses per call, 50-100 calls per frame, with the optimiser's Python work (a few
hundred microseconds) between calls. Handing each call's second half to a pool thread that sleeps between calls
costs two wake-ups per call (the worker's and, at the end, the caller's): 130-200 µs per call on a 2-core
virtual machine, 12-20 ms per frame of the walk. Here the worker waits for the next batch spinning
(``sched_yield`` between looks, so that other threads of the same or lower priority still run; the read-ahead
of the next frame does), for at most ``spin_us``, and only then sleeps; the caller waits for the worker's
chunk the same way.

The flags that the spinning threads watch are hints only: each is set *inside* GIL-free compiled code (the
caller's first kernel call, the worker's wait), so that the thread that sees it finds the GIL free and does
not sleep on it; the batch itself (chunks claimed, chunks finished) is handed over under a lock, which orders
the results written by one thread before the other reads them, on any memory model.
"""

from __future__ import annotations

import os
import sys
import threading
from collections.abc import Callable

import numba as nb
import numpy as np
from llvmlite import ir
from numba.core import cgutils, types
from numba.extending import intrinsic

__all__ = ["SPIN_SUPPORTED", "BatchThreads", "fetch_add", "load_acquire", "store_release", "wait_until_equal",
           "wait_for_newer"]

#: ``sched_yield`` is POSIX: elsewhere the workers sleep between batches.
SPIN_SUPPORTED = sys.platform != "win32"


def _item_pointer(context, builder, sig, args):
    """The pointer to ``arr[idx]`` (the intrinsics' first two arguments) and ``arr``'s element type."""
    aryty = sig.args[0]
    ary = context.make_array(aryty)(context, builder, args[0])
    return cgutils.get_item_pointer(context, builder, aryty, ary, [args[1]], wraparound=False), aryty.dtype


@intrinsic
def load_acquire(typingctx, arr, idx):
    """``arr[idx]`` read with acquire ordering (an atomic load the compiler cannot hoist out of a loop)."""
    def codegen(context, builder, sig, args):
        ptr, _ = _item_pointer(context, builder, sig, args)
        return builder.load_atomic(ptr, "acquire", 8)

    return arr.dtype(arr, idx), codegen


@intrinsic
def store_release(typingctx, arr, idx, value):
    """``arr[idx] = value`` with release ordering (``arr``: int64)."""
    def codegen(context, builder, sig, args):
        ptr, dtype = _item_pointer(context, builder, sig, args)
        builder.store_atomic(context.cast(builder, args[2], sig.args[2], dtype), ptr, "release", 8)
        return context.get_dummy_value()

    return types.void(arr, idx, value), codegen


@intrinsic
def fetch_add(typingctx, arr, idx, value):
    """``old = arr[idx]; arr[idx] += value`` as one atomic step (acquire-release); returns ``old`` (``arr``: int64)."""
    def codegen(context, builder, sig, args):
        ptr, dtype = _item_pointer(context, builder, sig, args)
        return builder.atomic_rmw("add", ptr, context.cast(builder, args[2], sig.args[2], dtype), "acq_rel")

    return arr.dtype(arr, idx, value), codegen


@intrinsic
def _sched_yield(typingctx):
    def codegen(context, builder, sig, args):
        fn = cgutils.get_or_insert_function(builder.module, ir.FunctionType(ir.IntType(32), []), "sched_yield")
        builder.call(fn, [])
        return context.get_dummy_value()

    return types.void(), codegen


@nb.njit(cache=True, nogil=True)
def wait_for_newer(flag, seen, max_looks, mark, mark_value):
    """Set ``mark[0] = mark_value`` (when ``mark`` has an element), then look at ``flag[0]`` until it exceeds
    ``seen``, yielding the core between looks, at most ``max_looks`` times. Returns whether it did."""
    if mark.shape[0] > 0:
        store_release(mark, 0, mark_value)
    for _ in range(max_looks):
        if load_acquire(flag, 0) > seen:
            return True
        _sched_yield()
    return load_acquire(flag, 0) > seen


@nb.njit(cache=True, nogil=True)
def wait_until_equal(flag, value, max_looks):
    """Look at ``flag[0]`` until it equals ``value``, yielding the core between looks, at most ``max_looks``
    times. Returns whether it did."""
    for _ in range(max_looks):
        if load_acquire(flag, 0) == value:
            return True
        _sched_yield()
    return load_acquire(flag, 0) == value


class _Batch:
    """One call's chunks: claimed and finished under ``lock``."""

    def __init__(self, chunks: list[np.ndarray], run: Callable[[np.ndarray], None]):
        self.chunks = chunks
        self.run = run
        self.claimed = 0
        self.finished = 0
        self.lock = threading.Lock()
        self.all_done = threading.Condition(self.lock)

    def claim(self) -> np.ndarray | None:
        with self.lock:
            if self.claimed == len(self.chunks):
                return None
            self.claimed += 1
            return self.chunks[self.claimed - 1]

    def finish(self) -> None:
        with self.lock:
            self.finished += 1
            if self.finished == self.claimed:
                self.all_done.notify_all()

    def done(self) -> bool:
        with self.lock:
            return self.finished == self.claimed == len(self.chunks)


class _Shared:
    """One call whose items every thread claims one at a time inside compiled code (:meth:`BatchThreads.share`)."""

    def __init__(self, run: Callable[[], None]):
        self.run = run


class BatchThreads:
    """Chunks of a batch run by the calling thread and ``n - 1`` workers that spin for ``spin_us`` between
    batches before they sleep.

    ``map(n_items, run, first)``: the items ``0 .. n_items - 1`` are cut into ``n`` contiguous chunks;
    ``first(chunk, go, seq)`` runs the caller's first chunk and must call :func:`store_release` ``(go, 0, seq)``
    as soon as it runs without the GIL (it tells a spinning worker that the batch is there and the GIL free);
    ``run(chunk)`` runs any other chunk without the GIL. A chunk a late worker has not claimed is run by the caller.
    Returns when every chunk has run. One batch at a time (calls from several threads are serialised).
    """

    LOOKS_PER_US = 1.0  # one look costs about a microsecond (a sched_yield system call)

    def __init__(self, n: int, *, spin_us: float = 2000.0):
        self.n = max(1, int(n))
        self.spin_looks = int(spin_us * self.LOOKS_PER_US) if SPIN_SUPPORTED else 0
        self.go = np.zeros(1, np.int64)  # the batch number the caller has started (hint)
        self.idle = np.zeros(1, np.int64)  # the batch number a worker has finished (hint)
        self._seq = 0
        self._batch: _Batch | None = None
        self._closed = False
        self._cond = threading.Condition()
        self._serial = threading.Lock()
        self._pid = os.getpid()
        self._threads = [threading.Thread(target=self._work, name=f"swarmpose-fitness-{i + 1}", daemon=True)
                         for i in range(self.n - 1)]
        for t in self._threads:
            t.start()

    @property
    def alive(self) -> bool:
        """False in a child process after ``fork()`` (it has no worker threads) or after :meth:`close`."""
        return not self._closed and self._pid == os.getpid()

    def map(self, n_items: int, run: Callable[[np.ndarray], None],
            first: Callable[[np.ndarray, np.ndarray, int], None]) -> None:
        with self._serial:
            size = max(1, -(-n_items // self.n))
            batch = _Batch([np.arange(a, min(a + size, n_items)) for a in range(0, n_items, size)], run)
            with self._cond:
                self._seq += 1
                seq = self._seq
                self._batch = batch
                self._cond.notify_all()  # a worker asleep (no system call when none is)
            chunk = batch.claim()
            if chunk is None:
                return
            first(chunk, self.go, seq)
            batch.finish()
            while (chunk := batch.claim()) is not None:
                run(chunk)
                batch.finish()
            if not batch.done():
                wait_until_equal(self.idle, seq, self.spin_looks)  # the worker's chunk, spinning (no GIL held)
                with batch.lock:
                    while batch.finished != batch.claimed:
                        batch.all_done.wait()

    def share(self, run: Callable[[], None], first: Callable[[np.ndarray, int], None], done: np.ndarray,
              total: int) -> None:
        """One batch whose ``total`` items every thread claims one at a time: ``run()`` claims and runs items
        until none is left (without the GIL), adding 1 to ``done[0]`` (:func:`fetch_add`) after each;
        ``first(go, seq)`` does the same on the calling thread after :func:`store_release` ``(go, 0, seq)``,
        once it runs without the GIL. A late worker finds fewer items or none; returns when ``done[0]`` is
        ``total``. The items are spread as they are claimed, so that the threads finish together."""
        with self._serial:
            with self._cond:
                self._seq += 1
                seq = self._seq
                self._batch = _Shared(run)
                self._cond.notify_all()  # a worker asleep (no system call when none is)
            first(self.go, seq)
            # the items the workers claimed and still run: each is short, wait spinning (without the GIL)
            while not wait_until_equal(done, total, max(self.spin_looks, 1000)):
                pass

    def _work(self) -> None:
        seen = 0
        while True:
            # wait for a batch newer than `seen`: spinning first, then asleep
            if not wait_for_newer(self.go, seen, self.spin_looks, self.idle, seen):
                with self._cond:
                    while self._seq == seen and not self._closed:
                        self._cond.wait()
            with self._cond:
                if self._closed:
                    return
                seq, batch = self._seq, self._batch
            if seq == seen or batch is None:
                continue
            seen = seq
            if isinstance(batch, _Shared):
                batch.run()
                continue
            while (chunk := batch.claim()) is not None:
                batch.run(chunk)
                batch.finish()

    def close(self) -> None:
        """Stop the workers (they finish the batch they run)."""
        with self._cond:
            self._closed = True
            self._cond.notify_all()
