"""``lidarsim dataset``: many frames, reproducible, restartable, serial or on Dask.

A run (see :func:`generate_dataset`):

1. takes the directory's lock and reads the plan (one scenario, or a dataset file);
2. normalises each sequence's scenario (inputs copied into ``DIR/inputs``, datasheet inlined,
   backend resolved) and, if ``DIR`` already holds a dataset, refuses any difference;
3. writes the scenario copies, the poses files, the splits and a first manifest;
4. skips every frame whose file and sidecar are already complete, and produces the others,
   each written atomically (a killed run leaves only hidden ``.part`` files, removed by the
   next run);
5. writes the final manifest with every frame's checksum.

With ``format="mcap"`` steps 4 and 5 work per sequence instead of per frame: one ROS 2 bag
each (:mod:`lidarsim_core.dataset.bags`).

Running the same command again therefore resumes, and a finished directory is the same to the
bit whether or not runs were interrupted on the way.
"""

from __future__ import annotations

import json
import os
from dataclasses import dataclass
from pathlib import Path
from typing import Any, Iterator

import numpy as np
import yaml

from ..base.atomic import atomic_output, deferred_sync, sync_files, write_text_atomic
from ..base.errors import ConfigError, OutputError
from ..io.points import DEFAULT_SPOOL_MEMORY
from ..io.sidecar import frame_is_complete
from ..plugins.manager import get_registry
from ..scenario.load import scenario_from_dict
from ..scenario.model import Scenario
from .bags import (
    BAG_FORMAT,
    BAG_NAME,
    BagFormat,
    check_bag_sequences,
    write_sequence_bag,
)
from .checks import (
    check_dataset_dir,
    check_directory,
    refuse,
    remove_created,
    scenario_differences,
    validate_sequences,
)
from .config import DatasetPlan, SequencePlan, load_plan, scenario_variant
from .durable import DurableFrames
from .executors import run_dask, run_serial
from .frames import FrameJob, keep_simulation
from .identity import (
    dataset_identity,
    differences,
    exporter_identity,
    normalize_scenario,
    package_versions,
    sequence_identity,
)
from .inputs import INPUTS_DIR, InputCopier
from .layout import (
    DATASET_COPY,
    FRAMES_DIR,
    LOCK,
    MANIFEST,
    POSES,
    SCENARIO_COPY,
    SPLITS,
    SPLITS_DIR,
    frame_relpath,
    sequence_root,
)
from .lock import dataset_lock, remove_stale_parts
from .manifest import read_manifest, write_manifest
from .poses import KEEP_FRAMES, PosesFile
from .progress import FrameProgress
from .sequence import SequenceRun
from .sharded import (
    SEQUENCES_ARCHIVE,
    archive_members,
    run_sharded,
    sharded_differences,
    write_sequence_archive,
)
from .shards import SHARD_FORMAT, SHARD_SUFFIX, SHARDS_DIR, ShardFormat, sample_key
from .splits import assign_splits, splits_record, trajectory_key
from .writer_process import writer_process

#: Name of the only sequence of a dataset made from one scenario.
SINGLE_SEQUENCE = "main"
DEFAULT_FORMAT = "ply"


@dataclass
class DatasetResult:
    """What a run did.

    Attributes
    ----------
    root
        The dataset directory.
    frames_total
        Frames in the dataset.
    frames_written
        Frames this run produced.
    frames_skipped
        Frames found finished on disk.
    points_written
        Points in the frames this run produced.
    elapsed_s
        Wall time of the frame loop (s).
    """

    root: Path
    frames_total: int
    frames_written: int
    frames_skipped: int
    points_written: int
    elapsed_s: float

    @property
    def manifest(self) -> Path:
        """The manifest file."""
        return self.root / MANIFEST




def _plan_for(source: Scenario | str | Path, frames: int | None,
              sequences: int | None = None) -> DatasetPlan:
    if isinstance(source, Scenario):
        scenario = source
        if frames is not None:
            scenario = scenario_variant(scenario.model_dump(mode="json"), frames=frames,
                                        source=None if source.source == "<scenario>"
                                        else source.source)
        return DatasetPlan([SequencePlan(SINGLE_SEQUENCE, scenario)], scenario.source)
    plan = load_plan(source, frames=frames, sequences=sequences)
    if not plan.multi:
        plan.sequences[0].name = SINGLE_SEQUENCE
    return plan














