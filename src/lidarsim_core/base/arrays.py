"""Array helpers of the hot path that NumPy offers in more than one form at different speeds."""

from __future__ import annotations

import numpy as np


def take_rows(array: np.ndarray, rows: np.ndarray) -> np.ndarray:
    """``array[rows]`` for an index array or a boolean mask ``rows`` along the first axis.

    The same values as fancy indexing; integer rows go through :func:`numpy.take`, which
    gathers whole rows ~4x faster (an (N, 3) direction array: 75 µs instead of 310 µs for
    41,600 of 65,536 rows; 17 µs instead of 25 µs for a 1-D array)."""
    rows = np.asarray(rows)
    if rows.dtype.kind in "iu" and array.ndim:
        return np.take(array, rows, axis=0)
    return array[rows]
