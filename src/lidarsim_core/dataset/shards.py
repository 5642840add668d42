"""Sharded training sets (``format: shards``): WebDataset-style tar files of NumPy arrays.

Layout::

    DIR/manifest.json                     identity, sequences (with drawn values), shards
    DIR/splits.json                       which sequence went to which split
    DIR/sequences.tar                     <name>/scenario.yaml and <name>/poses.json of every
                                          sequence (the ``cloud`` of a frame is its sample key)
    DIR/shards/train-000000.tar           at most ``shard_frames`` samples each
    DIR/shards/val-000000.tar ...

so the directory holds one shard per ``shard_frames`` frames and four files more, however
many sequences were drawn.

Each sample is a run of tar members sharing a key, ``<sequence>/<frame>`` (the sequence name
with ``.`` written ``_``): ``<key>.<array>.npy`` for every array of
:mod:`~lidarsim_core.dataset.samples` and ``<key>.json`` for its metadata. The frames of each
split are laid end to end (sequences in dataset order, frames in order) and cut into shards of
``shard_frames``, so a million frames make a thousand files.

Why tar shards and not Zarr or HDF5: a sample is a handful of arrays of different shapes (N
points, an H × W image, T poses) that a loader reads whole, one sample at a time, in shard
order; tar holds exactly that with the standard library alone (no new dependency, nothing
compiled), every shard is one file written once and renamed into place, so atomic writes,
resume and per-file checksums work as for frames, and the files stream (object stores,
``webdataset``, ``tar tf``). Zarr would split the same data into a file (or object) per chunk
and needs a chunk shape that fits ragged frames; HDF5 needs h5py/libhdf5 and a writer per file,
and its files are not safe to append from several processes or to recover after a kill.

The members are written with fixed metadata (mtime 0, uid/gid 0, mode 0644, USTAR), so a shard
is the same to the byte on every run, worker count and scheduler.
"""

from __future__ import annotations

import io
import json
import tarfile
from collections import OrderedDict
from dataclasses import dataclass
from pathlib import Path
from typing import IO, Any

import numpy as np

from ..base.atomic import atomic_output
from ..io.sidecar import sha256_file
from .samples import SampleSettings, make_sample, sample_meta

SHARDS_DIR = "shards"
SHARD_FORMAT = "shards"
SHARD_SUFFIX = ".tar"
#: Digits of the shard number in file names.
SHARD_DIGITS = 6


def sample_key(sequence: str, frame: int) -> str:
    """Key of a sample: ``<sequence>/<frame:06d>`` (dots of the name written ``_``)."""
    return f"{sequence.replace('.', '_')}/{frame:06d}"


def shard_name(split: str, number: int) -> str:
    """File name of a shard, e.g. ``train-000003.tar``."""
    return f"{split}-{number:0{SHARD_DIGITS}d}{SHARD_SUFFIX}"


class ShardFormat:
    """The ``shards`` output: its settings and identity (stands where an exporter would)."""

    name = SHARD_FORMAT
    suffixes = (SHARD_SUFFIX,)
    requires: tuple[str, ...] = ()

    def __init__(self, settings: SampleSettings) -> None:
        self.settings = settings

    def identity(self) -> dict[str, Any]:
        """The part of the dataset identity this output gives."""
        return {"name": SHARD_FORMAT, "options": self.settings.model_dump(mode="json"),
                "suffix": SHARD_SUFFIX, "provider": "lidarsim-core"}


@dataclass(frozen=True)
class ShardItem:
    """One frame of a shard."""

    sequence: str
    frame: int
    split: str | None


@dataclass(frozen=True)
class ShardJob:
    """One shard to write, picklable for Dask.

    Attributes
    ----------
    path
        Absolute path of the shard file.
    items
        Its frames, in order.
    scenarios
        Sequence name → (normalised scenario JSON, its source file).
    settings_json
        The ``samples:`` settings as JSON.
    """

    path: str
    items: tuple[ShardItem, ...]
    scenarios: dict[str, tuple[str, str | None]]
    settings_json: str


