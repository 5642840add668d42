"""The measurement stages: what happens to a piece of pulses between the cast and the record.

:class:`~lidarsim_core.pipeline.Simulation` casts every (sub-)ray of a piece and hands the
result, a :class:`Piece`, to its stages in order; each has one contract (the fields of the
piece it reads and writes, in its module docstring):

1. :class:`CandidateStage` (``candidates``): hits → candidate returns with signal and
   intensity; false-alarm noise models add theirs;
2. :class:`DetectionStage` (``detection``): range gate and the link budget's draw;
3. :class:`SelectionStage` (``returns``): the return mode's picks;
4. :class:`NoiseStage` (``noise``): return-stage noise of the reported returns;

then :func:`record_columns` writes the point record. Optional stages (multipath, receiver
dynamic range, the Sun) slot in between when the scenario switches them on; when it does not
they are not in the list, so the seed paper's model runs exactly the code it always ran.
"""

from .base import Piece, SceneRays, Stage
from .candidates import CandidateStage
from .detection import DetectionStage
from .noise import NoiseStage
from .record import record_columns
from .selection import SelectionStage

__all__ = ["CandidateStage", "DetectionStage", "NoiseStage", "Piece", "SceneRays",
           "SelectionStage", "Stage", "record_columns"]
