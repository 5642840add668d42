"""The resource budget: every size an input implies is checked before anything is allocated.

A scenario, a datasheet or a command-line option can imply an absurd amount of work with one
number (``point_rate_hz: 1e15``, ``frames: 1e14``, ``--cell-deg 1e-7``). Each such size has a
limit below; the check runs where the value enters (validation, CLI options, file readers),
never inside a hot loop, and a refusal is one :class:`~lidarsim_core.base.errors.ConfigError` that
names the field or option and the size it implies.

Every limit can be raised (or lowered) with its environment variable, e.g.
``LIDARSIM_MAX_RAYS_PER_FRAME=5e9 lidarsim simulate ...``; docs/reliability.md lists them.
"""

from __future__ import annotations

import math
import os
from dataclasses import dataclass
from pathlib import Path

from .errors import ConfigError

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
    Limit("bag_frame_points", 4e6, "LIDARSIM_MAX_BAG_FRAME_POINTS", "rays",
          "rays of one frame written into a ROS 2 bag: a PointCloud2 message holds the "
          "whole frame (about 100 bytes a point, several copies while serialised), so a "
          "bag cannot stream a frame the way point-cloud files do"),
    Limit("data_bytes", 4 * 2 ** 30, "LIDARSIM_MAX_DATA_BYTES", "bytes",
          "size of a binary input: mesh, NPY pattern table, NPZ cloud"),
)}


#: Ray indices and timestamps are exact in float64 below 2**53; a scan reaching further in
#: ray count (point rate × time since the epoch) is refused (a hard limit, not a budget).
MAX_RAY_INDEX = 2 ** 53


#: Largest value any limit may be raised to (integers are exact in float64 below it): a limit
#: of ``1e300`` is a typo, not a budget.
MAX_LIMIT = float(2 ** 53)

#: Lower ceilings where the machine itself sets one: threads beyond a few thousand do not
#: start (or hang inside Embree's task scheduler) instead of failing cleanly.
HARD_CEILINGS: dict[str, float] = {"threads": 4096.0}


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
    ceiling = HARD_CEILINGS.get(name, MAX_LIMIT)
    if value > ceiling:
        raise ConfigError(f"{spec.env}={raw!r} is above the largest value lidarsim accepts "
                          f"for it, {size_text(ceiling)}", source=ENVIRONMENT, field=spec.env)
    return value


def size_text(value: float) -> str:
    """A count for messages: grouped digits, or three significant digits when huge."""
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
    size = f"{size_text(value)} {spec.unit}"
    raise ConfigError(f"{what + ' means ' if what else ''}{size}, over the limit of "
                      f"{size_text(bound)} (set {spec.env} to raise it)", source=source,
                      field=field)


def env_choice(variable: str, choices: tuple[str, ...]) -> str:
    """The value of the environment variable ``variable``, one of ``choices`` (the first when
    unset or empty).

    Raises
    ------
    ConfigError
        If it is set to anything else, naming the variable and the choices.
    """
    raw = os.environ.get(variable, "").strip()
    if not raw:
        return choices[0]
    if raw not in choices:
        raise ConfigError(f"{variable}={raw!r} must be one of {', '.join(choices)}",
                          source=ENVIRONMENT, field=variable)
    return raw


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
    if not (raw.isascii() and raw.isdigit()) or int(raw) < 1:
        raise ConfigError(f"LIDARSIM_THREADS={raw!r} must be a positive integer",
                          source=ENVIRONMENT, field="LIDARSIM_THREADS")
    value = int(raw)
    check("threads", value, what=f"LIDARSIM_THREADS={raw}", source=ENVIRONMENT,
          field="LIDARSIM_THREADS")
    return value


def check_frames(frames: float, *, source: str | Path | None, field: str) -> None:
    """Refuse a sequence of more than the ``frames`` limit."""
    check("frames", frames, what="a sequence of", source=source, field=field)


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


def memory_ceiling_bytes() -> float:
    """The most memory this process can get: the smaller of the headroom its address-space
    limit leaves (``ulimit -v``: ``RLIMIT_AS`` minus what is mapped already) and the machine's
    physical memory; ``inf`` where neither is known."""
    ceiling = math.inf
    try:
        import resource

        soft, _ = resource.getrlimit(resource.RLIMIT_AS)
        if soft != resource.RLIM_INFINITY:
            ceiling = float(soft) - _mapped_bytes()
    except (ImportError, OSError, ValueError):
        pass
    try:
        ceiling = min(ceiling, float(os.sysconf("SC_PAGE_SIZE") * os.sysconf("SC_PHYS_PAGES")))
    except (AttributeError, OSError, ValueError):
        pass
    return ceiling


def _mapped_bytes() -> float:
    try:
        with open("/proc/self/status", "rb") as stream:
            for line in stream:
                if line.startswith(b"VmSize:"):
                    return float(line.split()[1]) * 1024
    except OSError:
        pass
    return 0.0


def check_memory(needed: float, *, what: str, source: str | Path | None = None,
                 field: str | None = None) -> None:
    """Refuse work that needs more memory than :func:`memory_ceiling_bytes` (``what`` says
    what needs it), before anything is allocated.

    Raises
    ------
    ConfigError
        Naming ``source`` and ``field``, the bytes needed and the bytes available.
    """
    ceiling = memory_ceiling_bytes()
    if needed <= ceiling:
        return
    raise ConfigError(f"{what} needs about {needed / 2 ** 30:,.1f} GiB of memory, more than "
                      f"the {max(ceiling, 0) / 2 ** 30:,.1f} GiB this process can get "
                      "(its address-space limit, or the machine's memory)", source=source,
                      field=field)