def _normalise(plan: DatasetPlan, root: Path, copier: InputCopier, sharded: bool = False
               ) -> list[SequenceRun]:
    registry = get_registry()
    out = []
    for seq in plan.sequences:
        # a sharded dataset keeps every sequence's files in one archive, relative to the root
        seq_root = root if sharded else sequence_root(root, seq.name, plan.multi)
        normal = normalize_scenario(seq.scenario, registry)
        data = normal.model_dump(mode="json")
        copier.localize(normal, data, seq_root)
        out.append(SequenceRun(seq, seq_root, data))
    return out




def _write_text(path: Path, text: str) -> None:
    path.parent.mkdir(parents=True, exist_ok=True)
    if path.is_file() and path.read_text(encoding="utf-8") == text:
        return
    write_text_atomic(path, text)


def _cloud_path(frame: int, suffix: str) -> str:
    """Where frame ``frame`` of a sequence is, relative to its root: its own file, or the
    sequence's bag."""
    return BAG_NAME if suffix == BagFormat.suffixes[0] else frame_relpath(frame, suffix)


def _prepare_sequence(seq: SequenceRun, suffix: str, keep: int = 0) -> None:
    """Write the sequence's scenario copy, build its simulation and its poses file; the
    metadata of its first ``keep`` frames stays with the simulation for its frames
    (:meth:`~lidarsim_core.pipeline.simulation.Simulation.keep_frame_infos`)."""
    from ..pipeline.simulation import Simulation

    if suffix != SHARD_SUFFIX:  # sharded: in the sequences archive
        _write_text(seq.copy_path, yaml.safe_dump(seq.data, sort_keys=False))
    seq.scenario = scenario_from_dict(seq.data, source=seq.copy_path)
    sim = Simulation(seq.scenario)
    seq.frames = seq.scenario.scan.frames
    if suffix == SHARD_SUFFIX:  # the sample's key in the shards
        seq.poses = PosesFile(sim, seq.frames, lambda f: sample_key(seq.plan.name, f), keep)
    else:
        seq.poses = PosesFile(sim, seq.frames, lambda f: _cloud_path(f, suffix), keep)
    seq.sim = sim
    seq.identity = sequence_identity(seq.plan.name, sim, get_registry(), seq.poses.sha256)
    if seq.plan.drawn:  # randomised: the drawn values are part of what the dataset is
        seq.identity["drawn"] = seq.plan.drawn
    seq.group = seq.plan.group or trajectory_key(seq.scenario)


def _splits(plan: DatasetPlan, sequences: list[SequenceRun]) -> tuple[dict[str, str], Any]:
    if not plan.multi or len(sequences) < 2 or plan.config is None:
        return {}, None
    groups: dict[str, list[str]] = {}
    for seq in sequences:
        groups.setdefault(seq.group, []).append(seq.plan.name)
    pinned = {s.plan.name: s.plan.split for s in sequences if s.plan.split}
    assignment = assign_splits(groups, pinned, plan.config.splits, plan.config.split_seed,
                               source=plan.source)
    record = splits_record(groups, assignment, {s.plan.name: s.frames for s in sequences},
                           plan.config.splits, plan.config.split_seed)
    return assignment, record


def _write_split_lists(root: Path, sequences: list[SequenceRun], assignment: dict[str, str],
                       record: dict[str, Any], suffix: str) -> None:
    _write_text(root / SPLITS, json.dumps(record, indent=1, sort_keys=True) + "\n")
    for split, names in record["splits"].items():
        path = root / SPLITS_DIR / f"{split}.txt"
        path.parent.mkdir(exist_ok=True)
        with atomic_output(path) as stream:
            for seq in sequences:
                if seq.plan.name not in names:
                    continue
                rel = seq.root.relative_to(root).as_posix()
                # one line per frame file, or per bag
                paths = sorted({_cloud_path(frame, suffix) for frame in range(seq.frames)})
                for path in paths:
                    stream.write(f"{rel}/{path}\n".encode("utf-8"))