_simulations: "OrderedDict[str, Any]" = OrderedDict()
#: Simulations kept per process.
CACHE_SIZE = 4


def _simulation(scenario_json: str, source: str | None) -> Any:
    from ..pipeline.simulation import Simulation
    from ..scenario.load import scenario_from_dict

    key = f"{source}\n{scenario_json}"
    if key in _simulations:
        _simulations.move_to_end(key)
        return _simulations[key]
    sim = Simulation(scenario_from_dict(json.loads(scenario_json), source=source))
    _simulations[key] = sim
    while len(_simulations) > CACHE_SIZE:
        _simulations.popitem(last=False)
    return sim


def add_member(tar: tarfile.TarFile, name: str, data: bytes) -> None:
    """Add ``data`` as member ``name`` with fixed metadata (mtime 0, root, mode 0644)."""
    info = tarfile.TarInfo(name)
    info.size = len(data)
    info.mtime = 0
    info.mode = 0o644
    info.uid = info.gid = 0
    info.uname = info.gname = ""
    tar.addfile(info, io.BytesIO(data))


def npy_bytes(array: np.ndarray) -> bytes:
    """The ``.npy`` file of ``array`` (no pickles)."""
    buffer = io.BytesIO()
    np.save(buffer, np.ascontiguousarray(array), allow_pickle=False)
    return buffer.getvalue()


def write_samples(stream: IO[bytes], job: ShardJob) -> int:
    """Simulate every frame of ``job`` and write its sample to ``stream`` (a tar); returns the
    points simulated."""
    settings = SampleSettings.model_validate_json(job.settings_json)
    points = 0
    with tarfile.open(fileobj=stream, mode="w", format=tarfile.USTAR_FORMAT) as tar:
        for item in job.items:
            sim = _simulation(*job.scenarios[item.sequence])
            cloud = sim.run_frame(item.frame)
            points += len(cloud)
            arrays = make_sample(cloud, settings, sim.scenario.seed,
                                 sim.pattern if settings.range_image else None)
            key = sample_key(item.sequence, item.frame)
            layout = None
            if settings.range_image:
                layout = sim.pattern.name
            meta = sample_meta(cloud, sequence=item.sequence, split=item.split,
                               settings=settings, layout=layout)
            add_member(tar, f"{key}.json", json.dumps(meta, sort_keys=True).encode("utf-8"))
            for name in sorted(arrays):
                add_member(tar, f"{key}.{name}.npy", npy_bytes(arrays[name]))
    return points


def run_shard_job(job: ShardJob) -> dict[str, Any]:
    """Write one shard atomically (what the serial loop and Dask workers run).

    Returns
    -------
    dict
        ``file`` (name), ``samples``, ``points`` (simulated), ``bytes``, ``sha256``.
    """
    path = Path(job.path)
    path.parent.mkdir(parents=True, exist_ok=True)
    with atomic_output(path) as stream:
        points = write_samples(stream, job)
    return {"file": path.name, "samples": len(job.items), "points": points,
            "bytes": path.stat().st_size, "sha256": sha256_file(path)}


def plan_shards(order: list[tuple[str, int, str | None]], settings: SampleSettings
                ) -> list[tuple[str, list[ShardItem]]]:
    """Cut ``(sequence, frames, split)`` in order into shards: ``(file name, items)`` each.

    Every split's frames are laid end to end in the given order and cut every
    ``settings.shard_frames``; a dataset without splits uses the name ``all``.
    """
    by_split: dict[str, list[ShardItem]] = {}
    for sequence, frames, split in order:
        items = by_split.setdefault(split or "all", [])
        items += [ShardItem(sequence, frame, split) for frame in range(frames)]
    out = []
    size = settings.shard_frames
    for split in ("train", "val", "test", "all"):
        items = by_split.get(split, [])
        for number, start in enumerate(range(0, len(items), size)):
            out.append((shard_name(split, number), items[start:start + size]))
    return out
