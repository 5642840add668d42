"""Base class of trajectory plugins."""

from __future__ import annotations

from abc import abstractmethod
from typing import TYPE_CHECKING

import numpy as np

from ..components import Component
from ..poses import Poses

if TYPE_CHECKING:
    from ..posing import PoseMatrices


class Trajectory(Component):
    """A body→scene pose as a function of time.

    Subclasses implement :meth:`poses_at`, vectorised over timestamps. Times are seconds from
    the scenario's epoch (the start of the first frame). A subclass may also implement
    :meth:`pose_matrices` (the same poses as arrays, without SciPy rotations, for the hot
    path); the pipeline uses it only when it is defined by the class that defines
    :meth:`poses_at` or a subclass of it (:func:`lidarsim_core.posing.has_fast_path`).
    """

    #: True when the pose never changes, so the pipeline can skip per-ray look-ups.
    is_static: bool = False

    @abstractmethod
    def poses_at(self, t: np.ndarray) -> Poses:
        """Poses at times ``t`` ((N,) float64 seconds); returns N poses."""

    def pose_matrices(self, t: np.ndarray) -> "PoseMatrices":
        """Poses at times ``t`` as (N, 3) positions and (N, 3, 3) rotation matrices (default:
        from :meth:`poses_at`)."""
        from ..posing import PoseMatrices

        return PoseMatrices.from_poses(self.poses_at(t))
