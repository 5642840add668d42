"""Built-in plugin: the static trajectory (a fixed pose)."""

from __future__ import annotations

from typing import Any

import numpy as np
from scipy.spatial.transform import Rotation

from ..geometry.poses import Poses
from ..geometry.posing import PoseMatrices
from ..hookspecs import hookimpl
from ..scenario.pose import PoseConfig
from .base import Trajectory


class StaticTrajectory(Trajectory):
    """A pose that never changes (the seed paper's set-up)."""

    name = "static"
    Options = PoseConfig
    is_static = True

    def __init__(self, options: PoseConfig | None = None) -> None:
        super().__init__(options)
        self._pose = self.options.to_pose()

    def poses_at(self, t: np.ndarray) -> Poses:
        n = len(np.atleast_1d(t))
        quat = np.tile(self._pose.rotation.as_quat().reshape(1, 4), (n, 1))
        return Poses(np.repeat(self._pose.position, n, axis=0), Rotation.from_quat(quat))

    def pose_matrices(self, t: np.ndarray) -> PoseMatrices:
        n = len(np.atleast_1d(t))
        matrix = self._pose.rotation.as_matrix().reshape(1, 3, 3)
        return PoseMatrices(np.repeat(self._pose.position, n, axis=0),
                            np.repeat(matrix, n, axis=0))


@hookimpl
def lidarsim_register_trajectories(register: Any) -> None:
    """Register the static trajectory."""
    register(StaticTrajectory)
