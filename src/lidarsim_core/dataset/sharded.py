"""A run of ``format: shards``: plan the shards, write the missing ones, finish the manifest.

A shard is written whole and renamed into place (:func:`~.shards.run_shard_job`), so a shard
file on disk is complete: a rerun skips it and writes the others (``--verify`` re-hashes the
ones the manifest of a finished run lists). The final manifest lists every shard with its
samples, size and SHA-256 and, per sequence, every frame's shard and key.
"""

from __future__ import annotations

import io
import json
import tarfile
from pathlib import Path
from typing import Any, Iterator

import yaml

from ..base.atomic import atomic_output
from ..base.errors import ConfigError, OutputError
from ..io.rangeimage import has_layout
from ..io.sidecar import sha256_file
from .checks import scenario_differences
from .executors import run_dask
from .layout import MANIFEST, POSES, SCENARIO_COPY, SPLITS
from .manifest import write_manifest
from .progress import FrameProgress
from .sequence import SequenceRun
from .shards import (
    SHARDS_DIR,
    ShardFormat,
    ShardJob,
    add_member,
    plan_shards,
    run_shard_job,
    sample_key,
    shard_name,
)

#: The archive of every sequence's scenario copy and poses in a sharded dataset.
SEQUENCES_ARCHIVE = "sequences.tar"


def archive_members(name: str) -> dict[str, str]:
    """Members of sequence ``name`` in :data:`SEQUENCES_ARCHIVE`: ``scenario`` and ``poses``."""
    return {"scenario": f"{name}/{SCENARIO_COPY}", "poses": f"{name}/{POSES}"}


def write_sequence_archive(root: Path, sequences: list[SequenceRun]) -> None:
    """Write :data:`SEQUENCES_ARCHIVE` atomically (left alone if it already holds the same
    bytes)."""
    buffer = io.BytesIO()
    with tarfile.open(fileobj=buffer, mode="w", format=tarfile.USTAR_FORMAT) as tar:
        for seq in sequences:
            assert seq.poses is not None
            members = archive_members(seq.plan.name)
            add_member(tar, members["scenario"],
                       yaml.safe_dump(seq.data, sort_keys=False).encode("utf-8"))
            add_member(tar, members["poses"], seq.poses.read_bytes())
    data = buffer.getvalue()
    path = root / SEQUENCES_ARCHIVE
    if path.is_file() and path.read_bytes() == data:
        return
    with atomic_output(path) as stream:
        stream.write(data)


def read_archive_member(root: Path, member: str) -> bytes | None:
    """The bytes of ``member`` of the dataset's :data:`SEQUENCES_ARCHIVE` (``None`` if it or
    the archive is missing)."""
    try:
        with tarfile.open(root / SEQUENCES_ARCHIVE) as tar:
            stream = tar.extractfile(member)
            return stream.read() if stream is not None else None
    except (OSError, KeyError, tarfile.TarError):
        return None


def sharded_differences(root: Path, sequences: list[SequenceRun], manifest: dict[str, Any]
                        ) -> list[str]:
    """What differs between the sequences of this run and those of the sharded dataset in
    ``root``: :func:`~.checks.scenario_differences` with the scenario copies read from the
    sequence archive."""
    def old_of(seq: SequenceRun) -> dict[str, Any] | None:
        text = read_archive_member(root, archive_members(seq.plan.name)["scenario"])
        return yaml.safe_load(text) if text is not None else None

    return scenario_differences(root, sequences, manifest, old_of)


def _write_splits(root: Path, record: dict[str, Any]) -> None:
    # no splits/*.txt: the shards are named by split, the manifest lists their samples
    text = json.dumps(record, indent=1, sort_keys=True) + "\n"
    path = root / SPLITS
    if not (path.is_file() and path.read_text(encoding="utf-8") == text):
        with atomic_output(path) as stream:
            stream.write(text.encode("utf-8"))


