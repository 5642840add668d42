"""Random streams of the return stage when a pulse reports several returns.

Return-stage noise draws its numbers by ray index. The first return of every pulse uses the
model's own stream (so single-return runs are exactly the seed paper's); return ``r > 1``
of a pulse uses the stream suffixed ``#r<r>``, so the returns of one pulse get independent
range noise while staying reproducible and chunk-independent. A model whose error belongs
to the pulse rather than to the echo (a pointing error) maps back with :func:`per_pulse`.
"""

from __future__ import annotations

from dataclasses import replace

from .base import NoiseContext

#: Separator of the return-number suffix of a noise stream name.
RETURN_SUFFIX = "#r"


def for_return(ctx: NoiseContext, return_number: int) -> NoiseContext:
    """The context of a model for the ``return_number``-th (1-based) reported return."""
    if return_number <= 1:
        return ctx
    return replace(ctx, stream=f"{ctx.stream}{RETURN_SUFFIX}{return_number}")


def per_pulse(ctx: NoiseContext) -> NoiseContext:
    """The context whose draws are shared by every return of a pulse."""
    base = ctx.stream.split(RETURN_SUFFIX, 1)[0]
    return ctx if base == ctx.stream else replace(ctx, stream=base)
