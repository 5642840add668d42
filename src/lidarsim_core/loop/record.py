"""The record of a loop: the steered poses as keyframe files and a scenario that flies them.

The scenario is the session's own (seed, sensor, noise, targets, measurement model) with each
steered body's trajectory replaced by ``kind: keyframes`` over its file (linear positions,
SLERP rotations, :mod:`.steered`) and the scan set to the steps: ``start_s`` the session's
start, ``duration_s = frame_period_s = dt``, one frame per step. Relative mesh, datasheet and
keyframe paths of the original scenario are made absolute, so the record replays from any
directory. ``lidarsim simulate <record>.yaml --frame j`` gives step ``j``'s cloud to the bit.
"""

from __future__ import annotations

from pathlib import Path
from typing import Any

import yaml

from ..base.atomic import write_text_atomic
from ..base.errors import ConfigError
from ..base.outputs import check_group, make_parent
from ..scenario.model import Scenario
from .steered import INTERPOLATION, SteeredPath


def _absolute(scenario: Scenario, data: dict[str, Any]) -> None:
    """Relative paths of the scenario's data made absolute (the record lives elsewhere)."""
    sheet = data["sensor"].get("datasheet")
    if isinstance(sheet, str) and scenario.resolve(Path(sheet)).is_file():
        data["sensor"]["datasheet"] = str(scenario.resolve(Path(sheet)))
    bodies = [data["sensor"], *data["targets"]]
    for target in data["targets"]:
        mesh = target["mesh"]
        if mesh.get("path") is not None:
            mesh["path"] = str(scenario.resolve(Path(mesh["path"])))
    for body in bodies:
        traj = body.get("trajectory") or {}
        if isinstance(traj.get("file"), str):
            traj["file"] = str(scenario.resolve(Path(traj["file"])))


def record_scenario(scenario: Scenario, *, start_s: float, dt: float | None, frames: int,
                    keyframe_files: dict[str, str]) -> dict[str, Any]:
    """The replay scenario of a session as a mapping: ``scenario`` with the steered bodies
    flying ``keyframe_files`` (``sensor`` or a target's name → file, as the scenario should
    name it) and one frame of ``dt`` per step from ``start_s`` (``dt`` None: the steps had
    different lengths, which a scenario cannot hold)."""
    if frames == 0:
        raise ConfigError("the session has no step to record", source="<loop record>",
                          field="steps")
    if dt is None:
        raise ConfigError("a scenario's frames are evenly spaced; this session's steps have "
                          "different lengths (the keyframe files are still exact)",
                          source="<loop record>", field="dt")
    data = scenario.model_dump(mode="json")
    _absolute(scenario, data)
    for body, file in keyframe_files.items():
        entry = data["sensor"] if body == "sensor" else \
            next(t for t in data["targets"] if t["name"] == body)
        entry.pop("pose", None)
        entry["trajectory"] = {"kind": "keyframes", "file": file, **INTERPOLATION}
    data["scan"] = {"duration_s": dt, "start_s": start_s, "frames": frames,
                    "frame_period_s": dt, "motion": scenario.scan.motion,
                    "body_frame_truth": scenario.scan.body_frame_truth}
    return data


def write_record(path: Path, scenario: Scenario, paths: dict[str, SteeredPath], *,
                 start_s: float, dt: float | None, frames: int, overwrite: bool = True
                 ) -> Path:
    """Write the keyframe files of the steered bodies (``paths``: ``sensor`` or a target's
    name → its path) beside ``path`` and the replay scenario at ``path``; nothing is written
    when the session cannot be recorded."""
    files = {body: f"{path.stem}.{body.replace('/', '_')}.csv" for body in paths}
    data = record_scenario(scenario, start_s=start_s, dt=dt, frames=frames,
                           keyframe_files=files)
    # the keyframe files and the scenario are one group: all checked, the folder made, then
    # written (the README's rule: missing output folders are created)
    check_group([path.parent / f for f in files.values()] + [path], overwrite=overwrite)
    make_parent(path)
    for body, steered in paths.items():
        write_text_atomic(path.parent / files[body], steered.csv_text(), overwrite=overwrite)
    header = ("# The record of a closed-loop session (lidarsim_core.loop): replays its "
              "frames to the bit.\n")
    return write_text_atomic(path, header + yaml.safe_dump(data, sort_keys=False),
                             overwrite=overwrite)
