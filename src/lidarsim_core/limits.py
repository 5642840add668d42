"""The resource budget: every size an input implies is checked before anything is allocated.

A scenario, a datasheet or a command-line option can imply an absurd amount of work with one
number (``point_rate_hz: 1e15``, ``frames: 1e14``, ``--cell-deg 1e-7``). Each such size has a
limit below; the check runs where the value enters (validation, CLI options, file readers),
never inside a hot loop, and a refusal is one :class:`~lidarsim_core.errors.ConfigError` that
names the field or option and the size it implies.

Every limit can be raised (or lowered) with its environment variable, e.g.
``LIDARSIM_MAX_RAYS_PER_FRAME=5e9 lidarsim simulate ...``; docs/reliability.md lists them.
"""

from __future__ import annotations

import math
import os
from dataclasses import dataclass
from pathlib import Path
from typing import TYPE_CHECKING, Any

from .errors import ConfigError

if TYPE_CHECKING:
    from .pipeline import Simulation

#: Where a value read from an environment variable comes from, in error messages.
ENVIRONMENT = "environment"


@dataclass(frozen=True)
class Limit:
    """One entry of the budget.

    Attributes
    ----------
    name
        Key in :data:`LIMITS`.
    default
        The limit when its environment variable is unset.
    env
        Environment variable that overrides it (a positive number; ``1e9`` is accepted).
    unit
        What is counted, for messages.
    """

    name: str
    default: float
    env: str
    unit: str
    description: str


LIMITS: dict[str, Limit] = {limit.name: limit for limit in (
    Limit("rays_per_frame", 1e9, "LIDARSIM_MAX_RAYS_PER_FRAME", "rays",
          "rays cast for one frame (point rate × frame duration × sub-rays), and rays a "
          "`coverage` run generates"),
    Limit("chunks_per_frame", 1e6, "LIDARSIM_MAX_CHUNKS_PER_FRAME", "chunks",
          "pieces one frame is cut into (rays per frame / chunk_rays)"),
    Limit("frames", 1e6, "LIDARSIM_MAX_FRAMES", "frames",
          "frames of one sequence (scan.frames, sequence_duration_s / period, --frames)"),
    Limit("pattern_rays", 2e7, "LIDARSIM_MAX_PATTERN_RAYS", "rays",
          "rays `lidarsim pattern` holds in memory to export (about 60 bytes each)"),
    Limit("coverage_cells", 2.5e7, "LIDARSIM_MAX_COVERAGE_CELLS", "cells",
          "cells of a coverage grid (`--cell-deg`; about 40 bytes each)"),
    Limit("profile_bins", 1e5, "LIDARSIM_MAX_PROFILE_BINS", "bins",
          "off-axis bins of a coverage density profile (180° / `--bin-deg`)"),
    Limit("keyframe_rows", 1e7, "LIDARSIM_MAX_KEYFRAME_ROWS", "rows",
          "rows of a keyframe file"),
    Limit("mesh_triangles", 5e7, "LIDARSIM_MAX_MESH_TRIANGLES", "triangles",
          "triangles of one target mesh (binary STL: checked from its header before "
          "reading)"),
    Limit("threads", 256, "LIDARSIM_MAX_THREADS", "threads",
          "threads of `LIDARSIM_THREADS`"),
    Limit("integration_rad", 1e5, "LIDARSIM_MAX_INTEGRATION_RAD", "rad",
          "angle a `torque_free` body turns through in the integrated time span (about 400 "
          "rad per CPU second at the integrator's tolerance)"),
    Limit("config_bytes", 64 * 2 ** 20, "LIDARSIM_MAX_CONFIG_BYTES", "bytes",
          "size of a text input: scenario, datasheet, dataset file, keyframes, CSV pattern "
          "table, sidecar or run-directory JSON"),
    Limit("data_bytes", 4 * 2 ** 30, "LIDARSIM_MAX_DATA_BYTES", "bytes",
          "size of a binary input: mesh, NPY pattern table, NPZ cloud"),
)}

#: Ray indices and timestamps are exact in float64 below 2**53; a scan reaching further in
#: ray count (point rate × time since the epoch) is refused (a hard limit, not a budget).
MAX_RAY_INDEX = 2 ** 53
#: Largest seed: noise keys are unsigned 64-bit integers, and a larger seed would silently
#: alias a smaller one.
MAX_SEED = 2 ** 64 - 1


