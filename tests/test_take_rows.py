"""base.arrays.take_rows: fancy indexing's values through np.take where that is faster."""

from __future__ import annotations

import numpy as np
import pytest

from lidarsim_core.base.arrays import take_rows


@pytest.mark.parametrize("shape", [(50,), (50, 3), (50, 3, 3)])
@pytest.mark.parametrize("kind", ["sorted", "shuffled", "negative", "empty", "mask", "uint"])
def test_take_rows_equals_fancy_indexing(shape, kind):
    rng = np.random.default_rng(7)
    array = rng.normal(size=shape)
    rows = {"sorted": np.sort(rng.choice(50, 20, replace=False)),
            "shuffled": rng.permutation(50)[:30], "negative": np.array([-1, -50, 3]),
            "empty": np.zeros(0, dtype=np.int64), "mask": rng.random(50) < 0.4,
            "uint": np.array([4, 1, 4], dtype=np.uint32)}[kind]
    taken = take_rows(array, rows)
    expected = array[rows]
    assert taken.shape == expected.shape and taken.dtype == expected.dtype
    assert np.array_equal(taken.view(np.uint8), expected.view(np.uint8))


def test_out_of_range_rows_are_refused_as_by_indexing():
    with pytest.raises(IndexError):
        take_rows(np.zeros((5, 3)), np.array([5]))
