"""The evaluation harness: run an estimator over a dataset, frame by frame, resumably.

Each frame's result (estimate, truth, metrics, runtime) is written atomically to
``OUT/frames/<sequence>/frame_NNNNNN.json`` as soon as it is known; the outputs
(``estimates.json``, ``metrics.csv``, ``summary.json``, plots, ``report.html``) are then built
from those records alone. A run that is interrupted (Ctrl-C, SIGKILL) and started again skips
the frames it has, gives the next frame the stored previous estimate, and so ends with the
same files as a run in one go (apart from the measured runtimes). ``OUT/evaluation.json``
records what the results depend on; a rerun with anything different is refused.
"""

from __future__ import annotations

import json
import math
import time
import zlib
from dataclasses import dataclass
from pathlib import Path
from typing import Any, Callable, Iterable, Mapping

import numpy as np

from .._version import __version__
from ..base.errors import ConfigError, OutputError
from .base import EstimationFailed, FrameInput, PoseEstimate, PoseEstimator
from .data import (
    SequenceData,
    frame_record_name,
    load_json,
    open_dataset,
    read_frame_columns,
    safe_name,
)
from .extras import require
from .metrics import pose_errors
from .scores import TargetScorer
from .symmetry import Symmetry, SymmetryGroup

CONFIG_FORMAT = "lidarsim-evaluation"
#: 2: frame records carry the scores of :mod:`.scores` (records of version 1 are not reused).
CONFIG_VERSION = 2
CONFIG_FILE = "evaluation.json"
RECORDS_DIR = "frames"
#: Default edges of the range bins of the summary (m); the last bin is open.
DEFAULT_RANGE_BINS_M: tuple[float, ...] = (0.0, 10.0, 20.0, 50.0, 100.0, 200.0, 500.0)
#: Default thresholds of the summary's ``within_rate``: 5 cm and 2°.
DEFAULT_WITHIN: tuple[float, float] = (0.05, 2.0)


@dataclass
class EvaluationResult:
    """What :func:`evaluate_dataset` did.

    Attributes
    ----------
    out
        The output directory.
    frames_total, frames_evaluated, frames_skipped
        Frames of the evaluation, run now, and found done on disk.
    failures
        Frames without a valid estimate (failed, raised, NaN).
    summary
        The content of ``summary.json``.
    elapsed_s
        Wall time of this run.
    """

    out: Path
    frames_total: int
    frames_evaluated: int
    frames_skipped: int
    failures: int
    summary: dict[str, Any]
    elapsed_s: float


def _estimator(name: str, options: Mapping[str, Any] | None, registry: Any
               ) -> tuple[PoseEstimator, str]:
    from ..plugins.manager import get_registry

    registry = registry or get_registry()
    entry = registry.entry("pose_estimator", name, field="--estimator")
    estimator = entry.obj.from_config(dict(options or {}), field="--option")
    return estimator, entry.provider


def _prepare_out(out: Path, config: dict[str, Any]) -> None:
    path = out / CONFIG_FILE
    if out.exists() and not out.is_dir():
        raise OutputError("--out must be a directory", source=out)
    if out.is_dir() and any(out.iterdir()):
        old = load_json(path)
        if not isinstance(old, dict) or old.get("format") != CONFIG_FORMAT:
            raise OutputError("directory is not empty and holds no evaluation; use a new --out "
                              "directory", source=out)
        changed = [f"{k}: {json.dumps(old.get(k))} → {json.dumps(v)}"
                   for k, v in config.items() if old.get(k) != v]
        if changed:
            raise OutputError(f"holds an evaluation made differently ({'; '.join(changed)}); "
                              "use another --out directory, or delete this one to start over",
                              source=out)
        return
    out.mkdir(parents=True, exist_ok=True)
    from ..base.atomic import write_text_atomic

    write_text_atomic(path, json.dumps(config, indent=1, sort_keys=True) + "\n")


def _frame_seed(seed: int, sequence: str, frame: int) -> int:
    return (seed * 1_000_003 + zlib.crc32(sequence.encode()) * 7919 + frame) % (2 ** 63)


def _reference_time(seq: SequenceData, columns: Mapping[str, np.ndarray], on_target: np.ndarray,
                    t_start: float, t_end: float) -> float:
    """Frame start under ``motion: frozen``; otherwise the mean emission time of the target's
    points (what an estimator that ignores timestamps fits), mid-frame without any."""
    if seq.frozen:
        return t_start
    times = np.asarray(columns["timestamp"])[on_target]
    return float(times.mean()) if len(times) else 0.5 * (t_start + t_end)


