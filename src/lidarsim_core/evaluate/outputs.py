"""The files of an evaluation, built from the per-frame records alone (so a resumed run ends
with the same bytes): ``estimates.json``, ``metrics.csv``, ``summary.json``, plots and
``report.html``.
"""

from __future__ import annotations

import csv
import io
import json
import math
from pathlib import Path
from typing import Any

import numpy as np

from ..base.atomic import write_text_atomic
from ..records.groundtruth import CONVENTION
from .metrics import METRICS
from .scores import (ADD_FRACTION, MSSD_FRACTIONS, SCORES, SPEEDPLUS_ORIENTATION_THRESHOLD_DEG,
                     SPEEDPLUS_POSITION_THRESHOLD)

ESTIMATES_FORMAT = "lidarsim-estimates"
SUMMARY_FORMAT = "lidarsim-evaluation-summary"
#: metrics.csv columns, in order.
CSV_COLUMNS: tuple[str, ...] = ("sequence", "frame", "time_s", "range_m", "points",
                                "target_points", *METRICS, *SCORES, "runtime_s", "success",
                                "status",
                                "message")
#: Statistics of the summary.
STATS: tuple[str, ...] = ("mean", "median", "p95")


def _finite(value: Any) -> Any:
    """JSON-safe: non-finite floats become ``None``."""
    if isinstance(value, float) and not math.isfinite(value):
        return None
    if isinstance(value, dict):
        return {k: _finite(v) for k, v in value.items()}
    if isinstance(value, list):
        return [_finite(v) for v in value]
    return value


def _stats(values: list[float]) -> dict[str, float | None]:
    data = np.asarray([v for v in values if v is not None and math.isfinite(v)], dtype=float)
    if not len(data):
        return {s: None for s in STATS}
    return {"mean": float(data.mean()), "median": float(np.median(data)),
            "p95": float(np.percentile(data, 95))}


def group_summary(records: list[dict[str, Any]], within: tuple[float, float]) -> dict[str, Any]:
    """Frames, successes and their rate, the rate of frames within ``within`` (m, deg), and
    mean/median/p95 of every metric (over the frames with a valid estimate) and of the runtime
    (over every frame)."""
    ok = [r for r in records if r["status"] == "ok"]
    good = [r for r in ok if r["metrics"]["translation_error_m"] <= within[0] and
            r["metrics"]["rotation_error_deg"] <= within[1]]
    out: dict[str, Any] = {"frames": len(records), "successes": len(ok),
                           "success_rate": len(ok) / len(records) if records else None,
                           "within_rate": len(good) / len(records) if records else None}
    out.update({m: _stats([r["metrics"][m] for r in ok]) for m in METRICS})
    out.update({m: _stats([r["metrics"].get(m) for r in ok]) for m in SCORES})
    out["runtime_s"] = _stats([r["runtime_s"] for r in records])
    out["scores"] = literature_scores(records)
    return out


def literature_scores(records: list[dict[str, Any]]) -> dict[str, float | None]:
    """The scores papers report, over a group of frames: BOP's ADD(-S) accuracy and AR_MSSD
    (a frame without an estimate counts as a miss) and the SPEED+ score (the mean over the
    frames with an estimate)."""
    ok = [r["metrics"] for r in records if r["status"] == "ok" and r["metrics"] and
          "add_s_correct" in r["metrics"]]
    n = len(records)
    return {"add_s_accuracy": sum(m["add_s_correct"] for m in ok) / n if n else None,
            "ar_mssd": sum(m["mssd_recall"] for m in ok) / n if n else None,
            "speedplus_score": (sum(m["speedplus_score"] for m in ok) / len(ok)
                                if ok else None)}


#: The thresholds of the scores, recorded in summary.json.
SCORE_THRESHOLDS: dict[str, Any] = {
    "add_s_fraction_of_diameter": ADD_FRACTION,
    "mssd_fractions_of_diameter": list(MSSD_FRACTIONS),
    "speedplus_position": SPEEDPLUS_POSITION_THRESHOLD,
    "speedplus_orientation_deg": SPEEDPLUS_ORIENTATION_THRESHOLD_DEG}


