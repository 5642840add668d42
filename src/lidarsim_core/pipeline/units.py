"""A warning when a target's size says its mesh file is in the wrong unit.

CAD files of spacecraft are often in millimetres; loaded as metres, a 8 m satellite becomes
8 km wide, the sensor ends up inside it and every frame is empty. The scene is still valid,
so this is a warning (not an error), and it says what to do: ``scale: 0.001``. Only meshes
read from files are checked: a target model takes its sizes in metres by name (``size_m``),
and a 200 m plate built on purpose is not a unit mistake.
"""

from __future__ import annotations

import warnings

import numpy as np

from .context import RunContext

#: Largest extent of a plausible spacecraft (m): the ISS, the largest one flown, is 109 m
#: across its truss; anything beyond this is far more likely a mesh in millimetres.
MAX_SPACECRAFT_SIZE_M = 150.0


class UnitsWarning(UserWarning):
    """A target's size suggests its mesh is not in metres."""


def _advice(ctx: RunContext, index: int) -> str:
    cfg = ctx.scenario.targets[index].mesh
    field = f"targets.{index}.mesh"
    if cfg.scale == 1.0:
        return (f"is the mesh in millimetres? add 'scale: 0.001' to {field} "
                f"({{path: {cfg.path}, scale: 0.001}})")
    return f"check the unit of the mesh and '{field}.scale' (now {cfg.scale:g})"


def size_warnings(ctx: RunContext) -> list[str]:
    """Messages about targets read from mesh files that are implausibly large for a
    spacecraft, or have the sensor inside their bounding box at the start of the scan."""
    messages = []
    where = f"{ctx.scenario.source}: " if ctx.scenario.source else ""
    t0 = np.array([ctx.scenario.scan.frame_interval(0)[0]])
    sensor = ctx.sensor_trajectory.poses_at(t0).position
    for i, target in enumerate(ctx.targets):
        if ctx.scenario.targets[i].mesh.path is None:
            continue  # a target model: sizes given in metres, by name
        lo, hi = target.mesh.bounds
        size = float(np.max(hi - lo))
        local = target.trajectory.poses_at(t0).apply_inverse(sensor)[0]  # sensor, body frame
        inside = bool(np.all((local > lo) & (local < hi)))
        if size > MAX_SPACECRAFT_SIZE_M:
            reason = (f"target '{target.name}' is {size:,.0f} m across, larger than any "
                      f"spacecraft (the ISS is 109 m)")
            if inside:
                reason += " and the sensor is inside it"
        elif inside:
            reason = (f"the sensor is inside the bounding box of target '{target.name}' "
                      f"({size:,.3g} m across, read from a file)")
        else:
            continue
        messages.append(f"{where}{reason}: {_advice(ctx, i)}")
    return messages


def warn_about_units(ctx: RunContext) -> None:
    """Issue a :class:`UnitsWarning` for every message of :func:`size_warnings`."""
    for message in size_warnings(ctx):
        warnings.warn(message, UnitsWarning, stacklevel=3)
