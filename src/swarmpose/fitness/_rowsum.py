"""numpy's order of adding a row, in numba: compiled sums that equal numpy's ``row.sum()`` to the last bit."""

from __future__ import annotations

import numba as nb

__all__ = ["row_sum"]


@nb.njit(cache=True, nogil=True, inline="always")
def row_sum(row):
    """``row.sum()`` as numpy adds a row of up to 128 values (pairwise: 8 running sums from 8 values on)."""
    n = row.shape[0]
    if n < 8:
        r = -0.0
        for j in range(n):
            r += row[j]
        return r
    r0, r1, r2, r3, r4, r5, r6, r7 = row[0], row[1], row[2], row[3], row[4], row[5], row[6], row[7]
    j = 8
    while j < n - n % 8:
        r0 += row[j]
        r1 += row[j + 1]
        r2 += row[j + 2]
        r3 += row[j + 3]
        r4 += row[j + 4]
        r5 += row[j + 5]
        r6 += row[j + 6]
        r7 += row[j + 7]
        j += 8
    r = ((r0 + r1) + (r2 + r3)) + ((r4 + r5) + (r6 + r7))
    while j < n:
        r += row[j]
        j += 1
    return r