def _dataset_copy(plan: DatasetPlan, root: Path, sequences: list[SequenceRun],
                  exporter: dict[str, Any]) -> str:
    assert plan.config is not None
    config = plan.config
    entries = []
    for seq in sequences:
        entry: dict[str, Any] = {"scenario": seq.copy_path.relative_to(root).as_posix(),
                                 "name": seq.plan.name}
        if seq.plan.split:
            entry["split"] = seq.plan.split
        if seq.plan.group:
            entry["group"] = seq.plan.group
        entries.append(entry)
    data = {"sequences": entries, "splits": config.splits.model_dump(),
            "split_seed": config.split_seed, "format": exporter["name"],
            "exporter_options": exporter["options"]}
    return yaml.safe_dump(data, sort_keys=False)


def _sequence_summary(root: Path, seq: SequenceRun, split: str | None, bag: bool,
                      sharded: bool = False) -> dict[str, Any]:
    rel = seq.root.relative_to(root).as_posix() if seq.root != root else "."
    assert seq.scenario is not None
    out = {"name": seq.plan.name, "root": rel, "scenario": SCENARIO_COPY, "poses": POSES,
           "frames_dir": FRAMES_DIR, "frame_count": seq.frames, "seed": seq.scenario.seed,
           "config_hash": seq.scenario.config_hash(), "split": split, "group": seq.group}
    if seq.plan.drawn:
        out["drawn"] = seq.plan.drawn
    if bag:
        out["frames_dir"] = None
        out["bag"] = {"file": BAG_NAME}
    if sharded:
        out["frames_dir"] = None
    return out


def generate_dataset(source: Scenario | str | Path, out: str | Path, *,
                     frames: int | None = None, format: str | None = None,
                     exporter_options: dict[str, Any] | None = None,
                     workers: int | None = None, scheduler: str | None = None,
                     quiet: bool = True, verify: bool = False,
                     spool_memory: int = DEFAULT_SPOOL_MEMORY,
                     livox: bool = False, display: Any = None,
                     sequences: int | None = None) -> DatasetResult:
    """Generate (or resume, or check) a dataset in ``out``.

    Parameters
    ----------
    source
        A scenario (object or file) or a dataset file with several ``sequences``.
    out
        The dataset directory (created if missing; must be empty or hold this same dataset).
    frames
        Number of frames of every sequence (default: the scenario's ``scan.frames``).
    format
        Exporter name (default: the dataset file's ``format``, else the format of the dataset
        already in ``out``, else ``ply``), or ``mcap``: one ROS 2 bag per sequence
        (:mod:`lidarsim_core.dataset.bags`; serial only).
    exporter_options
        Options of the exporter (default: the dataset file's ``exporter_options``, else those
        of the dataset already in ``out``).
    workers
        Run on a local Dask cluster of this many single-threaded processes.
    scheduler
        Run on the Dask cluster at this address instead.
    quiet
        Draw no progress.
    display
        Draws the progress unless ``quiet`` (:class:`~lidarsim_core.dataset.progress.FrameProgress`;
        ``lidarsim dataset`` passes its progress bar).
    verify
        Recompute the checksum of every finished frame before skipping it.
    spool_memory
        Bytes of a frame's points held in memory before it streams through a temporary file.
    livox
        With ``format="mcap"``: also write the Livox ``CustomMsg`` topic (exporter option
        ``livox``).
    sequences
        Number of sequences drawn from every randomised entry of a dataset file
        (:mod:`lidarsim_core.dataset.randomize`).

    Returns
    -------
    DatasetResult
        Counts and timing of the run.

    Raises
    ------
    OutputError
        If ``out`` holds something else (another dataset, foreign files), or another run holds
        its lock.
    ConfigError
        For invalid scenarios, dataset files or options (one line naming file and field).
    """
    plan = _plan_for(source, frames, sequences)
    registry = get_registry()
    config = plan.config
    root = Path(out).resolve()
    # resuming without naming a format: keep the directory's
    previous = (read_manifest(root / MANIFEST) or {}).get("identity", {}).get("exporter") \
        if root.is_dir() else None
    name = format or (config.format if config else None) or (
        previous["name"] if previous else DEFAULT_FORMAT)
    if exporter_options is not None:
        options = exporter_options
    elif config is not None and config.exporter_options:
        options = config.exporter_options
    else:
        options = previous["options"] if previous and previous["name"] == name else {}
    exporter: Any
    if livox:
        if name != BAG_FORMAT:
            raise ConfigError(f"--livox needs --format mcap (not {name})", field="livox")
        options = {**options, "livox": True}
    if name == SHARD_FORMAT:
        if config is None or config.samples is None:
            raise ConfigError("format 'shards' needs a dataset file with a 'samples:' section",
                              source=plan.source, field="samples")
        exporter = ShardFormat(config.samples)
    elif name == BAG_FORMAT:
        if workers is not None or scheduler is not None:
            raise ConfigError("--format mcap writes each sequence's bag in this process; "
                              "drop --workers/--scheduler", field="workers")
        exporter = BagFormat.from_options(options, source=plan.source)
    else:
        exporter = registry.get("exporter", name, source=plan.source,
                                field="format").from_config(options, source=plan.source,
                                                            field="exporter_options")
    if not exporter.suffixes:
        raise OutputError(f"exporter '{name}' declares no file suffix", field="format")
    suffix = exporter.suffixes[0]
    # everything is checked before anything is created: the output directory, then every
    # sequence built once from the user's own files (errors name them, not the copies)
    check_dataset_dir(root)
    validate_sequences(plan)
    if isinstance(exporter, BagFormat):
        check_bag_sequences(seq.scenario for seq in plan.sequences)
    existed = root.exists()
    before = set(os.listdir(root)) if existed else set()
    if existed and not (root / MANIFEST).exists() and not (root / LOCK).exists():
        check_directory(root, None)  # a foreign directory is refused before the lock
    root.mkdir(parents=True, exist_ok=True)
    first_run = False
    with dataset_lock(root):
        manifest = read_manifest(root / MANIFEST)
        first_run = manifest is None
        try:
            check_directory(root, manifest)
            copier = InputCopier(root)
            sequences = _normalise(plan, root, copier, isinstance(exporter, ShardFormat))
            if manifest is not None:
                lines = sharded_differences(root, sequences, manifest) \
                    if isinstance(exporter, ShardFormat) else \
                    scenario_differences(root, sequences, manifest)
                if lines:
                    copier.forget_created()
                    refuse(root, lines)
            try:
                return _run(plan, root, sequences, exporter, manifest, suffix, workers=workers,
                            scheduler=scheduler, display=None if quiet else display,
                            verify=verify,
                            spool_memory=spool_memory)
            finally:
                for seq in sequences:
                    if seq.poses is not None:
                        seq.poses.close()
        except Exception:
            # a failed first run leaves the directory as it found it (an interrupted one
            # keeps its frames: the next run resumes)
            if first_run:
                remove_created(root, before)
            raise
        finally:
            if first_run and not existed and not (root / MANIFEST).exists() and \
                    set(os.listdir(root)) <= {LOCK}:
                (root / LOCK).unlink(missing_ok=True)
                root.rmdir()
            elif LOCK not in before and not (root / MANIFEST).exists():
                (root / LOCK).unlink(missing_ok=True)


