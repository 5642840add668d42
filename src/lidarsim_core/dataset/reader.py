"""Reading a sharded training set: :func:`open_dataset` (``ls.open_dataset``).

The returned :class:`TrainingSet` is a map-style dataset: ``len(ds)`` samples, ``ds[i]`` a dict
of NumPy arrays (:mod:`~lidarsim_core.dataset.samples` lists the keys) plus ``meta``, the
sample's metadata dict. That is the protocol PyTorch's ``DataLoader`` (and JAX, TensorFlow or
plain loops) take; lidarsim imports none of them.

Files are opened lazily, on the first sample read from a shard, and the open files are never
pickled: every worker process, forked or spawned, opens its own. The samples are in a fixed
order (shards in the manifest's order, samples in each shard's order), so a loader with the
same sampler seed gives the same samples in the same order.
"""

from __future__ import annotations

import json
import os
import tarfile
from pathlib import Path
from typing import IO, Any

import numpy as np
import yaml

from ..base.errors import UserInputError
from .layout import MANIFEST
from .manifest import read_manifest
from .sharded import archive_members, read_archive_member
from .shards import sample_key


class TrainingSet:
    """The samples of one split of a sharded dataset (see the module docstring).

    Attributes
    ----------
    root
        The dataset directory.
    split
        The split read (``None``: every sample).
    keys
        ``(shard file, sample key)`` of every sample, in order.
    """

    def __init__(self, root: Path, split: str | None, keys: list[tuple[str, str]]) -> None:
        self.root = root
        self.split = split
        self.keys = keys
        self._files: dict[str, IO[bytes]] = {}
        self._members: dict[str, dict[str, list[tuple[str, int, int]]]] = {}
        self._pid = os.getpid()

    def __len__(self) -> int:
        return len(self.keys)

    def __getstate__(self) -> dict[str, Any]:
        state = self.__dict__.copy()
        state["_files"] = {}
        state["_members"] = {}
        return state

    def __setstate__(self, state: dict[str, Any]) -> None:
        self.__dict__.update(state)
        self._pid = os.getpid()

    def _member_index(self, shard: str
                      ) -> tuple[IO[bytes], dict[str, list[tuple[str, int, int]]]]:
        if self._pid != os.getpid():  # forked: the parent's file positions are shared
            self._files, self._members, self._pid = {}, {}, os.getpid()
        stream = self._files.get(shard)
        if stream is None:
            path = self.root / shard
            stream = open(path, "rb")
            index: dict[str, list[tuple[str, int, int]]] = {}
            with tarfile.open(fileobj=stream, mode="r:") as tar:
                for member in tar:  # key.field: the key is up to the first dot of the base
                    folder, _, base = member.name.rpartition("/")
                    stem, _, field = base.partition(".")
                    key = f"{folder}/{stem}" if folder else stem
                    index.setdefault(key, []).append((field, member.offset_data, member.size))
            self._members[shard] = index
            self._files[shard] = stream
        return stream, self._members[shard]

    def __getitem__(self, index: int) -> dict[str, Any]:
        if not -len(self) <= index < len(self):
            raise IndexError(f"sample {index} of {len(self)}")
        shard, key = self.keys[index]
        stream, members = self._member_index(shard)
        out: dict[str, Any] = {}
        for field, offset, size in members.get(key, ()):
            stream.seek(offset)
            if field == "json":
                out["meta"] = json.loads(stream.read(size))
            elif field.endswith(".npy"):
                out[field[:-4]] = np.lib.format.read_array(stream, allow_pickle=False)
        if "meta" not in out:
            raise UserInputError(f"sample {key} missing from its shard", source=self.root / shard)
        return out

    def poses(self, sequence: str) -> dict[str, Any]:
        """The ``poses.json`` of ``sequence`` (from ``sequences.tar``): the ground truth of
        every frame, ``frames[i]["targets"][j]["q_target_in_sensor"]``..."""
        return json.loads(self._archive(sequence, "poses"))

    def scenario(self, sequence: str) -> dict[str, Any]:
        """The normalised scenario ``sequence`` simulated, drawn values included."""
        return yaml.safe_load(self._archive(sequence, "scenario"))

    def _archive(self, sequence: str, what: str) -> bytes:
        data = read_archive_member(self.root, archive_members(sequence)[what])
        if data is None:
            raise UserInputError(f"no {what} of sequence '{sequence}' in sequences.tar",
                                 source=self.root)
        return data

    def close(self) -> None:
        """Close the shard files this process opened."""
        for stream in self._files.values():
            stream.close()
        self._files, self._members = {}, {}

    def __repr__(self) -> str:
        return f"TrainingSet({str(self.root)!r}, split={self.split!r}, samples={len(self)})"


def open_dataset(path: str | Path, split: str | None = "train") -> TrainingSet:
    """Open the samples of a sharded dataset (``lidarsim dataset`` with ``format: shards``).

    Parameters
    ----------
    path
        The dataset directory.
    split
        ``"train"``, ``"val"``, ``"test"``, or ``None`` for every sample.

    Returns
    -------
    TrainingSet
        Indexable and sized; items are dicts of NumPy arrays plus ``meta``.

    Raises
    ------
    UserInputError
        If ``path`` holds no finished sharded dataset, or the split is unknown.
    """
    root = Path(path)
    manifest = read_manifest(root / MANIFEST)
    if manifest is None:
        raise UserInputError("no lidarsim dataset manifest here", source=root / MANIFEST)
    if not manifest.get("complete") or "shards" not in manifest:
        raise UserInputError("not a finished sharded dataset (generate it with format: "
                             "shards; rerun to finish an interrupted one)",
                             source=root / MANIFEST)
    shards = manifest["shards"]
    splits = sorted({s["split"] for s in shards if s["split"] is not None})
    if split is not None and split not in splits:
        raise UserInputError(f"split '{split}' not in this dataset (it has: "
                             f"{', '.join(splits) or 'no splits; pass split=None'})",
                             source=root / MANIFEST, field="split")
    keys = []
    for shard in shards:
        if split is not None and shard["split"] != split:
            continue
        for sequence, first, count in shard["runs"]:
            keys += [(shard["file"], sample_key(sequence, frame))
                     for frame in range(first, first + count)]
    return TrainingSet(root, split, keys)
