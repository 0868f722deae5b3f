"""The tracking process's mmap threshold: fixed, a mid-sized buffer is mapped from the system even after a large
one was freed (glibc's own dynamic threshold would rise to the large one's size and usually grow the heap for it;
usually, not always, so only the fixed case is asserted)."""

from __future__ import annotations

import os
import subprocess
import sys

import pytest

PROBE = r"""
import sys
import numpy as np
from swarmpose.track.heap import fix_mmap_threshold
was_set = fix_mmap_threshold() if sys.argv[1] == "fixed" else False
big = np.ones(16 << 20, np.uint8)
del big  # glibc's dynamic threshold would now rise to 16 MiB
mid = np.ones(4 << 20, np.uint8)  # more than the heap holds free: it grows the heap, or is mapped on its own
address = mid.ctypes.data
for line in open("/proc/self/maps"):
    span, *rest = line.split()
    lo, hi = (int(x, 16) for x in span.split("-"))
    if lo <= address < hi:
        print(was_set, "heap" if line.rstrip().endswith("[heap]") else "own mapping")
"""


def _where(mode: str) -> str:
    env = {k: v for k, v in os.environ.items() if k != "MALLOC_MMAP_THRESHOLD_"}
    return subprocess.run([sys.executable, "-c", PROBE, mode], capture_output=True, text=True, env=env,
                          check=True).stdout.strip()


@pytest.mark.skipif(not sys.platform.startswith("linux") or not os.path.exists("/proc/self/maps"),
                    reason="glibc's malloc on Linux")
def test_a_mid_sized_buffer_stays_off_the_heap_with_the_threshold_fixed():
    assert _where("fixed") == "True own mapping"


def test_the_users_own_setting_is_left_alone(monkeypatch):
    from swarmpose.track.heap import fix_mmap_threshold

    monkeypatch.setenv("MALLOC_MMAP_THRESHOLD_", "65536")
    assert fix_mmap_threshold() is False