def _run(plan: DatasetPlan, root: Path, sequences: list[SequenceRun], exporter: Any,
         manifest: dict[str, Any] | None, suffix: str, *, workers: int | None,
         scheduler: str | None, display: Any, verify: bool, spool_memory: int
         ) -> DatasetResult:
    registry = get_registry()
    bag = isinstance(exporter, BagFormat)
    sharded = isinstance(exporter, ShardFormat)
    if workers is None and scheduler is None and not (bag or sharded):
        writer_process()  # its imports overlap the set-up and the first frame's meshes
    # the poses files make every frame's metadata before the frames run; the frames of a
    # run in this process take theirs from there instead of making it again (~70 µs a
    # frame), for KEEP_FRAMES frames of the run at most (bounded memory)
    keep = KEEP_FRAMES if workers is None and scheduler is None else 0
    for seq in sequences:
        _prepare_sequence(seq, suffix, keep)
        keep = max(0, keep - seq.frames)
    exp_id = exporter.identity() if bag or sharded else exporter_identity(exporter, registry)
    identity = dataset_identity([s.identity for s in sequences if s.identity], exp_id,
                                multi=plan.multi, packages=package_versions(exporter.requires))
    if manifest is not None and manifest.get("identity") != identity:
        refuse(root, differences(manifest.get("identity"), identity))
    remove_stale_parts([root, root / INPUTS_DIR, root / SPLITS_DIR, root / SHARDS_DIR] +
                       [d for s in sequences for d in (s.root, s.root / FRAMES_DIR)])
    assignment, split_record = _splits(plan, sequences)
    summaries = [_sequence_summary(root, s, assignment.get(s.plan.name), bag, sharded)
                 for s in sequences]
    if sharded:  # the manifest holds every sequence's values; poses in sequences.tar
        for summary in summaries:
            summary.update(root=SEQUENCES_ARCHIVE, **archive_members(summary["name"]))
        write_manifest(root / MANIFEST, identity=identity, sequences=summaries,
                       splits=split_record)
        write_sequence_archive(root, sequences)
        return DatasetResult(root, *run_sharded(root, sequences, exporter, identity, summaries,
                                                assignment, split_record, workers=workers,
                                                scheduler=scheduler, display=display,
                                                verify=verify, source=plan.source,
                                                previous=manifest))
    # the first manifest, the poses, the copies and the splits are written atomically and
    # made durable together, before any frame (one sync instead of one per file)
    with deferred_sync([]) as written:
        write_manifest(root / MANIFEST, identity=identity, sequences=summaries,
                       splits=split_record)
        for seq in sequences:
            assert seq.poses is not None
            seq.poses.save(seq.root / POSES)
            if not bag:
                (seq.root / FRAMES_DIR).mkdir(parents=True, exist_ok=True)
        if plan.multi:
            _write_text(root / DATASET_COPY, _dataset_copy(plan, root, sequences, exp_id))
        if split_record is not None:
            _write_split_lists(root, sequences, assignment, split_record, suffix)
    sync_files(written)
    if bag:
        return _run_bags(root, sequences, exporter, identity, summaries, split_record,
                         display=display, verify=verify)

    # a frame written since the last synced block of an interrupted run is checked against
    # its checksum too: after a crash it may be on disk empty or in part (dataset/durable.py)
    durable = DurableFrames.read(root, manifest)
    # no manifest before this run: it wrote the first, and no frame is written before it
    done = {s.plan.name: np.zeros(s.frames, dtype=bool) if manifest is None else np.array(
        [frame_is_complete(s.root / frame_relpath(f, suffix),
                           verify=verify or (s.plan.name, f) not in durable) is not None
         for f in range(s.frames)], dtype=bool) for s in sequences}
    total = sum(s.frames for s in sequences)
    skipped = int(sum(int(m.sum()) for m in done.values()))

    texts = {seq.plan.name: json.dumps(seq.data, sort_keys=True) for seq in sequences}
    serial = workers is None and scheduler is None

    def jobs() -> Iterator[FrameJob]:
        options = exporter.options.model_dump(mode="json")  # one dictionary, every job's
        for seq in sequences:
            text = texts[seq.plan.name]
            if serial:  # the frames run in the simulation built for the poses
                keep_simulation(str(seq.copy_path), text, seq.sim)
            root_dir, copy = os.fspath(seq.root), str(seq.copy_path)
            for frame in np.flatnonzero(~done[seq.plan.name]).tolist():
                path = os.path.join(root_dir, *frame_relpath(frame, suffix).split("/"))
                yield FrameJob(seq.plan.name, frame, path, text, copy, exporter.name, options,
                               spool_memory)

    written: dict[tuple[str, int], dict[str, Any]] = {}  # this run's frames, for the manifest
    try:
        with FrameProgress(total - skipped, display=display, already=skipped) as progress:
            def on_result(result: dict[str, Any]) -> None:
                written[(result["sequence"], result["frame"])] = result
                progress.frame_done(result["points"])

            if serial:
                run_serial(jobs(), on_result, on_durable=durable.add)
            else:
                run_dask(jobs(), on_result, workers=workers, scheduler=scheduler)
    except KeyboardInterrupt as exc:  # Ctrl-C or SIGTERM: say what is kept, and how to go on
        kept = sum(frame_is_complete(s.root / frame_relpath(f, suffix)) is not None
                   for s in sequences for f in range(s.frames))
        raise type(exc)(f"{kept} of {total} frames are complete and kept in "
                        f"{root} (no partial frame file); rerun the same command to resume"
                        ) from None
    _finish(root, sequences, identity, summaries, split_record, suffix, written)
    durable.remove()
    return DatasetResult(root, total, progress.written, skipped, progress.points,
                         progress.elapsed)


