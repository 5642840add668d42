"""Plots (matplotlib, extra ``eval``) and the self-contained HTML report of an evaluation.

PNG files carry no date or software version, so a resumed run writes the same bytes.
"""

from __future__ import annotations

import base64
import html
import io
import json
from pathlib import Path
from typing import Any

import numpy as np

from ..base.atomic import atomic_output, write_text_atomic
from .extras import require
from .metrics import METRICS

PLOTS_DIR = "plots"
#: Plot file names and captions, in report order.
PLOTS: dict[str, str] = {
    "errors_over_time.png": "Errors frame by frame (failed frames marked at the bottom)",
    "errors_vs_range.png": "Errors against the range to the target",
    "errors_vs_points.png": "Errors against the number of points on the target",
    "histograms.png": "Distribution of the errors",
}
_LABELS = {"translation_error_m": "translation error (m)",
           "rotation_error_deg": "rotation error (deg)"}


def _figures(records: dict[str, list[dict[str, Any]]]) -> dict[str, Any]:
    require("matplotlib")
    import matplotlib

    matplotlib.use("Agg", force=False)
    import matplotlib.pyplot as plt
    import matplotlib.ticker

    figures = {}
    metrics = ("translation_error_m", "rotation_error_deg")
    many = len(records) > 8
    fig, axes = plt.subplots(2, 1, figsize=(9, 6), sharex=True, constrained_layout=True)
    for name, rs in records.items():
        frames = np.array([r["frame"] for r in rs])
        ok = np.array([r["status"] == "ok" for r in rs])
        for ax, m in zip(axes, metrics):
            values = np.array([r["metrics"][m] if r["metrics"] else np.nan for r in rs])
            line, = ax.plot(frames, values, ".-", lw=0.8, ms=3, label=None if many else name)
            if (~ok).any():
                ax.plot(frames[~ok], np.zeros((~ok).sum()), "x", color="red", ms=6)
    for ax, m in zip(axes, metrics):
        ax.set_ylabel(_LABELS[m])
        ax.grid(alpha=0.3)
        ax.set_ylim(bottom=0)
    axes[-1].set_xlabel("frame")
    axes[-1].xaxis.set_major_locator(matplotlib.ticker.MaxNLocator(integer=True))
    if not many and records:
        axes[0].legend(fontsize=8, loc="upper right")
    figures["errors_over_time.png"] = fig
    every = [r for rs in records.values() for r in rs if r["status"] == "ok"]
    for key, column, label, log in (("errors_vs_range.png", "range_m", "range to target (m)",
                                     False),
                                    ("errors_vs_points.png", "target_points",
                                     "points on the target", True)):
        fig, axes = plt.subplots(1, 2, figsize=(10, 4), constrained_layout=True)
        x = np.array([r[column] for r in every], dtype=float)
        for ax, m in zip(axes, metrics):
            ax.scatter(x, [r["metrics"][m] for r in every], s=8, alpha=0.7)
            ax.set_xlabel(label)
            ax.set_ylabel(_LABELS[m])
            ax.grid(alpha=0.3)
            if log and len(x) and x.min() > 0:
                ax.set_xscale("log")
        figures[key] = fig
    fig, axes = plt.subplots(1, 2, figsize=(10, 4), constrained_layout=True)
    for ax, m in zip(axes, metrics):
        values = [r["metrics"][m] for r in every]
        ax.hist(values, bins=min(40, max(5, len(values) // 3)) if values else 5)
        ax.set_xlabel(_LABELS[m])
        ax.set_ylabel("frames")
        ax.grid(alpha=0.3)
    figures["histograms.png"] = fig
    return figures


def _png(fig: Any) -> bytes:
    import matplotlib.pyplot as plt

    buffer = io.BytesIO()
    fig.savefig(buffer, format="png", dpi=90, metadata={"Software": None})
    plt.close(fig)
    return buffer.getvalue()


def _fmt(value: Any) -> str:
    if value is None:
        return "–"
    if isinstance(value, float):
        return f"{value:.4g}"
    return html.escape(str(value))


def _percent(value: float | None) -> str:
    return "–" if value is None else f"{value * 100:.4g} %"


def _stats_table(rows: list[tuple[str, dict[str, Any]]], within: list[float]) -> str:
    head = (f"<tr><th></th><th>frames</th><th>estimates</th><th>within {within[0]:g} m and "
            f"{within[1]:g}°</th>" +
            "".join(f"<th>{html.escape(m)}<br>mean / median / p95</th>"
                    for m in (*METRICS, "runtime_s")) + "</tr>")
    body = []
    for label, s in rows:
        cells = [f"<td>{html.escape(label)}</td><td>{s['frames']}</td>",
                 f"<td>{_percent(s['success_rate'])}</td><td>{_percent(s['within_rate'])}</td>"]
        for m in (*METRICS, "runtime_s"):
            st = s[m]
            cells.append(f"<td>{_fmt(st['mean'])} / {_fmt(st['median'])} / {_fmt(st['p95'])}</td>")
        body.append("<tr>" + "".join(cells) + "</tr>")
    return f"<table>{head}{''.join(body)}</table>"


def _scores_table(rows: list[tuple[str, dict[str, Any]]]) -> str:
    head = ("<tr><th></th><th>ADD (m)<br>mean / median</th><th>ADD-S (m)<br>mean / median</th>"
            "<th>ADD(-S) accuracy<br>&lt; 10 % of d</th><th>MSSD (m)<br>mean / median</th>"
            "<th>AR<sub>MSSD</sub></th><th>SPEED+ score</th></tr>")
    body = []
    for label, s in rows:
        scores = s.get("scores", {})
        cells = [f"<td>{html.escape(label)}</td>"]
        for m in ("add_m", "adds_m"):
            cells.append(f"<td>{_fmt(s[m]['mean'])} / {_fmt(s[m]['median'])}</td>")
        cells.append(f"<td>{_percent(scores.get('add_s_accuracy'))}</td>")
        cells.append(f"<td>{_fmt(s['mssd_m']['mean'])} / {_fmt(s['mssd_m']['median'])}</td>")
        cells.append(f"<td>{_fmt(scores.get('ar_mssd'))}</td>"
                     f"<td>{_fmt(scores.get('speedplus_score'))}</td>")
        body.append("<tr>" + "".join(cells) + "</tr>")
    return f"<table>{head}{''.join(body)}</table>"


_CSS = """body{font-family:system-ui,sans-serif;margin:2em;max-width:1200px;color:#222}
table{border-collapse:collapse;margin:0.5em 0 1.5em;font-size:0.9em}
td,th{border:1px solid #ccc;padding:3px 8px;text-align:right}th{background:#eef}
td:first-child{text-align:left}.warn{background:#fff4d6;padding:0.6em;border:1px solid #e0c060}
img{max-width:100%;border:1px solid #ddd;margin:0.3em 0}code{background:#f4f4f4}"""


def _html(config: dict[str, Any], records: dict[str, list[dict[str, Any]]],
          summary: dict[str, Any], images: dict[str, bytes]) -> str:
    every = [r for rs in records.values() for r in rs]
    parts = [f"<!DOCTYPE html><html><head><meta charset='utf-8'><title>lidarsim evaluate: "
             f"{html.escape(config['estimator'])}</title><style>{_CSS}</style></head><body>",
             f"<h1>Pose-estimator evaluation: <code>{html.escape(config['estimator'])}</code></h1>"]
    if config["uses_truth"]:
        parts.append("<p class='warn'>This estimator reads the ground truth (to start, or to "
                     "check the harness): its scores are not those of an estimator on its own."
                     "</p>")
    setup = {"provider": config["estimator_provider"],
             "options": json.dumps(config["options"], sort_keys=True),
             "split": config["split"] or "all sequences", "target": config["target"] or
             "first target of each sequence", "points given": "the target's only (oracle "
             "segmentation)" if config["segment"] else "every detected point",
             "symmetries": ", ".join(json.dumps(s) for s in config["symmetries"]) or "none",
             "dataset manifest SHA-256": config["dataset_manifest_sha256"],
             "lidarsim": config["lidarsim"]}
    parts.append("<table>" + "".join(f"<tr><td>{html.escape(k)}</td><td style='text-align:"
                                     f"left'>{_fmt(v)}</td></tr>" for k, v in setup.items())
                 + "</table>")
    within = config["within_m_deg"]
    parts.append("<h2>Summary</h2>" + _stats_table([("all frames", summary["overall"])], within))
    t = summary["score_thresholds"]
    diameters = sorted({s["target_diameter_m"] for s in summary["sequences"].values()
                        if s.get("target_diameter_m") is not None})
    parts.append("<h2>Scores of the literature</h2>" + _scores_table(
        [("all frames", summary["overall"]), *summary["sequences"].items()]) +
        "<p>On the target mesh's vertices (diameter d = "
        f"{', '.join(f'{d:.4g}' for d in diameters) or '–'} m): ADD (Hinterstoisser et al. "
        "2012), ADD-S (Hodaň et al. 2016; it decides the accuracy when symmetries are "
        f"declared) and the share of frames with ADD(-S) &lt; {t['add_s_fraction_of_diameter']:g}"
        " d (frames without an estimate count as misses); MSSD and its average recall over "
        "τ = 0.05-0.5 d (BOP); SPEED+ score: e_t zeroed below "
        f"{t['speedplus_position']:g} (2.173 mm per metre), e_q below "
        f"{t['speedplus_orientation_deg']:g}°, mean over the frames with an estimate.</p>")
    parts.append("<h2>Per sequence</h2>" + _stats_table(list(summary["sequences"].items()),
                                                        within))
    parts.append("<h2>Per range bin</h2>" + _stats_table(
        [(b["label"], b) for b in summary["range_bins"]], within))
    for name, caption in PLOTS.items():
        data = base64.b64encode(images[name]).decode("ascii")
        parts.append(f"<h3>{html.escape(caption)}</h3><img alt='{html.escape(caption)}' "
                     f"src='data:image/png;base64,{data}'>")
    worst = sorted((r for r in every if r["status"] == "ok"),
                   key=lambda r: -r["metrics"]["speed_score"])[:10]
    parts.append("<h2>Worst frames (SPEED score)</h2><table><tr><th>sequence</th><th>frame</th>"
                 "<th>range (m)</th><th>points</th><th>translation error (m)</th>"
                 "<th>rotation error (deg)</th><th>score</th></tr>" + "".join(
                     f"<tr><td>{html.escape(r['sequence'])}</td><td>{r['frame']}</td>"
                     f"<td>{_fmt(r['range_m'])}</td><td>{r['target_points']}</td>"
                     f"<td>{_fmt(r['metrics']['translation_error_m'])}</td>"
                     f"<td>{_fmt(r['metrics']['rotation_error_deg'])}</td>"
                     f"<td>{_fmt(r['metrics']['speed_score'])}</td></tr>" for r in worst)
                 + "</table>")
    failed = [r for r in every if r["status"] != "ok"]
    parts.append(f"<h2>Frames without a valid estimate ({len(failed)})</h2>")
    if failed:
        parts.append("<table><tr><th>sequence</th><th>frame</th><th>status</th><th>message</th>"
                     "</tr>" + "".join(
                         f"<tr><td>{html.escape(r['sequence'])}</td><td>{r['frame']}</td>"
                         f"<td>{r['status']}</td><td style='text-align:left'>"
                         f"{html.escape(r['estimate'].get('message', ''))}</td></tr>"
                         for r in failed[:200]) + "</table>")
    parts.append("<p>Metrics: translation error ‖t_est − t_gt‖; rotation error, the angle of "
                 "R_gtᵀ R_est; SPEED terms e_t = ‖t_est − t_gt‖ / ‖t_gt‖ and e_q = "
                 "2·arccos|⟨q_est, q_gt⟩| (rad), score e_t + e_q. Files: metrics.csv, "
                 "estimates.json, summary.json, plots/.</p></body></html>\n")
    return "\n".join(parts)


def write_report(out: Path, config: dict[str, Any], records: dict[str, list[dict[str, Any]]],
                 summary: dict[str, Any]) -> None:
    """Write ``plots/*.png`` and ``report.html`` (the plots embedded)."""
    images = {name: _png(fig) for name, fig in _figures(records).items()}
    (out / PLOTS_DIR).mkdir(exist_ok=True)
    for name, data in images.items():
        with atomic_output(out / PLOTS_DIR / name) as stream:
            stream.write(data)
    write_text_atomic(out / "report.html", _html(config, records, summary, images))
