"""Closed loop: a scan session stepped frame by frame by guidance (docs/closed_loop.md).

>>> from lidarsim_core.loop import LoopSession          # doctest: +SKIP
>>> session = LoopSession("examples/scenarios/envisat_tumbling_hold.yaml")
>>> result = session.step(0.1, delta_v_m_s=[0.0, -0.01, 0.0])
>>> result.cloud, result.state.position_m                # the frame, the chaser at its end
"""

from .dynamics import hcw_forced, propagate
from .scenarios import vbar_approach
from .session import ChaserState, LoopSession, StepResult

__all__ = ["ChaserState", "LoopSession", "StepResult", "hcw_forced", "propagate", "vbar_approach"]
