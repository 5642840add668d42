"""Direction groups of patterns that fire slots in cycles
(:func:`lidarsim_core.patterns.base.cycle_groups`), in numba.

The same groups as the NumPy code, made and expanded in two loops that release the GIL: a
piece of 50,000 pulses spent ~0.2 ms in a dozen small NumPy calls here, during which a second
thread's piece waited to run its own Python steps.
"""

from __future__ import annotations

import numpy as np
from numba import njit


@njit(nogil=True, cache=True)
def slot_groups(first, last, size, cycles):  # noqa: ANN001, ANN201
    """The groups of rays ``first..last``: per block of ``cycles`` cycles and slot (of
    ``size``), the first and last cycle whose ray lies in the range; returns the
    representatives (the middle cycle's ray), the first and last cycles and the slots,
    in order of block, then slot."""
    block0 = first // size // cycles
    blocks = last // size // cycles - block0 + 1
    representative = np.empty(blocks * size, dtype=np.int64)
    low = np.empty(blocks * size, dtype=np.int64)
    high = np.empty(blocks * size, dtype=np.int64)
    slot = np.empty(blocks * size, dtype=np.int64)
    count = 0
    for b in range(blocks):
        block = block0 + b
        for s in range(size):
            lo = max(block * cycles, -((s - first) // size))
            hi = min(block * cycles + cycles - 1, (last - s) // size)
            if lo <= hi:
                representative[count] = (lo + hi) // 2 * size + s
                low[count], high[count], slot[count] = lo, hi, s
                count += 1
    return representative[:count], low[:count], high[:count], slot[:count]


@njit(nogil=True, cache=True)
def group_members(low, high, slot, size, groups):  # noqa: ANN001, ANN201
    """The rays (ascending) of the groups at positions ``groups`` (ascending) of
    :func:`slot_groups`' arrays."""
    total = 0
    for g in groups:
        total += high[g] - low[g] + 1
    rays = np.empty(total, dtype=np.int64)
    k = 0
    for g in groups:
        for cycle in range(low[g], high[g] + 1):
            rays[k] = cycle * size + slot[g]
            k += 1
    return rays if size == 1 else np.sort(rays)
