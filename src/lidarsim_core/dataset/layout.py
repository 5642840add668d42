"""Where everything of a dataset lives on disk.

One scenario::

    DIR/manifest.json           what, how, and every frame's checksum
    DIR/scenario.yaml           the normalised scenario that was simulated
    DIR/poses.json              ground-truth poses of every frame (lidarsim-poses format)
    DIR/frames/frame_000000.ply         one file per frame
    DIR/frames/frame_000000.ply.json    its sidecar (frame metadata, checksum)

A dataset file with several sequences puts each under ``DIR/sequences/<name>/`` (same four
entries) and adds ``DIR/dataset.yaml`` (the expanded dataset file), ``DIR/splits.json`` and
``DIR/splits/{train,val,test}.txt`` (one frame path per line, relative to ``DIR``).

With ``--format mcap`` a sequence holds ``bag.mcap`` and its sidecar ``bag.mcap.json`` instead
of ``frames/`` (:mod:`lidarsim_core.dataset.bags`), and the split lists name the bags.
"""

from __future__ import annotations

from pathlib import Path

MANIFEST = "manifest.json"
SCENARIO_COPY = "scenario.yaml"
DATASET_COPY = "dataset.yaml"
POSES = "poses.json"
FRAMES_DIR = "frames"
SPLITS = "splits.json"
SPLITS_DIR = "splits"
LOCK = ".lidarsim-dataset.lock"
#: Digits of the frame number in file names.
FRAME_DIGITS = 6


def sequence_root(root: Path, name: str, multi: bool) -> Path:
    """Directory of sequence ``name``: the dataset root itself for a single scenario."""
    return root / "sequences" / name if multi else root


def frame_name(frame: int, suffix: str) -> str:
    """File name of a frame, e.g. ``frame_000042.ply``."""
    return f"frame_{frame:0{FRAME_DIGITS}d}{suffix}"


def frame_relpath(frame: int, suffix: str) -> str:
    """Path of a frame relative to its sequence root (POSIX separators)."""
    return f"{FRAMES_DIR}/{frame_name(frame, suffix)}"
