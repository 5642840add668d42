"""Body-frame ground truth: each noiseless point in its target's body frame (optional columns).

With ``scan.body_frame_truth: true`` the point record gains ``x_body``, ``y_body``, ``z_body``
(float64, m): the noiseless point ``x_true`` expressed in the body frame of the target it hit,
at the point's own ``timestamp`` (frame start with ``scan.motion: frozen``), i.e. the
coordinates of the hit on the target's mesh as ``lidarsim mesh`` writes it. These are
point-to-model correspondences for supervised learning and registration tests, with no pose
to recompute. Points that hit no target (false alarms) get NaN.
"""

from __future__ import annotations

import numpy as np

from ..geometry.frames import rotate, to_body
from .context import RunContext

#: The optional columns and their dtypes.
BODY_FIELDS: dict[str, str] = {"x_body": "f8", "y_body": "f8", "z_body": "f8"}


def body_frame_columns(ctx: RunContext, columns: dict[str, np.ndarray], t_frame: float
                       ) -> dict[str, np.ndarray]:
    """``x_body``, ``y_body``, ``z_body`` of a chunk of point-record ``columns``.

    The sensor-frame point is carried to the scene with the sensor's pose and into the body
    frame with the target's pose, both at the point's emission time: the inverse of the path
    the simulation's ray took, so the result lies on the mesh to rounding.
    """
    t = np.asarray(columns["timestamp"], dtype=np.float64)
    if ctx.scenario.scan.motion == "frozen":
        t = np.full_like(t, t_frame)
    true = np.column_stack([columns["x_true"], columns["y_true"], columns["z_true"]])
    out = np.full(true.shape, np.nan)
    target = np.asarray(columns["target"])
    if len(t):
        sensor = ctx.sensor_trajectory.poses_at(t)
        scene = rotate(sensor, true) + sensor.position
        for j, entry in enumerate(ctx.targets):
            rows = np.flatnonzero(target == j)
            if len(rows):
                poses = entry.trajectory.poses_at(t[rows])
                out[rows] = to_body(poses, scene[rows])
    return {"x_body": out[:, 0], "y_body": out[:, 1], "z_body": out[:, 2]}
