"""Return-stage noise: the noise chain perturbs the reported range and direction of every
reported return (paper: range error, Eq. 4); return r > 1 of a pulse draws from its own streams
(:func:`~lidarsim_core.noise.streams.for_return`); kept undetected returns stay noiseless.

Reads ``piece.rows``, ``piece.flag``, ``piece.number``, ``piece.cand`` (with each return's
signal, for signal-driven models) and ``piece.noise_scale``; writes
``piece.range_measured`` and ``piece.direction_measured``.
"""

from __future__ import annotations

import numpy as np

from ...noise.base import NoiseContext, Returns
from ...noise.streams import for_return
from ...patterns.base import RayBatch
from ..context import RunContext
from .base import Piece


class NoiseStage:
    """The scenario's noise chain applied to the reported returns."""

    name = "noise"

    def __init__(self, ctx: RunContext) -> None:
        self.noise = ctx.noise

    def run(self, piece: Piece) -> None:
        cand, rows, flag, number = piece.cand, piece.rows, piece.flag, piece.number
        batch, contexts = piece.batch, piece.contexts
        pulse = cand.pulse[rows]
        direction = piece.flown[pulse]
        range_measured = cand.range[rows]
        direction_measured = direction
        signal = cand.signal[rows]
        scale = None if piece.noise_scale is None else piece.noise_scale[pulse]
        reported = np.flatnonzero(flag)
        if len(reported) == len(rows):
            range_measured, direction_measured = self.perturb(
                batch, contexts, pulse, direction, cand.range_true[rows], range_measured, number,
                signal, scale)
        else:  # noise on the reported returns only; kept undetected ones stay noiseless
            range_measured, direction_measured = range_measured.copy(), direction.copy()
            r_meas, d_meas = self.perturb(batch, contexts, pulse[reported], direction[reported],
                                          cand.range_true[rows][reported],
                                          range_measured[reported], number[reported],
                                          signal[reported],
                                          None if scale is None else scale[reported])
            range_measured[reported], direction_measured[reported] = r_meas, d_meas
        piece.range_measured, piece.direction_measured = range_measured, direction_measured

    def perturb(self, batch: RayBatch, contexts: list[NoiseContext], pulse: np.ndarray,
                direction: np.ndarray, range_true: np.ndarray, range_measured: np.ndarray,
                number: np.ndarray, signal: np.ndarray | None = None,
                noise_scale: np.ndarray | None = None) -> tuple[np.ndarray, np.ndarray]:
        """Return-stage noise of reported returns (one call per return number)."""
        if len(number) == 0 or number.min() == number.max():  # the usual case: one value
            numbers = number[:1]
        else:
            numbers = np.unique(number)
        if len(numbers) <= 1:
            r = int(numbers[0]) if len(numbers) else 1
            returns = Returns(batch.index[pulse], direction, range_true, range_measured.copy(),
                              direction, signal, noise_scale)
            for model, ctx in zip(self.noise, contexts):
                returns = model.perturb_returns(returns, for_return(ctx, r))
            return returns.range_measured, returns.direction_measured
        out_range = np.empty(len(pulse))
        out_direction = np.empty((len(pulse), 3))
        for r in numbers:
            sel = np.flatnonzero(number == r)
            out_range[sel], out_direction[sel] = self.perturb(
                batch, contexts, pulse[sel], direction[sel], range_true[sel],
                range_measured[sel], number[sel], None if signal is None else signal[sel],
                None if noise_scale is None else noise_scale[sel])
        return out_range, out_direction