def limit(name: str) -> float:
    """The current value of limit ``name`` (its environment variable, else the default).

    Raises
    ------
    ConfigError
        If the environment variable is set to something other than a positive number.
    """
    spec = LIMITS[name]
    raw = os.environ.get(spec.env, "").strip()
    if not raw:
        return spec.default
    try:
        value = float(raw)
    except ValueError:
        value = math.nan
    if not (math.isfinite(value) and value > 0):
        raise ConfigError(f"{spec.env}={raw!r} must be a positive number", source=ENVIRONMENT,
                          field=spec.env)
    return value


def _size(value: float) -> str:
    if not math.isfinite(value):
        return "an infinite number of"
    return f"{value:,.0f}" if value < 1e12 else f"{value:.3g}"


def check(name: str, value: float, *, what: str = "", source: str | Path | None = None,
          field: str | None = None) -> None:
    """Refuse ``value`` (the size an input implies) when it exceeds limit ``name``.

    ``what`` says how the size comes about, e.g. ``"100,000 Hz × 10 s"``.

    Raises
    ------
    ConfigError
        Naming ``source`` and ``field``, the size, the limit and the variable that raises it.
    """
    bound = limit(name)
    try:
        value = float(value)
    except OverflowError:  # an integer beyond float range
        value = math.inf
    if value <= bound:  # NaN fails this comparison and is refused too
        return
    spec = LIMITS[name]
    size = f"{_size(value)} {spec.unit}"
    raise ConfigError(f"{what + ' means ' if what else ''}{size}, over the limit of "
                      f"{_size(bound)} (set {spec.env} to raise it)", source=source,
                      field=field)


def threads_from_env(default: int) -> int:
    """Threads asked for by ``LIDARSIM_THREADS`` (``default`` when unset or empty).

    Raises
    ------
    ConfigError
        If it is not a positive integer, or above the ``threads`` limit.
    """
    raw = os.environ.get("LIDARSIM_THREADS", "").strip()
    if not raw:
        return default
    if not raw.isdigit() or int(raw) < 1:
        raise ConfigError(f"LIDARSIM_THREADS={raw!r} must be a positive integer",
                          source=ENVIRONMENT, field="LIDARSIM_THREADS")
    value = int(raw)
    check("threads", value, what=f"LIDARSIM_THREADS={raw}", source=ENVIRONMENT,
          field="LIDARSIM_THREADS")
    return value


# ---- simulations ---------------------------------------------------------------------------
def _scan_span(scenario: Any) -> tuple[float, float]:
    scan = scenario.scan
    return scan.start_s, scan.start_s + (scan.frames - 1) * scan.period_s + scan.duration_s


def check_simulation(sim: "Simulation") -> None:
    """Refuse a built simulation whose frames are too large or whose scan reaches too far.

    Checks, from the configuration alone (nothing is generated): rays per frame (point rate
    × duration × sub-rays), the pieces a frame is cut into (``chunk_rays``), ray indices
    (point rate × the scan's last time) and the integration span of ``torque_free``
    trajectories.
    """
    scenario = sim.scenario
    src = scenario.source
    scan = scenario.scan
    from .chunks import worker_threads

    worker_threads()  # a bad LIDARSIM_THREADS is refused before the run, not in it
    rate = float(sim.pattern.rate_hz) if hasattr(sim.pattern, "rate_hz") else \
        float(sim.sensor.point_rate_hz)
    per_pulse = sim.rays_per_pulse
    pulses = rate * scan.duration_s
    check("rays_per_frame", pulses * per_pulse, source=src, field="scan.duration_s",
          what=f"a point rate of {rate:g} Hz × duration_s {scan.duration_s:g} s"
               + (f" × {per_pulse} sub-rays" if per_pulse > 1 else ""))
    check("chunks_per_frame", pulses / scenario.chunk_rays, source=src, field="chunk_rays",
          what=f"{_size(pulses)} pulses per frame in chunks of {scenario.chunk_rays}")
    first, last = _scan_span(scenario)
    if not rate * last < MAX_RAY_INDEX:
        field = "scan.start_s" if rate * first >= MAX_RAY_INDEX / 2 else "scan.frames"
        raise ConfigError(f"the scan reaches t = {last:g} s, where ray indices (point rate "
                          f"{rate:g} Hz × time) exceed 2^53 and timestamps lose precision; "
                          "start the scan earlier or shorten it", source=src, field=field)
    posed = [("sensor.trajectory", sim.sensor_trajectory)] + [
        (f"targets.{i}.trajectory", t.trajectory) for i, t in enumerate(sim.targets)]
    for field, trajectory in posed:
        check_integration(trajectory, first, last, source=src, field=field)