def run_sharded(root: Path, sequences: list[SequenceRun], output: ShardFormat,
                identity: dict[str, Any], summaries: list[dict[str, Any]],
                assignment: dict[str, str], split_record: dict[str, Any] | None, *,
                workers: int | None, scheduler: str | None, display: Any, verify: bool,
                source: str | None = None, previous: dict[str, Any] | None = None
                ) -> tuple[int, int, int, int, float]:
    """Write every shard not yet on disk, then the final manifest (see the module docstring).

    ``previous`` is the manifest found when the run started: with ``verify``, every shard it
    lists is re-hashed and written again if it differs. Returns frames in the dataset, frames
    written, frames skipped, points simulated and the elapsed time (s).
    """
    keys = [sample_key(s.plan.name, 0) for s in sequences]
    if len(set(keys)) != len(keys):
        raise OutputError("two sequence names give the same sample key (a '.' is written "
                          "'_'): rename one", source=root, field="sequences")
    if output.settings.range_image:
        for seq in sequences:
            if not has_layout(seq.sim.pattern):
                raise ConfigError(f"sequence {seq.plan.name}: scan pattern "
                                  f"'{seq.sim.pattern.name}' has no regular layout: range "
                                  "images exist for spinning, flash and raster sensors",
                                  source=source, field="samples.range_image")
    order = [(s.plan.name, s.frames, assignment.get(s.plan.name)) for s in sequences]
    shards = plan_shards(order, output.settings)
    if split_record is not None:
        _write_splits(root, split_record)
    scenarios = {s.plan.name: (json.dumps(s.data, sort_keys=True), str(s.copy_path))
                 for s in sequences}
    settings_json = output.settings.model_dump_json()
    shard_dir = root / SHARDS_DIR
    shard_dir.mkdir(exist_ok=True)
    # checksums taken when each shard was written: the manifest found when the run started
    # (a finished run's lists its shards), then this run's results
    known = {s["file"]: s["sha256"] for s in (previous or {}).get("shards", [])}
    done = []
    for file, _ in shards:
        path = shard_dir / file
        ok = path.is_file()
        listed = known.get(f"{SHARDS_DIR}/{file}")
        if ok and verify and listed is not None:
            ok = sha256_file(path) == listed
        done.append(ok)
    total = sum(s.frames for s in sequences)
    skipped = sum(len(items) for (_, items), ok in zip(shards, done) if ok)

    def jobs() -> Iterator[ShardJob]:
        for (file, items), ok in zip(shards, done):
            if not ok:
                needed = {item.sequence for item in items}
                yield ShardJob(str(shard_dir / file), tuple(items),
                               {name: scenarios[name] for name in sorted(needed)},
                               settings_json)

    def on_result(result: dict[str, Any]) -> None:
        known[f"{SHARDS_DIR}/{result['file']}"] = result["sha256"]
        for i in range(result["samples"]):  # the shard's points count once
            progress.frame_done(result["points"] if i == 0 else 0)

    try:
        with FrameProgress(total - skipped, display=display, already=skipped) as progress:
            if workers is None and scheduler is None:
                for job in jobs():
                    on_result(run_shard_job(job))
            else:
                run_dask(jobs(), on_result, workers=workers, scheduler=scheduler,
                         task=run_shard_job)
    except KeyboardInterrupt as exc:  # Ctrl-C or SIGTERM: say what is kept, and how to go on
        kept = sum((shard_dir / file).is_file() for file, _ in shards)
        raise type(exc)(f"{kept} of {len(shards)} shards are complete and kept in {root} "
                        "(no partial shard); rerun the same command to resume") from None
    entries = []
    totals = {"frames": 0, "bytes": 0}
    for file, items in shards:
        path = shard_dir / file
        if not path.is_file():
            raise OutputError("shard missing after the run", source=path)
        size = path.stat().st_size
        runs: list[list[Any]] = []
        for item in items:
            if runs and runs[-1][0] == item.sequence and \
                    runs[-1][1] + runs[-1][2] == item.frame:
                runs[-1][2] += 1
            else:
                runs.append([item.sequence, item.frame, 1])
        entries.append({"file": f"{SHARDS_DIR}/{file}", "split": items[0].split,
                        "samples": len(items), "runs": runs, "bytes": size,
                        "sha256": known.get(f"{SHARDS_DIR}/{file}") or sha256_file(path)})
        totals["frames"] += len(items)
        totals["bytes"] += size

    # where each sequence starts in its split's run of frames (constant memory per frame)
    offsets: dict[str, tuple[str, int]] = {}
    filled: dict[str, int] = {}
    for name, frames, split in order:
        offsets[name] = (split or "all", filled.get(split or "all", 0))
        filled[split or "all"] = offsets[name][1] + frames
    size = output.settings.shard_frames

    def frames_of(index: int) -> Iterator[dict[str, Any]]:
        seq = sequences[index]
        split, offset = offsets[seq.plan.name]
        for frame in range(seq.frames):
            file = f"{SHARDS_DIR}/{shard_name(split, (offset + frame) // size)}"
            yield {"frame": frame, "file": file, "key": sample_key(seq.plan.name, frame)}

    write_manifest(root / MANIFEST, identity=identity, sequences=summaries,
                   splits=split_record, frames_of=frames_of, totals=totals,
                   extra={"shards": entries})
    return total, progress.written, skipped, progress.points, progress.elapsed
