"""Base class of trajectory plugins."""

from __future__ import annotations

from abc import abstractmethod

import numpy as np

from ..components import Component
from ..poses import Poses


class Trajectory(Component):
    """A body→scene pose as a function of time.

    Subclasses implement :meth:`poses_at`, vectorised over timestamps. Times are seconds from
    the scenario's epoch (the start of the first frame).
    """

    #: True when the pose never changes, so the pipeline can skip per-ray look-ups.
    is_static: bool = False

    @abstractmethod
    def poses_at(self, t: np.ndarray) -> Poses:
        """Poses at times ``t`` ((N,) float64 seconds); returns N poses."""