def check_integration(trajectory: Any, t0: float, t1: float, *, source: str | Path | None,
                      field: str) -> None:
    """Refuse a ``torque_free`` trajectory whose integration over ``[t0, t1]`` would not end.

    The body rate of a torque-free body never exceeds ``sqrt(ωᵀ I ω / I_min)`` (kinetic
    energy is conserved), and the integrator works in pieces from ``t_ref_s``; the angle
    turned through those pieces bounds the integrator's work.
    """
    from .trajectories.tumbling import TorqueFreeTrajectory

    if not isinstance(trajectory, TorqueFreeTrajectory):
        return
    import numpy as np

    opts = trajectory.options
    inertia = np.asarray(trajectory._inertia, dtype=np.float64)
    omega = np.radians(np.asarray(opts.angular_velocity_deg_s, dtype=np.float64))
    energy2 = float(omega @ inertia @ omega)
    omega_max = math.sqrt(max(energy2, 0.0) / float(np.linalg.eigvalsh(inertia)[0]))
    piece = trajectory.PIECE_S
    reach = max(abs(t0 - opts.t_ref_s), abs(t1 - opts.t_ref_s))
    pieces = math.floor(reach / piece) + 1 if math.isfinite(reach) else math.inf
    check("integration_rad", omega_max * piece * pieces, source=source,
          field=f"{field}.angular_velocity_deg_s",
          what=f"a body rate up to {math.degrees(omega_max):g} °/s integrated over "
               f"{_size(pieces)} × {piece:g} s")


def check_frames(frames: float, *, source: str | Path | None, field: str) -> None:
    """Refuse a sequence of more than the ``frames`` limit."""
    check("frames", frames, what="a sequence of", source=source, field=field)


# ---- scan-pattern commands -----------------------------------------------------------------
def coverage_cells(sheet: Any, cell_deg: float) -> float:
    """Cells of the coverage grid of datasheet ``sheet`` with cells of ``cell_deg`` (the
    shape :func:`lidarsim_core.patterns.coverage.fov_coverage` builds), computed without
    building it."""
    if not (math.isfinite(cell_deg) and 0 < cell_deg <= 360):
        return math.inf
    if sheet.fov_type == "panoramic":
        return max(1.0, float(round(360.0 / cell_deg))) * \
            float(math.floor(sheet.fov_v_deg / cell_deg) + 1)
    if sheet.fov_type == "circular":
        reach = sheet.fov_h_deg / 2
    else:
        reach = math.hypot(sheet.fov_h_deg / 2, abs(sheet.fov_v_center_deg) + sheet.fov_v_deg / 2)
    side = max(1.0, float(math.ceil(2 * (min(reach, 180.0) + cell_deg) / cell_deg)))
    return side * side


def check_pattern_window(rate_hz: float, start_s: float, duration_s: float, *,
                         budget: str, duration_field: str = "--duration",
                         start_field: str = "--start",
                         source: str | Path | None = None) -> None:
    """Refuse a scan-pattern time window whose rays exceed limit ``budget`` or whose ray
    indices leave the exact range of float64."""
    check(budget, rate_hz * duration_s, source=source, field=duration_field,
          what=f"{duration_field} {duration_s:g} s at {rate_hz:g} Hz")
    if not rate_hz * (start_s + duration_s) < MAX_RAY_INDEX:
        raise ConfigError(f"the window ends at t = {start_s + duration_s:g} s, where ray "
                          f"indices ({rate_hz:g} Hz × time) exceed 2^53", source=source,
                          field=start_field)
