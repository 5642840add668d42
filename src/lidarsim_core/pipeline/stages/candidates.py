"""Candidate returns: the hits of a piece's (sub-)rays become returns with a signal and an
intensity, plus the spurious echoes of false-alarm noise models (docs/realism.md).

Reads ``piece.hits``; writes ``piece.cand``.
"""

from __future__ import annotations

import numpy as np

from ...instrument.returns import Candidates, group_sub_rays
from ...noise.base import NoiseContext
from ...noise.outliers import SpuriousReturnModel
from ...patterns.base import RayBatch
from ..context import RunContext
from .base import Piece


class CandidateStage:
    """One candidate per pulse, or the pulse's sub-ray hits grouped by range
    (:func:`~lidarsim_core.instrument.returns.group_sub_rays`), each with its signal from the parts'
    materials and the link budget; false-alarm models add theirs."""

    name = "candidates"

    def __init__(self, ctx: RunContext) -> None:
        self.link = ctx.link
        self.sub_rays = ctx.sub_rays
        self.materials = ctx.materials
        self.range_resolution_m = ctx.range_resolution_m
        self.spurious = ctx.spurious
        self.range_min_m = ctx.sensor.range_min_m
        self.range_limit = ctx.range_limit
        self.false_alarm_part = ctx.false_alarm_part

    def run(self, piece: Piece) -> None:
        batch, hits, link = piece.batch, piece.hits, self.link
        exponent = link.exponent if link is not None else 2.0
        if self.sub_rays is None:
            idx = np.flatnonzero(hits.target >= 0)
            rng = hits.distance[idx]
            part, cos_inc = hits.part[idx], hits.cos_incidence[idx]
            rho = self.materials.effective(part, cos_inc)
            power = rho / rng ** exponent
            zeros = np.zeros(len(idx), dtype=np.int64)
            cand = Candidates(idx, zeros, rng, rng, zeros,
                              link.constant * power if link is not None else power, rho,
                              hits.target[idx], hits.face[idx], part, cos_inc)
        else:
            k = self.sub_rays.count
            pulse, rank, rng, flat, power, rng_true = group_sub_rays(
                hits, k, self.sub_rays.weights, self.materials.effective, exponent,
                self.range_resolution_m)
            cand = Candidates(pulse, rank, rng, rng_true, flat % k,
                              link.constant * power if link is not None else power,
                              power * rng ** exponent, hits.target[flat], hits.face[flat],
                              hits.part[flat], hits.cos_incidence[flat])
        extra = [self.false_alarms(batch, model, piece.contexts[i])
                 for i, model in self.spurious]
        extra = [c for c in extra if len(c)]
        piece.cand = Candidates.concatenate([cand, *extra]) if extra else cand

    def false_alarms(self, batch: RayBatch, model: SpuriousReturnModel,
                     ctx: NoiseContext) -> Candidates:
        """The spurious echoes ``model`` adds to the pulses of ``batch``."""
        rng = model.spurious_ranges(batch.index, ctx, self.range_min_m, self.range_limit)
        pulse = np.flatnonzero(np.isfinite(rng))
        return self.spurious_candidates(pulse, rng[pulse])

    def spurious_candidates(self, pulse: np.ndarray, rng: np.ndarray) -> Candidates:
        """Echoes of no surface at ranges ``rng`` on pulses ``pulse`` (false alarms)."""
        m = len(pulse)
        # a false alarm just crosses the threshold: S = 1 (0 without a calibrated budget)
        signal = np.ones(m) if self.link is not None else np.zeros(m)
        intensity = (self.link.apparent_reflectivity(signal, rng) if self.link is not None
                     else np.zeros(m))
        return Candidates(pulse, np.full(m, -1, dtype=np.int64), rng, np.full(m, np.nan),
                          np.zeros(m, dtype=np.int64), signal, intensity,
                          np.full(m, -1, dtype=np.int16), np.full(m, -1, dtype=np.int64),
                          np.full(m, self.false_alarm_part, dtype=np.int16), np.full(m, np.nan))
