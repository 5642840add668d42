"""A frame whose sensor sits inside a closed target mesh is refused: every point would lie on
the inside of the hull, data that looks plausible and is wrong.
"""

from __future__ import annotations

from typing import Any

from .context import RunContext
from .spanposes import SpanPoses, span_poses


# ---- impossible geometry -----------------------------------------------------------------
def _probe_directions() -> Any:
    import numpy as np

    # the 6 axes and the 8 cube diagonals, slightly skewed so that no probe runs exactly
    # along an edge or face of an axis-aligned box
    axes = np.vstack([np.eye(3), -np.eye(3)])
    diagonals = np.array([[x, y, z] for x in (-1, 1) for y in (-1, 1) for z in (-1, 1)], float)
    dirs = np.vstack([axes, diagonals]) + np.array([0.0123, -0.0071, 0.0049])
    return dirs / np.linalg.norm(dirs, axis=1, keepdims=True)


def check_sensor_outside(ctx: RunContext, frame: int,
                         interval: tuple[float, float] | None = None,
                         poses: SpanPoses | None = None) -> None:
    """Refuse a frame whose sensor is inside a closed target at the frame's start or end
    (``interval``: the frame's ``(t_start, t_end)`` when it is not the scenario's; ``poses``:
    the trajectories' poses when already looked up at the instants checked).

    The sensor counts as inside when probe rays in 14 directions all hit the target and all
    hit the back (inner) side of a face first, which is only possible from inside a closed,
    outward-oriented surface. Open meshes (a plate) and meshes with some inward faces never
    trigger it. A sensor outside the target's bounding box needs no probe.

    Raises
    ------
    ConfigError
        Naming the scenario file and the target's ``pose`` (or ``trajectory``) field.
    """
    import numpy as np

    from ..base.errors import ConfigError

    scenario = ctx.scenario
    t0, t1 = scenario.scan.frame_interval(frame) if interval is None else interval
    times = np.array([t0] if scenario.scan.motion == "frozen" else [t0, t1], dtype=np.float64)
    looked_up = (None if poses is None else poses.at(times)) or span_poses(ctx, times)
    sensor_at = looked_up.sensor.position
    dirs = _probe_directions()
    for i, (target, target_poses) in enumerate(zip(ctx.targets, looked_up.targets)):
        origins = target_poses.apply_inverse(sensor_at)
        lo, hi = target.mesh.bounds
        for t, origin in zip(times, origins):
            if (origin < lo).any() or (origin > hi).any():
                continue  # outside the bounding box: outside any closed surface, no probe
            hits = ctx.backend.cast(target.mesh, np.repeat(origin[None, :], len(dirs), axis=0),
                                    dirs)
            if hits.hit.all() and (np.einsum("ij,ij->i", hits.normal, dirs) > 0).all():
                cfg = scenario.targets[i]
                field = f"targets.{i}.trajectory" if cfg.trajectory is not None else \
                    f"targets.{i}.pose"
                raise ConfigError(
                    f"the sensor is inside the closed target '{target.name}' at t = {t:g} s "
                    "(every probe ray meets the inner side of its surface); move the sensor "
                    "or the target", source=scenario.source, field=field)


#: Margin, relative to the size of a target's box and of the coordinates, by which the sensor
#: must clear the box in :func:`clear_of_targets`: far beyond any rounding difference between
#: evaluating poses one frame or a block of frames at a time.
CLEAR_MARGIN = 1e-6


def clear_of_targets(ctx: RunContext, frames: Any) -> Any:
    """For each of ``frames`` (scenario frames), whether the sensor is clearly outside every
    target's bounding box at the frame's start and end: such a frame passes
    :func:`check_sensor_outside` without a probe, so a caller that checked a block of frames
    here (every trajectory evaluated once for the block) may skip the frame's own check. A
    frame near or inside a box gets ``False`` and its own check, as before.

    Returns
    -------
    numpy.ndarray
        One bool per frame.
    """
    import numpy as np

    scan = ctx.scenario.scan
    frames = list(frames)
    intervals = np.array([scan.frame_interval(f) for f in frames], dtype=np.float64)
    times = intervals[:, :1] if scan.motion == "frozen" else intervals
    flat = times.reshape(-1)
    clear = np.ones(len(frames), dtype=bool)
    if not len(frames):
        return clear
    sensor_at = ctx.sensor_trajectory.poses_at(flat).position
    for target in ctx.targets:
        origins = target.trajectory.poses_at(flat).apply_inverse(sensor_at)
        lo, hi = (np.asarray(b, dtype=np.float64) for b in target.mesh.bounds)
        margin = CLEAR_MARGIN * (1.0 + float(np.abs(hi - lo).max()) +
                                 float(np.abs(origins).max()))
        outside = ((origins < lo - margin) | (origins > hi + margin)).any(axis=1)
        clear &= outside.reshape(len(frames), -1).all(axis=1)
    return clear
