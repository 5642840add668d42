"""Detection: the range gate, then, with ``sensor.detection``, the link budget's draw
(P_d = Φ(TNR (S − 1)), docs/realism.md; Φ(TNR (S − 1) / √(1 + B)) where the Sun's background B
raises the receiver's noise).

Reads ``piece.cand`` and ``piece.noise_scale``; writes ``piece.detected``.
"""

from __future__ import annotations

import numpy as np

from ...noise.rng import ray_uniforms
from ..context import RunContext
from .base import Piece

#: Random stream of the detection draws (returns after b bounces: ``detection#b<b>``).
DETECTION_STREAM = "detection"


class DetectionStage:
    """Which candidates the sensor detects. Draws are keyed by (ray index, return rank), so
    results do not depend on chunking or threads; ghosts (``bounces`` b > 0) draw from their
    own stream per bounce count, so turning multipath on changes no direct return."""

    name = "detection"

    def __init__(self, ctx: RunContext) -> None:
        self.range_min_m = ctx.sensor.range_min_m
        self.range_limit = ctx.range_limit
        self.link = ctx.link
        self.seed = ctx.scenario.seed
        self.rays_per_pulse = ctx.rays_per_pulse

    def run(self, piece: Piece) -> None:
        cand = piece.cand
        detected = (cand.range >= self.range_min_m) & (cand.range <= self.range_limit)
        if self.link is None or not len(cand):
            piece.detected = detected
            return
        real = cand.group >= 0
        draws = ray_uniforms(self.seed, piece.frame, DETECTION_STREAM,
                             piece.batch.index[cand.pulse], self.rays_per_pulse)
        draw = draws[np.arange(len(cand)), np.maximum(cand.group, 0)]
        if cand.bounces is not None and cand.bounces.any():
            for b in np.unique(cand.bounces[cand.bounces > 0]):
                sel = np.flatnonzero(cand.bounces == b)
                ghost = ray_uniforms(self.seed, piece.frame, f"{DETECTION_STREAM}#b{int(b)}",
                                     piece.batch.index[cand.pulse[sel]], self.rays_per_pulse)
                draw[sel] = ghost[np.arange(len(sel)), cand.group[sel]]
        signal = cand.signal
        if piece.noise_scale is not None:  # background noise σ = σ_n √(1 + B): P_d falls
            signal = 1.0 + (signal - 1.0) / piece.noise_scale[cand.pulse]
        piece.detected = detected & (~real | (draw < self.link.detection_probability(signal)))
