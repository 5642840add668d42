"""The simulation pipeline: :class:`Simulation` assembles a run from a scenario and hands a
:class:`~.context.RunContext` to the pieces below it, in the order a pulse meets them:
pattern → poses (:mod:`.posing`) → culling (:mod:`.cull`) → cast (:mod:`.cast`) →
measurement stages (:mod:`.stages`) → record; :mod:`.frameinfo` gives the frames' metadata,
:mod:`.budget`, :mod:`.inside` and :mod:`.units` check a run before it starts.
"""

from .context import RunContext, Target
from .simulation import Simulation, sequence_frame_infos, simulate

__all__ = ["RunContext", "Simulation", "Target", "sequence_frame_infos", "simulate"]