def range_bin_label(low: float, high: float) -> str:
    """``"20-50 m"`` or ``"≥ 500 m"``."""
    return f"≥ {low:g} m" if math.isinf(high) else f"{low:g}-{high:g} m"


def summarise(config: dict[str, Any], records: dict[str, list[dict[str, Any]]],
              bins: list[float]) -> dict[str, Any]:
    """The content of ``summary.json``."""
    every = [r for rs in records.values() for r in rs]
    within = tuple(config["within_m_deg"])
    edges = list(bins) + [math.inf]
    by_range = []
    for low, high in zip(edges, edges[1:]):
        inside = [r for r in every if low <= r["range_m"] < high]
        if inside:
            by_range.append({"range_m": [low, None if math.isinf(high) else high],
                             "label": range_bin_label(low, high), **group_summary(inside, within)})
    return {"format": SUMMARY_FORMAT, "version": 1, "estimator": config["estimator"],
            "estimator_provider": config["estimator_provider"],
            "uses_truth": config["uses_truth"], "options": config["options"],
            "split": config["split"], "symmetries": config["symmetries"],
            "within_m_deg": config["within_m_deg"], "score_thresholds": SCORE_THRESHOLDS,
            "overall": group_summary(every, within),
            "sequences": {name: {**group_summary(rs, within),
                                 "target_diameter_m": rs[0].get("target_diameter_m") if rs
                                 else None} for name, rs in records.items()},
            "range_bins": by_range}


def _estimates(config: dict[str, Any], records: dict[str, list[dict[str, Any]]]) -> str:
    head = {"format": ESTIMATES_FORMAT, "version": 1, "convention": CONVENTION,
            "estimator": config["estimator"], "options": config["options"]}
    text = json.dumps(head, indent=1, sort_keys=True)[:-2] + ',\n "sequences": ['
    for i, (name, rs) in enumerate(records.items()):
        text += ("\n" if i == 0 else ",\n") + f'  {{"name": {json.dumps(name)}, "frames": ['
        for j, r in enumerate(rs):
            entry = {"frame": r["frame"], "status": r["status"], "reference_time_s": r["time_s"],
                     **r["estimate"]}
            text += ("\n" if j == 0 else ",\n") + "   " + json.dumps(_finite(entry),
                                                                     sort_keys=True)
        text += "\n  ]}"
    return text + "\n ]\n}\n"


def _cell(value: Any) -> str:
    if value is None:
        return ""
    if isinstance(value, bool):
        return "true" if value else "false"
    if isinstance(value, float):
        return repr(value) if math.isfinite(value) else ""
    return str(value)


def _metrics_csv(records: dict[str, list[dict[str, Any]]]) -> str:
    buffer = io.StringIO(newline="")
    writer = csv.writer(buffer, lineterminator="\n")
    writer.writerow(CSV_COLUMNS)
    for rs in records.values():
        for r in rs:
            metrics = r["metrics"] or {}
            row = [r["sequence"], r["frame"], r["time_s"], r["range_m"], r["points"],
                   r["target_points"], *[metrics.get(m) for m in (*METRICS, *SCORES)],
                   r["runtime_s"],
                   r["status"] == "ok", r["status"], r["estimate"].get("message", "")]
            writer.writerow([_cell(v) for v in row])
    return buffer.getvalue()


def write_outputs(out: Path, config: dict[str, Any], records: dict[str, list[dict[str, Any]]],
                  bins: list[float]) -> dict[str, Any]:
    """Write every output file; returns the summary."""
    from .report import write_report

    summary = summarise(config, records, bins)
    write_text_atomic(out / "estimates.json", _estimates(config, records))
    write_text_atomic(out / "metrics.csv", _metrics_csv(records))
    write_text_atomic(out / "summary.json",
                      json.dumps(_finite(summary), indent=1, sort_keys=True, allow_nan=False)
                      + "\n")
    write_report(out, config, records, summary)
    return summary
