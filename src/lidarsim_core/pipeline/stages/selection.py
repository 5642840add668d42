"""Return selection: the return mode picks the reported returns of each pulse
(:func:`~lidarsim_core.instrument.returns.select_returns`); undetected ones are kept when asked.

Reads ``piece.cand`` and ``piece.detected``; writes ``piece.rows``, ``piece.flag``,
``piece.number`` and ``piece.count``.
"""

from __future__ import annotations

import numpy as np

from ...instrument.returns import select_returns
from ..context import RunContext
from .base import Piece


class SelectionStage:
    """Rows of the candidates written to the record (the return mode's picks, plus the
    undetected ones when kept), whether each was detected, and their return numbers and
    returns per pulse (0 for undetected ones)."""

    name = "returns"

    def __init__(self, ctx: RunContext) -> None:
        self.return_mode = ctx.return_mode
        self.dual_return = ctx.dual_return
        self.max_returns = ctx.max_returns
        self.keep_undetected = ctx.keep_undetected

    def run(self, piece: Piece) -> None:
        cand, detected = piece.cand, piece.detected
        det = np.flatnonzero(detected)
        pulse = cand.pulse[det]
        if len(det) > 1 and bool((pulse[1:] == pulse[:-1]).any()):
            keep, number, count = select_returns(pulse, cand.signal[det], self.return_mode,
                                                 dual=self.dual_return,
                                                 max_returns=self.max_returns)
            det, number, count = det[keep], number[keep], count[keep]
        else:  # at most one detected return per pulse: every mode reports it
            number = count = np.ones(len(det), dtype=np.uint8)
        if not self.keep_undetected:
            piece.rows, piece.flag = det, np.ones(len(det), dtype=bool)
            piece.number, piece.count = number, count
            return
        rows = np.sort(np.concatenate([det, np.flatnonzero(~detected)]))
        where = np.searchsorted(rows, det)
        number_all = np.zeros(len(rows), dtype=np.uint8)
        count_all = np.zeros(len(rows), dtype=np.uint8)
        number_all[where], count_all[where] = number, count
        piece.rows, piece.flag = rows, detected[rows]
        piece.number, piece.count = number_all, count_all
