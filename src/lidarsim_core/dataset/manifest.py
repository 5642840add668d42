"""The dataset manifest: identity, layout, seed scheme and every frame's checksum.

``manifest.json`` is written when a run starts (``"complete": false``, no frame table) and
again when every frame is on disk (``"complete": true``, one entry per frame with its file,
point count, size and SHA-256). It holds nothing that depends on when, where or how the run
went (no dates, host names, timings or worker counts), so an interrupted and resumed run ends
with the same bytes as an uninterrupted one. Frame tables are streamed from the sidecars, so
writing it needs constant memory whatever the number of frames.
"""

from __future__ import annotations

import json
import os
from pathlib import Path
from typing import IO, Any, Callable, Iterator

from ..base.atomic import atomic_output

MANIFEST_FORMAT = "lidarsim-dataset"
MANIFEST_VERSION = 1
# words of every manifest already written: they keep the module path of the time
# (lidarsim_core.rng, now lidarsim_core.noise.rng; the old path still imports)
SEED_SCHEME = ("Noise of ray k in frame f of a sequence with seed s is drawn from NumPy's "
               "Philox-4x64 keyed by (s, f, noise stream name) with its counter set from k "
               "(lidarsim_core.rng): every frame is a pure function of the normalised scenario "
               "and its index, independent of chunk size, threads, workers and run order.")


def read_manifest(path: Path) -> dict[str, Any] | None:
    """The manifest at ``path``, or ``None`` if there is none (or it is unreadable)."""
    from ..base.config_io import read_bytes_file
    from ..base.errors import UserInputError

    if not os.path.lexists(path):
        return None
    try:  # bounded: a FIFO or device named manifest.json must not block or fill memory
        data = json.loads(read_bytes_file(path, "manifest", limit_name="data_bytes"))
    except (UserInputError, UnicodeDecodeError, RecursionError, json.JSONDecodeError):
        return None
    return data if isinstance(data, dict) and data.get("format") == MANIFEST_FORMAT else None


def _write_json_stream(out: IO[bytes], head: dict[str, Any], sequences: list[dict[str, Any]],
                       frames_of: Callable[[int], Iterator[dict[str, Any]]] | None,
                       tail: dict[str, Any]) -> None:
    def put(text: str) -> None:
        out.write(text.encode("utf-8"))

    put("{\n")
    for key, value in head.items():
        put(f" {json.dumps(key)}: {json.dumps(value, sort_keys=True)},\n")
    put(' "sequences": [')
    for i, seq in enumerate(sequences):
        body = json.dumps(seq, sort_keys=True)
        put(("\n  " if i == 0 else ",\n  ") + body[:-1])
        if frames_of is not None:
            put(', "frames": [')
            for j, entry in enumerate(frames_of(i)):
                put(("\n   " if j == 0 else ",\n   ") + json.dumps(entry, sort_keys=True))
            put("\n  ]")
        put("}")
    put("\n ]")
    for key, value in tail.items():
        put(f",\n {json.dumps(key)}: {json.dumps(value, sort_keys=True)}")
    put("\n}\n")


def write_manifest(path: Path, *, identity: dict[str, Any], sequences: list[dict[str, Any]],
                   splits: dict[str, Any] | None,
                   frames_of: Callable[[int], Iterator[dict[str, Any]]] | None = None,
                   totals: dict[str, int] | None = None,
                   extra: dict[str, Any] | None = None) -> None:
    """Write the manifest atomically.

    Parameters
    ----------
    path
        ``DIR/manifest.json``.
    identity
        See :mod:`lidarsim_core.dataset.identity`.
    sequences
        One summary per sequence (name, root, files, seed, frame count, split...).
    splits
        Split assignment (``None`` for a single sequence).
    frames_of
        For a complete dataset: sequence index → iterator of frame entries.
    totals
        For a complete dataset: frames, points and bytes over all sequences.
    extra
        More top-level entries, written last (a sharded dataset's ``shards``).
    """
    head = {"format": MANIFEST_FORMAT, "version": MANIFEST_VERSION,
            "complete": frames_of is not None, "identity": identity, "seed_scheme": SEED_SCHEME}
    tail: dict[str, Any] = {"splits": splits}
    if totals is not None:
        tail["totals"] = totals
    tail.update(extra or {})
    with atomic_output(path) as stream:
        _write_json_stream(stream, head, sequences, frames_of, tail)
