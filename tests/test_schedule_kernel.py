"""The compiled firing schedule (lidarsim_core.kernels.patterns.cycle_rays) gives NumPy's
times, slots and channels bit for bit on any index array: contiguous runs (where it steps
instead of dividing), jumps, repeats, descending and negative indices, one- and many-slot
cycles."""

from __future__ import annotations

import numpy as np
import pytest

from lidarsim_core.patterns.timing import FiringCycle

pytest.importorskip("numba", reason="the compiled schedule needs the 'fast' extra")

from lidarsim_core.kernels.patterns import cycle_rays  # noqa: E402


def _indices(rng: np.random.Generator) -> np.ndarray:
    runs = [np.arange(start, start + length) for start, length in
            zip(rng.integers(-50, 10**12, 40), rng.integers(0, 3000, 40))]
    runs.append(rng.integers(0, 10**6, 5000))  # unordered, with repeats
    runs.append(np.arange(20_000, 0, -1))  # descending
    return np.concatenate(runs).astype(np.int64)


@pytest.mark.parametrize("slots", [1, 2, 6, 16, 257])
def test_schedule_kernel_matches_numpy_bit_for_bit(slots):
    rng = np.random.default_rng(slots)
    offsets = np.sort(rng.uniform(0, 1e-3, slots))
    offsets[0] = 0.0
    cycle = FiringCycle(1e-3 + 1e-6 * slots, offsets, rng.integers(0, 64, slots))
    index = _indices(rng)
    t, slot, channel = cycle_rays(index, cycle.size, float(cycle.period_s), cycle.offsets_s,
                                  cycle.channels)
    np.testing.assert_array_equal(slot, index % slots)
    assert t.tobytes() == cycle.time(index).tobytes()
    np.testing.assert_array_equal(channel, cycle.channels[index % slots])
    assert channel.dtype == np.int16
