"""The C heap of a tracking process: large buffers taken straight from the system, so that a long run's heap does
not keep what the frames' buffers leave behind.

glibc's ``malloc`` raises its mmap threshold every time a block above it is freed (its dynamic threshold, up to
32 MiB). From then on the per-frame buffers between 128 KiB and that size come from the heap, where the freed
pieces do not always fit the next frames' buffers: over 3,000 frames of SPPSO the heap grew by about 0.33 KB
per frame (measured with ``/proc/self/status`` every 250 frames), by 0.23 KB per frame with the threshold fixed
at 1 MiB, and not over the first 1,000 frames with it fixed at glibc's own starting value, 128 KiB, which also
lowers an 85-frame run's resident memory by 6 MB; the features then cost about 1 ms more per frame (fresh
mappings are paged in). A 20,000-frame run still grows by about 0.25 KB per frame (``bench track``).

:func:`fix_mmap_threshold` sets it (``mallopt(M_MMAP_THRESHOLD)``, which also turns the dynamic threshold off). The
command line calls it at start and in every worker process; a program that calls the library itself may call it
too. A ``MALLOC_MMAP_THRESHOLD_`` in the environment is the user's choice and is left as it is; other C libraries
(musl, macOS, Windows) are left alone.
"""

from __future__ import annotations

import ctypes
import os
import sys

__all__ = ["fix_mmap_threshold", "MMAP_THRESHOLD"]

#: Blocks of at least this many bytes are mapped from the system and given back when freed.
MMAP_THRESHOLD = 128 * 1024
_M_MMAP_THRESHOLD = -3  # glibc's malloc.h


def fix_mmap_threshold(threshold: int = MMAP_THRESHOLD) -> bool:
    """Fix glibc's mmap threshold at ``threshold`` bytes for this process; True when it was set."""
    if "MALLOC_MMAP_THRESHOLD_" in os.environ or not sys.platform.startswith("linux"):
        return False
    try:
        mallopt = ctypes.CDLL("libc.so.6").mallopt
    except (OSError, AttributeError):  # not glibc
        return False
    mallopt.argtypes, mallopt.restype = [ctypes.c_int, ctypes.c_int], ctypes.c_int
    return bool(mallopt(_M_MMAP_THRESHOLD, int(threshold)))
