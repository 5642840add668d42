"""NumPy floating-point warnings kept off the terminal while inputs that would cause them are
refused with messages of their own.
"""

from __future__ import annotations

from contextlib import contextmanager
from typing import Iterator


@contextmanager
def quiet_numerics() -> Iterator[None]:
    """While the block runs, NumPy floating-point warnings (overflow, invalid values) are not
    printed: inputs that would cause them are refused with a message of their own, and a
    warning line would break the one-line error contract of the CLI."""
    import warnings

    import numpy as np

    with warnings.catch_warnings(), np.errstate(all="ignore"):
        warnings.simplefilter("ignore", RuntimeWarning)
        yield
