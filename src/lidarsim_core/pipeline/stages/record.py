"""The point record of a piece: every written row in the sensor frame at its pulse's emission
time, with its ground truth (see :mod:`lidarsim_core.records.pointcloud` for the columns).

Reads every field the stages wrote; returns the column dictionary.
"""

from __future__ import annotations

import numpy as np

from ...geometry.vec3 import scale_rows
from ..bodyframe import body_frame_columns
from ..context import RunContext
from .base import Piece


def record_columns(ctx: RunContext, piece: Piece) -> dict[str, np.ndarray]:
    """Point-record columns of ``piece`` (plus the optional stages' extra columns)."""
    cand, rows, batch = piece.cand, piece.rows, piece.batch
    pulse = cand.pulse[rows]
    direction = np.take(piece.flown, pulse, axis=0)  # fancy indexing's rows, faster
    measured = scale_rows(piece.direction_measured, piece.range_measured)
    range_true = cand.range_true[rows]
    if ctx.sub_rays is None:
        true = scale_rows(direction, range_true)
    else:  # the strongest sub-ray's own surface point
        true = scale_rows(ctx.sub_rays.direction_of(cand.sub_ray[rows], direction,
                                                    piece.axes[0][pulse], piece.axes[1][pulse]),
                          range_true)
    if cand.true_point is not None:  # returns after bounces: the surface the light came from
        ghost = cand.bounces[rows] > 0
        true[ghost] = cand.true_point[rows][ghost]
    azimuth, elevation = ctx.pattern.nominal_az_el(batch, pulse)
    columns = {
        "x": measured[:, 0], "y": measured[:, 1], "z": measured[:, 2],
        "x_true": true[:, 0], "y_true": true[:, 1], "z_true": true[:, 2],
        "range": piece.range_measured, "range_true": range_true,
        "azimuth": azimuth, "elevation": elevation, "timestamp": batch.t[pulse],
        "return_number": piece.number, "number_of_returns": piece.count,
        "channel": batch.channel[pulse], "ray_index": batch.index[pulse],
        "face_index": cand.face[rows], "target": cand.target[rows], "part": cand.part[rows],
        "incidence_angle": np.arccos(np.clip(cand.cos_incidence[rows], 0.0, 1.0)),
        "intensity": cand.intensity[rows].astype(np.float32),
        "detected": piece.flag.astype(np.uint8),
    }
    if cand.bounces is not None:
        columns["bounces"] = cand.bounces[rows]
    columns.update(piece.extra)
    if ctx.scenario.scan.body_frame_truth:  # optional columns (lidarsim_core.pipeline.bodyframe)
        t_frame = ctx.scenario.scan.frame_interval(piece.frame)[0]
        columns.update(body_frame_columns(ctx, columns, t_frame))
    return columns
