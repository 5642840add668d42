"""The ground-truth poses file of a sequence, streamed frame by frame.

The content is exactly :func:`lidarsim_core.records.groundtruth.ground_truth` (same header, same
per-frame records from :func:`~lidarsim_core.records.groundtruth.frame_record`, read back by
:func:`~lidarsim_core.io.groundtruth.read_ground_truth`), but written one block of frames at a time
so that a sequence of any length needs constant memory; each block's poses are computed
together (:meth:`~lidarsim_core.pipeline.simulation.Simulation.frame_infos`,
:func:`~lidarsim_core.records.groundtruth.frame_records`: the same bits, about a tenth of the time).
"""

from __future__ import annotations

import hashlib
import json
import shutil
import tempfile
from pathlib import Path
from typing import IO, TYPE_CHECKING, Callable

from ..base.atomic import atomic_output
from ..records.groundtruth import frame_records, ground_truth

if TYPE_CHECKING:
    from ..pipeline.simulation import Simulation

_SPOOL_BYTES = 8 * 2 ** 20
#: Frames whose poses are computed together (bounded memory for any sequence length).
_BLOCK_FRAMES = 512
#: Frames of a run whose metadata the poses files hand to the simulations at most (one
#: block: ~1 MB).
KEEP_FRAMES = _BLOCK_FRAMES


class _Hashing:
    """A write-only stream that hashes what it forwards."""

    def __init__(self, stream: IO[bytes]) -> None:
        self.stream = stream
        self.digest = hashlib.sha256()

    def write(self, data: bytes) -> None:
        self.digest.update(data)
        self.stream.write(data)


def _write(out: _Hashing, sim: "Simulation", frames: int, cloud: Callable[[int], str],
           keep: int) -> None:
    for start in range(0, frames, _BLOCK_FRAMES):
        block = range(start, min(frames, start + _BLOCK_FRAMES))
        infos = sim.frame_infos(block)  # every trajectory evaluated once per block
        if start == 0 and keep > 0:
            sim.keep_frame_infos(infos[:keep])
        clouds = [cloud(frame) for frame in block]
        if start == 0:
            header = ground_truth(infos[:1], clouds[:1])
            header.pop("frames")
            text = json.dumps(header, indent=1)
            out.write((text[:-2] + ',\n "frames": [').encode("utf-8"))
        for frame, record in zip(block, frame_records(infos, clouds)):
            out.write((("\n  " if frame == 0 else ",\n  ") + json.dumps(record)).encode("utf-8"))
    out.write(b"\n ]\n}\n")


class PosesFile:
    """The poses of a sequence, generated once into a spooled buffer and hashed.

    Call :meth:`save` to put them in place (atomically); use as a context manager. The
    metadata of the first ``keep`` frames (at most one block of 512) is handed to ``sim`` for
    its frames (:meth:`~lidarsim_core.pipeline.simulation.Simulation.keep_frame_infos`).
    """

    def __init__(self, sim: "Simulation", frames: int, cloud: Callable[[int], str],
                 keep: int = 0) -> None:
        self._buffer = tempfile.SpooledTemporaryFile(max_size=_SPOOL_BYTES)
        out = _Hashing(self._buffer)  # type: ignore[arg-type]
        _write(out, sim, frames, cloud, keep)
        self.sha256 = out.digest.hexdigest()

    def save(self, path: Path) -> None:
        """Write the poses to ``path`` atomically (skipped if it already holds them)."""
        from ..io.sidecar import sha256_file

        if path.is_file() and sha256_file(path) == self.sha256:
            return
        self._buffer.seek(0)
        with atomic_output(path) as stream:
            shutil.copyfileobj(self._buffer, stream)

    def read_bytes(self) -> bytes:
        """The whole poses file."""
        self._buffer.seek(0)
        return self._buffer.read()

    def close(self) -> None:
        """Release the buffer."""
        self._buffer.close()

    def __enter__(self) -> "PosesFile":
        return self

    def __exit__(self, *exc: object) -> None:
        self.close()
