"""Which frames of an unfinished dataset are known to be on disk.

A serial run renames each frame's file and sidecar into place without an ``fsync`` each and
makes them durable a block at a time (:func:`lidarsim_core.dataset.executors.run_serial`);
after each block it records the block's frames here, in ``DIR/.lidarsim-durable.json``
(itself written with an ``fsync``). Should the machine crash, a frame written since the last
block may be on disk empty or in part although its sidecar is there, so a resumed run checks
the size *and checksum* of every frame that is neither recorded here nor in a finished
manifest, and simulates again those that do not match: the finished directory is the same to
the bit. The file is removed once the final manifest is written.
"""

from __future__ import annotations

import json
import threading
from pathlib import Path
from typing import Any

from ..base.atomic import write_text_atomic

#: The record's file name in the dataset directory.
DURABLE = ".lidarsim-durable.json"


class DurableFrames:
    """The frames recorded as durable, per sequence name (see the module docstring)."""

    def __init__(self, root: Path, frames: dict[str, set[int]] | None = None) -> None:
        self.path = Path(root) / DURABLE
        self.frames: dict[str, set[int]] = frames or {}
        self._lock = threading.Lock()

    @classmethod
    def read(cls, root: Path, manifest: dict[str, Any] | None = None) -> "DurableFrames":
        """The record in ``root`` (none if missing or unreadable), with every frame of a
        finished ``manifest`` (written after all its frames were synced)."""
        frames: dict[str, set[int]] = {}
        try:
            data = json.loads((Path(root) / DURABLE).read_text(encoding="utf-8"))
            for name, ranges in data["sequences"].items():
                frames[str(name)] = {f for a, b in ranges for f in range(int(a), int(b))}
        except (OSError, ValueError, KeyError, TypeError, AttributeError):
            frames = {}
        if manifest is not None and manifest.get("complete"):
            for seq in manifest.get("sequences", []):
                if isinstance(seq, dict) and isinstance(seq.get("frames"), list):
                    frames.setdefault(str(seq.get("name")), set()).update(
                        int(f["frame"]) for f in seq["frames"] if isinstance(f, dict))
        return cls(root, frames)

    def __contains__(self, key: tuple[str, int]) -> bool:
        name, frame = key
        return frame in self.frames.get(name, ())

    def add(self, results: list[dict[str, Any]]) -> None:
        """Record the frames of ``results`` (``sequence``, ``frame``) as durable."""
        if not results:
            return
        with self._lock:
            for result in results:
                self.frames.setdefault(str(result["sequence"]), set()).add(int(result["frame"]))
            record = {"sequences": {name: _ranges(frames)
                                    for name, frames in sorted(self.frames.items())}}
            write_text_atomic(self.path, json.dumps(record, sort_keys=True) + "\n")

    def remove(self) -> None:
        """Delete the record (the dataset is finished)."""
        self.path.unlink(missing_ok=True)


def _ranges(frames: set[int]) -> list[list[int]]:
    """``frames`` as sorted half-open ranges ``[start, stop]``."""
    out: list[list[int]] = []
    for frame in sorted(frames):
        if out and out[-1][1] == frame:
            out[-1][1] = frame + 1
        else:
            out.append([frame, frame + 1])
    return out
