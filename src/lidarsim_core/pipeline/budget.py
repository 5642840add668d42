"""The resource budget of a built simulation: the sizes its scenario implies, checked before
any ray is generated (:mod:`lidarsim_core.base.limits` holds the limits).
"""

from __future__ import annotations

from typing import Any

from ..base.errors import ConfigError
from ..base.limits import MAX_RAY_INDEX, check, size_text
from .context import RunContext


# ---- simulations ---------------------------------------------------------------------------
def _scan_span(scenario: Any) -> tuple[float, float]:
    scan = scenario.scan
    return scan.start_s, scan.start_s + (scan.frames - 1) * scan.period_s + scan.duration_s


def check_simulation(ctx: RunContext) -> None:
    """Refuse a built simulation whose frames are too large or whose scan reaches too far.

    Checks, from the configuration alone (nothing is generated): rays per frame (point rate
    × duration × sub-rays), the pieces a frame is cut into (``chunk_rays``), ray indices
    (point rate × the scan's last time) and the integration span of ``torque_free``
    trajectories.
    """
    scenario = ctx.scenario
    src = scenario.source
    scan = scenario.scan
    from ..base.threads import worker_threads

    worker_threads()  # a bad LIDARSIM_THREADS is refused before the run, not in it
    rate = float(ctx.pattern.rate_hz) if hasattr(ctx.pattern, "rate_hz") else \
        float(ctx.sensor.point_rate_hz)
    per_pulse = ctx.rays_per_pulse
    pulses = rate * scan.duration_s
    check("rays_per_frame", pulses * per_pulse, source=src, field="scan.duration_s",
          what=f"a point rate of {rate:g} Hz × duration_s {scan.duration_s:g} s"
               + (f" × {per_pulse} sub-rays" if per_pulse > 1 else ""))
    check("chunks_per_frame", pulses / scenario.chunk_rays, source=src, field="chunk_rays",
          what=f"{size_text(pulses)} pulses per frame in chunks of {scenario.chunk_rays}")
    first, last = _scan_span(scenario)
    if not rate * last < MAX_RAY_INDEX:
        field = "scan.start_s" if rate * first >= MAX_RAY_INDEX / 2 else "scan.frames"
        raise ConfigError(f"the scan reaches t = {last:g} s, where ray indices (point rate "
                          f"{rate:g} Hz × time) exceed 2^53 and timestamps lose precision; "
                          "start the scan earlier or shorten it", source=src, field=field)
    posed = [("sensor.trajectory", ctx.sensor_trajectory)] + [
        (f"targets.{i}.trajectory", t.trajectory) for i, t in enumerate(ctx.targets)]
    for field, trajectory in posed:
        trajectory.check_span(first, last, source=src, field=field)
