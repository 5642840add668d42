"""The sensor's and every target's poses at a few instants (a frame's start and end), looked
up once for the checks and the metadata of a frame.

:meth:`Simulation.run_frame <lidarsim_core.pipeline.simulation.Simulation.run_frame>` refuses a
sensor inside a target at the frame's start and end
(:func:`~lidarsim_core.pipeline.inside.check_sensor_outside`) and records the poses at those
instants in the frame's metadata (:func:`~lidarsim_core.pipeline.frameinfo.frame_infos`). Both
read the trajectories' SciPy path (``poses_at``) at the same times: ~0.1–0.2 ms per
trajectory on a tumbling or HCW scene, paid twice per frame before they shared a
:class:`SpanPoses`. The lookup is the same call on the same times, so what both make of it is
the same to the bit.
"""

from __future__ import annotations

from dataclasses import dataclass

import numpy as np

from ..geometry.poses import Poses
from .context import RunContext


@dataclass(frozen=True, eq=False)
class SpanPoses:
    """The poses of a run's trajectories at ``times``.

    Attributes
    ----------
    times
        (T,) float64 instants (s).
    sensor
        The sensor's T poses.
    targets
        Each target's T poses, in the run's target order.
    """

    times: np.ndarray
    sensor: Poses
    targets: list[Poses]

    def at(self, times: np.ndarray) -> "SpanPoses | None":
        """These poses when they were looked up at exactly ``times``, else None."""
        return self if same_times(self.times, times) else None


def same_times(a: np.ndarray, b: np.ndarray) -> bool:
    """Whether two arrays of instants are the same instants, in the same order."""
    return a.shape == b.shape and bool(np.all(a == b))


def span_poses(ctx: RunContext, times: np.ndarray) -> SpanPoses:
    """The sensor's and every target's poses at ``times`` (their trajectories' ``poses_at``)."""
    times = np.asarray(times, dtype=np.float64)
    return SpanPoses(times, ctx.sensor_trajectory.poses_at(times),
                     [target.trajectory.poses_at(times) for target in ctx.targets])