def _bag_record(seq: SequenceRun, verify: bool = False) -> dict[str, Any] | None:
    """The sidecar record of the sequence's bag if it is complete (and holds every frame)."""
    record = frame_is_complete(seq.root / BAG_NAME, verify=verify)
    if record is None or record.get("frames") != seq.frames or \
            len(record.get("points_per_frame", ())) != seq.frames:
        return None
    return record


def _run_bags(root: Path, sequences: list[SequenceRun], exporter: BagFormat,
              identity: dict[str, Any], summaries: list[dict[str, Any]],
              splits: dict[str, Any] | None, *, display: Any, verify: bool) -> DatasetResult:
    """Write the bag of every sequence whose bag is not complete, then the final manifest."""
    done = [_bag_record(seq, verify) is not None for seq in sequences]
    total = sum(s.frames for s in sequences)
    skipped = sum(s.frames for s, d in zip(sequences, done) if d)
    try:
        with FrameProgress(total - skipped, display=display, already=skipped) as progress:
            for seq, finished in zip(sequences, done):
                if not finished:
                    write_sequence_bag(seq.sim, seq.frames, seq.root / BAG_NAME,
                                       livox=exporter.livox, on_frame=progress.frame_done)
    except KeyboardInterrupt as exc:  # Ctrl-C or SIGTERM: say what is kept, and how to go on
        kept = sum(_bag_record(seq) is not None for seq in sequences)
        raise type(exc)(f"{kept} of {len(sequences)} sequence bags are complete and kept in "
                        f"{root} (no partial bag); rerun the same command to resume") from None
    totals = {"frames": 0, "points": 0, "bytes": 0}
    for seq, summary in zip(sequences, summaries):
        record = _bag_record(seq)
        if record is None:
            raise OutputError("bag or its sidecar missing after the run", source=seq.root /
                              BAG_NAME)
        rel = seq.root.relative_to(root).as_posix()
        summary["bag"] = {"file": BAG_NAME if rel == "." else f"{rel}/{BAG_NAME}",
                          "frames": record["frames"], "points": record["points"],
                          "points_per_frame": record["points_per_frame"],
                          "bytes": record["bytes"], "sha256": record["sha256"]}
        totals["frames"] += record["frames"]
        totals["points"] += record["points"]
        totals["bytes"] += record["bytes"]

    def frames_of(index: int) -> Iterator[dict[str, Any]]:
        bag_file = summaries[index]["bag"]["file"]
        for frame, points in enumerate(summaries[index]["bag"]["points_per_frame"]):
            yield {"frame": frame, "file": bag_file, "points": points}

    write_manifest(root / MANIFEST, identity=identity, sequences=summaries, splits=splits,
                   frames_of=frames_of, totals=totals)
    return DatasetResult(root, total, progress.written, skipped, progress.points,
                         progress.elapsed)


