"""A trajectory's poses as matrices: its closed form when it has one, else ``poses_at``.
"""

from __future__ import annotations

from typing import TYPE_CHECKING

import numpy as np

if TYPE_CHECKING:
    from .base import Trajectory
from ..geometry.posing import PoseMatrices


def _defining_class(cls: type, name: str) -> int:
    """Position in ``cls``'s MRO of the class that defines ``name``."""
    for position, klass in enumerate(cls.__mro__):
        if name in vars(klass):
            return position
    return len(cls.__mro__)


def has_fast_path(trajectory: "Trajectory") -> bool:
    """Whether ``trajectory``'s own class implements ``pose_matrices`` alongside (or below)
    ``poses_at``, so that the two describe the same motion."""
    cls = type(trajectory)
    return _defining_class(cls, "pose_matrices") <= _defining_class(cls, "poses_at") and \
        not getattr(trajectory.poses_at, "__lidarsim_guarded__", False)


def pose_matrices(trajectory: "Trajectory", t: np.ndarray) -> PoseMatrices:
    """The poses of ``trajectory`` at ``t`` as matrices: the closed form when the trajectory
    has one (:func:`has_fast_path`), else through ``poses_at``."""
    if has_fast_path(trajectory):
        return trajectory.pose_matrices(t)
    return PoseMatrices.from_poses(trajectory.poses_at(t))


def motion_rates(trajectory: "Trajectory", t0: float, t1: float) -> tuple[float, float] | None:
    """``trajectory``'s bounds on its angular speed (rad/s) and speed (m/s) over ``[t0, t1]``
    (:meth:`~lidarsim_core.trajectories.base.Trajectory.motion_rates`): ``(0, 0)`` for a
    static one, None when it gives none or when a subclass redefines its poses below the
    class that gives the bounds (they would describe another motion)."""
    if trajectory.is_static:
        return (0.0, 0.0)
    cls = type(trajectory)
    rates_at = _defining_class(cls, "motion_rates")
    if rates_at > _defining_class(cls, "poses_at") or \
            rates_at > _defining_class(cls, "pose_matrices") or not has_fast_path(trajectory):
        return None
    rates = trajectory.motion_rates(float(t0), float(t1))
    if rates is None:
        return None
    angular, linear = (float(r) for r in rates)
    if not (0.0 <= angular < float("inf") and 0.0 <= linear < float("inf")):
        return None
    return angular, linear
