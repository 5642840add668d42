"""Base class of trajectory plugins."""

from __future__ import annotations

from abc import abstractmethod
from typing import TYPE_CHECKING, Any

import numpy as np

from ..base.components import Component
from ..geometry.poses import Poses

if TYPE_CHECKING:
    from ..geometry.posing import PoseMatrices


class Trajectory(Component):
    """A body→scene pose as a function of time.

    Subclasses implement :meth:`poses_at`, vectorised over timestamps. Times are seconds from
    the scenario's epoch (the start of the first frame). A subclass may also implement
    :meth:`pose_matrices` (the same poses as arrays, without SciPy rotations, for the hot
    path); the pipeline uses it only when it is defined by the class that defines
    :meth:`poses_at` or a subclass of it (:func:`lidarsim_core.trajectories.matrices.has_fast_path`).
    """

    #: True when the pose never changes, so the pipeline can skip per-ray look-ups.
    is_static: bool = False

    @abstractmethod
    def poses_at(self, t: np.ndarray) -> Poses:
        """Poses at times ``t`` ((N,) float64 seconds); returns N poses."""

    def check_span(self, t0: float, t1: float, *, source: Any, field: str) -> None:
        """Refuse a time span ``[t0, t1]`` whose poses would cost an unbounded amount of work
        (:mod:`lidarsim_core.base.limits`); most trajectories are closed forms and accept any.

        Raises
        ------
        ConfigError
            Naming ``source`` and ``field`` (the trajectory's own fields below it).
        """

    def motion_rates(self, t0: float, t1: float) -> tuple[float, float] | None:
        """Upper bounds on the body's angular speed (rad/s) and on the speed of its origin
        (m/s) at every time in ``[t0, t1]``, or None when the trajectory gives none (the
        default).

        The pipeline's culling uses them to bound how far a body moves among a piece's rays
        without a pose per ray (:mod:`lidarsim_core.pipeline.cull`); a bound that is too small
        would drop pulses that hit, so a trajectory returns None unless the bound is certain.
        They are used only when defined by the class that defines :meth:`poses_at` and
        :meth:`pose_matrices` or a subclass of it
        (:func:`lidarsim_core.trajectories.matrices.motion_rates`).
        """
        return None

    def pose_matrices(self, t: np.ndarray) -> "PoseMatrices":
        """Poses at times ``t`` as (N, 3) positions and (N, 3, 3) rotation matrices (default:
        from :meth:`poses_at`)."""
        from ..geometry.posing import PoseMatrices

        return PoseMatrices.from_poses(self.poses_at(t))