def _valid(estimate: Any, t_start: float, t_end: float) -> tuple[PoseEstimate, str]:
    """The estimate, or a failure with the status that explains why."""
    if not isinstance(estimate, PoseEstimate):
        return PoseEstimate.failure(f"returned {type(estimate).__name__}, not a PoseEstimate"), \
            "invalid"
    if not estimate.success:
        return estimate, "failed"
    if not estimate.is_finite():
        return PoseEstimate.failure("returned a non-finite pose (NaN or inf)"), "invalid"
    if estimate.time_s is not None and not (math.isfinite(estimate.time_s) and
                                            t_start <= estimate.time_s <= t_end):
        return PoseEstimate.failure(f"time_s {estimate.time_s} is outside the frame "
                                    f"[{t_start}, {t_end}]"), "invalid"
    return estimate, "ok"


def _run_frame(seq: SequenceData, entry: Any, target: int, estimator: PoseEstimator,
               previous: PoseEstimate | None, group: SymmetryGroup, segment: bool, seed: int,
               timer: Callable[[], float], scorer: TargetScorer | None = None
               ) -> dict[str, Any]:
    columns = read_frame_columns(entry.path)
    n_all = len(columns["x"])
    detected = np.asarray(columns["detected"]) == 1 if "detected" in columns else \
        np.ones(n_all, dtype=bool)
    labels = np.asarray(columns["target"]) if "target" in columns else np.zeros(n_all)
    on_target = detected & (labels == target)
    keep = on_target if segment else detected
    points = {name: values[keep] for name, values in columns.items()}
    record = seq.poses["frames"][entry.frame]
    t_start, t_end = float(record["t_start_s"]), float(record["t_end_s"])
    t_ref = _reference_time(seq, columns, on_target, t_start, t_end)
    q_ref, r_ref = seq.truth(entry.frame, target, t_ref)
    truth = PoseEstimate(q_ref, r_ref, time_s=t_ref)
    frame_input = FrameInput(seq.name, entry.frame, t_start, t_end, points, seq.model(target),
                             previous, truth if estimator.uses_truth else None,
                             _frame_seed(seed, seq.name, entry.frame))
    started = timer()
    try:
        raw: Any = estimator.estimate(frame_input)
        runtime = timer() - started
        estimate, status = _valid(raw, t_start, t_end)
    except EstimationFailed as exc:
        runtime = timer() - started
        estimate, status = PoseEstimate.failure(str(exc) or "failed"), "failed"
    except Exception as exc:  # a faulty estimator costs one frame, not the run
        runtime = timer() - started
        estimate = PoseEstimate.failure(f"raised {type(exc).__name__}: {' '.join(str(exc).split())}")
        status = "error"
    metrics: dict[str, float] | None = None
    if status == "ok" and estimate.time_s is None:
        estimate.time_s = t_ref  # stored, so the next frame's ``previous`` says when it was
    if status == "ok":
        t_est = estimate.time_s if estimate.time_s is not None else t_ref
        q_gt, r_gt = (q_ref, r_ref) if t_est == t_ref else seq.truth(entry.frame, target, t_est)
        metrics = pose_errors(estimate.quaternion_xyzw, estimate.translation_m, q_gt, r_gt, group,
                              scorer)
    return {"version": CONFIG_VERSION, "sequence": seq.name, "frame": entry.frame,
            "time_s": t_ref, "range_m": float(np.linalg.norm(r_ref)), "points": int(keep.sum()),
            "target_points": int(on_target.sum()), "status": status,
            "estimate": estimate.to_record(),
            "truth": {"q_target_in_sensor": [float(v) for v in q_ref],
                      "r_target_in_sensor_m": [float(v) for v in r_ref]},
            "metrics": metrics, "runtime_s": float(runtime),
            "target_diameter_m": None if scorer is None else scorer.diameter_m}


class _Progress:
    """Frames evaluated and failed, shown on ``display`` (if any): ``start(total, done)``,
    ``advance(failures)`` and ``stop()`` (the command line's bar,
    :class:`lidarsim_core.cli.progress.EvaluateBar`)."""

    def __init__(self, total: int, done: int, display: Any) -> None:
        self.display = display
        self.failures = 0
        if display is not None:
            display.start(total, done)

    def advance(self, failed: bool) -> None:
        self.failures += int(failed)
        if self.display is not None:
            self.display.advance(self.failures)

    def close(self) -> None:
        if self.display is not None:
            self.display.stop()


def _stored(path: Path, seq: str, frame: int) -> dict[str, Any] | None:
    record = load_json(path)
    if isinstance(record, dict) and record.get("version") == CONFIG_VERSION and \
            record.get("sequence") == seq and record.get("frame") == frame:
        return record
    return None


