"""The measurement stages: what happens to a piece of pulses between the cast and the record.

:class:`~lidarsim_core.pipeline.simulation.RunContext` casts every (sub-)ray of a piece and hands the
result, a :class:`Piece`, to its stages in order; each has one contract (the fields of the
piece it reads and writes, in its module docstring):

1. :class:`CandidateStage` (``candidates``): hits → candidate returns with signal and
   intensity; false-alarm noise models add theirs;
2. :class:`~.bounces.BounceStage` (``bounces``, with ``sensor.multipath``): specular bounces
   and their ghost returns;
3. :class:`~.sun.SunStage` (``sun``, with ``sun``): shadows, solar false alarms, blinding;
4. :class:`DetectionStage` (``detection``): range gate and the link budget's draw;
5. :class:`~.receiver.ReceiverStage` (``receiver``, with ``sensor.receiver``): saturation and
   range walk;
6. :class:`SelectionStage` (``returns``): the return mode's picks;
7. :class:`NoiseStage` (``noise``): return-stage noise of the reported returns;

then :func:`record_columns` writes the point record. An optional stage is in the list only
when the scenario switches it on, so the seed paper's model runs exactly the code it always
ran. Optional stages have an ``info()`` method: what they add to the frame metadata
(``frame.extra["measurement"][name]``).

A new effect is a new stage module: a class with ``name`` and ``run(piece)`` (the
:class:`Stage` protocol), its configuration model, and one line in
:func:`measurement_stages`.
"""

from typing import TYPE_CHECKING

from ...base.errors import ConfigError
from ..context import RunContext
from .base import Piece, SceneRays, Stage
from .candidates import CandidateStage
from .detection import DetectionStage
from .noise import NoiseStage
from .record import record_columns
from .selection import SelectionStage

__all__ = ["CandidateStage", "DetectionStage", "NoiseStage", "Piece", "SceneRays",
           "SelectionStage", "Stage", "measurement_stages", "record_columns"]


def measurement_stages(ctx: RunContext) -> list[Stage]:
    """The stages of ``ctx``'s scenario, in the order they run (see the module docstring)."""
    from .bounces import BounceStage
    from .receiver import ReceiverStage
    from .sun import SunStage

    scenario = ctx.scenario
    stages: list[Stage] = [CandidateStage(ctx)]
    multipath = scenario.sensor.multipath
    if multipath is not None:
        if ctx.link is None:
            raise ConfigError("multipath ghosts are detected by the link budget; add "
                              "'detection: {}' to the sensor", source=scenario.source,
                              field="sensor.multipath")
        stages.append(BounceStage(ctx, multipath))
    if scenario.earth is not None and scenario.sun is None:
        raise ConfigError("the Earth's place and its sunlit side follow the target's orbit and "
                          "epoch; add sun: {orbit: ...}", source=scenario.source, field="earth")
    if scenario.sun is not None:
        stages.append(SunStage(ctx, scenario.sun, stages[0]))
    stages.append(DetectionStage(ctx))
    if scenario.sensor.receiver is not None:
        stages.append(ReceiverStage(ctx, scenario.sensor.receiver))
    return stages + [SelectionStage(ctx), NoiseStage(ctx)]