def _finish(root: Path, sequences: list[SequenceRun], identity: dict[str, Any],
            summaries: list[dict[str, Any]], splits: dict[str, Any] | None, suffix: str,
            written: dict[tuple[str, int], dict[str, Any]] | None = None) -> None:
    """Write the final manifest: the frames this run wrote from their results (``written``,
    the values of their sidecars), the others from their sidecars on disk."""
    totals = {"frames": 0, "points": 0, "bytes": 0}
    written = written or {}

    def frames_of(index: int) -> Iterator[dict[str, Any]]:
        seq = sequences[index]
        rel = seq.root.relative_to(root).as_posix()
        for frame in range(seq.frames):
            record = written.get((seq.plan.name, frame)) or \
                frame_is_complete(seq.root / frame_relpath(frame, suffix))
            if record is None:
                raise OutputError("frame file or sidecar missing after the run",
                                  source=seq.root / frame_relpath(frame, suffix))
            totals["frames"] += 1
            totals["points"] += record["points"]
            totals["bytes"] += record["bytes"]
            file = frame_relpath(frame, suffix) if rel == "." else \
                f"{rel}/{frame_relpath(frame, suffix)}"
            yield {"frame": frame, "file": file, "points": record["points"],
                   "bytes": record["bytes"], "sha256": record["sha256"]}

    write_manifest(root / MANIFEST, identity=identity, sequences=summaries, splits=splits,
                   frames_of=frames_of, totals=totals)