def evaluate_dataset(dataset: str | Path, out: str | Path, estimator: str,
                     options: Mapping[str, Any] | None = None, *, split: str | None = None,
                     target: str | None = None, symmetries: Iterable[Symmetry] = (),
                     segment: bool = False, seed: int = 0,
                     range_bins_m: Iterable[float] = DEFAULT_RANGE_BINS_M,
                     within: tuple[float, float] = DEFAULT_WITHIN,
                     quiet: bool = True, registry: Any = None, display: Any = None,
                     timer: Callable[[], float] = time.perf_counter,
                     verify: bool = True) -> EvaluationResult:
    """Score estimator ``estimator`` on every frame of the dataset at ``dataset``.

    Parameters
    ----------
    dataset
        A complete dataset directory (``lidarsim dataset``).
    out
        Output directory: new, empty, or one this same evaluation started (it then resumes).
    estimator, options
        Registered pose-estimator name and its options (validated by its ``Options``).
    split
        Evaluate only the sequences of this split (``train``, ``val``, ``test``).
    target
        Name of the target whose pose is estimated (default: each sequence's first target).
    symmetries
        The target's symmetries (body frame); the metrics then score the closest equivalent
        true pose (:mod:`lidarsim_core.evaluate.symmetry`).
    segment
        Give the estimator only the points of the target (by their ground-truth label) instead
        of every detected point of the frame.
    seed
        Seed of estimators that draw random numbers (combined with sequence and frame).
    range_bins_m
        Edges of the summary's range bins (m), ascending; the last bin is open.
    within
        ``(metres, degrees)``: the summary's ``within_rate`` is the fraction of frames whose
        estimate is within both (an estimate is not necessarily a right one).
    quiet
        Draw no progress.
    registry
        Plugin registry (default: the process-wide one).
    display
        Draws the progress unless ``quiet`` (``lidarsim evaluate`` passes its progress bar).
    timer
        Clock used to time each call (seconds).
    verify
        Recompute every frame file's SHA-256 and compare it with the manifest's before
        anything is written (the default; ``False`` skips it for speed). Paths outside the
        dataset and malformed ``poses.json`` files are refused either way.

    Raises
    ------
    ConfigError, OutputError, UnknownNameError
        Bad dataset, options or output directory (nothing is written then).
    """
    from .outputs import write_outputs

    started = time.perf_counter()
    dataset, out = Path(dataset), Path(out)
    est, provider = _estimator(estimator, options, registry)
    for module in ("matplotlib", *type(est).requires):  # before anything is written
        require(module, f"lidarsim evaluate --estimator {estimator}")
    bins = [float(b) for b in range_bins_m]
    within = (float(within[0]), float(within[1]))
    if not all(math.isfinite(v) and v > 0 for v in within):
        raise ConfigError("the thresholds must be positive numbers", field="--within")
    if len(bins) < 1 or any(not math.isfinite(b) for b in bins) or \
            any(b >= c for b, c in zip(bins, bins[1:])):
        raise ConfigError("range bin edges must be finite and ascending", field="--range-bins")
    symmetries = list(symmetries)
    group = SymmetryGroup.from_symmetries(symmetries)
    sequences, fingerprint = open_dataset(dataset, split, verify=verify)
    indices = [seq.target_index(target) for seq in sequences]
    config = {"format": CONFIG_FORMAT, "version": CONFIG_VERSION,
              "dataset_manifest_sha256": fingerprint, "estimator": estimator,
              "estimator_provider": provider, "uses_truth": bool(type(est).uses_truth),
              "options": est.options.model_dump(mode="json"), "split": split, "target": target,
              "symmetries": [s.model_dump(mode="json") for s in symmetries],
              "segment": segment, "seed": seed, "range_bins_m": bins,
              "within_m_deg": list(within),
              "lidarsim": __version__}
    from ..dataset.lock import remove_stale_parts

    _prepare_out(out, config)
    dirs = {seq.name: out / RECORDS_DIR / safe_name(seq.name) for seq in sequences}
    remove_stale_parts([out, *dirs.values()])
    total = sum(len(seq.frames) for seq in sequences)
    done = sum(1 for seq in sequences for e in seq.frames
               if _stored(dirs[seq.name] / frame_record_name(e.frame), seq.name, e.frame))
    from ..base.atomic import write_text_atomic

    records: dict[str, list[dict[str, Any]]] = {}
    evaluated = 0
    progress = _Progress(total, done, None if quiet else display)
    try:
        for seq, index in zip(sequences, indices):
            folder = dirs[seq.name]
            folder.mkdir(parents=True, exist_ok=True)
            est.start_sequence(seq.model(index))
            scorer = TargetScorer(seq.model(index).vertices, group)
            previous: PoseEstimate | None = None
            records[seq.name] = []
            for entry in seq.frames:
                path = folder / frame_record_name(entry.frame)
                record = _stored(path, seq.name, entry.frame)
                if record is None:
                    record = _run_frame(seq, entry, index, est, previous, group, segment, seed,
                                        timer, scorer)
                    write_text_atomic(path, json.dumps(record, sort_keys=True) + "\n")
                    evaluated += 1
                    progress.advance(record["status"] != "ok")
                previous = PoseEstimate.from_record(record["estimate"])
                records[seq.name].append(record)
    finally:
        progress.close()
    summary = write_outputs(out, config, records, bins)
    failures = sum(1 for rs in records.values() for r in rs if r["status"] != "ok")
    return EvaluationResult(out, total, evaluated, total - evaluated, failures, summary,
                            time.perf_counter() - started)
