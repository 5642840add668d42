"""The report page: one self-contained HTML file (figures embedded as base64 PNG, inline CSS)."""

from __future__ import annotations

import base64
import html
from pathlib import Path
from typing import TYPE_CHECKING, Any

from ..base.atomic import write_text_atomic

if TYPE_CHECKING:
    from .result import Report

_CSS = """
body{font-family:system-ui,-apple-system,Segoe UI,Roboto,sans-serif;max-width:1200px;
margin:2em auto;padding:0 1em;color:#222;line-height:1.45}
h1{font-size:1.6em;margin-bottom:.2em}
h2{font-size:1.25em;margin-top:2em;border-bottom:1px solid #ddd}
table{border-collapse:collapse;margin:.5em 0}td,th{padding:.25em .8em;border-bottom:1px solid #eee;
text-align:left}th{background:#f5f5f5}td.num{text-align:right;font-variant-numeric:tabular-nums}
figure{margin:1.5em 0}figure img{max-width:100%;border:1px solid #ddd}
figcaption{font-size:.92em;color:#444;margin-top:.4em}code,pre{background:#f6f8fa;border-radius:4px}
pre{padding:.7em 1em;overflow-x:auto}.note{background:#fff8e1;border-left:4px solid #f0b400;
padding:.5em 1em;margin:1em 0}
"""


def _rows(pairs: list[tuple[str, Any]]) -> str:
    out = []
    for key, value in pairs:
        cls = ' class="num"' if isinstance(value, (int, float)) else ""
        text = f"{value:,}" if isinstance(value, int) else str(value)
        out.append(f"<tr><th>{html.escape(key)}</th><td{cls}>{html.escape(text)}</td></tr>")
    return "\n".join(out)


def _image(path: Path) -> str:
    data = base64.b64encode(path.read_bytes()).decode("ascii")
    return f'<img alt="{html.escape(path.name)}" src="data:image/png;base64,{data}">'


def render_html(report: "Report") -> str:
    """The report page as a string (see :func:`write_html`)."""
    s = report.summary
    overview = [
        ("sensor", f"{s['sensor']} ({s['sensor_model']})"),
        ("scan pattern", s["pattern"]),
        ("frame", f"{s['frame']}: {s['t_start_s']:g}–{s['t_end_s']:g} s"),
        ("rays emitted", s["rays_emitted"]),
        ("points with errors", s["points_with_errors"]),
        ("points without errors", s["points_without_errors"]),
        ("hit fraction", f"{100 * s['hit_fraction']:.1f} %"),
        ("range of points", f"{s['range_min_m']:.2f}–{s['range_max_m']:.2f} m"
         if s.get("range_min_m") is not None else "-"),
        ("backend / seed", f"{s['backend']} / {s['seed']}"),
        ("noise chain", ", ".join(s["noise"]) or "none"),
        ("configuration hash", s["config_hash"]),
    ]
    errors = []
    if s.get("angular_sigma_deg") is not None:
        errors.append(("angular error σ (fitted / datasheet)",
                       f"{s['angular_sigma_deg']:.4f}° / {s['angular_sigma_datasheet_deg']:g}°"))
    if s.get("range_sigma_mm") is not None:
        errors.append(("range error σ (fitted / datasheet)",
                       f"{s['range_sigma_mm']:.2f} mm / {s['range_sigma_datasheet_mm']:g} mm"))
    if s.get("coverage") is not None:
        errors.append((f"FOV coverage in {s['coverage_time_s']:g} s "
                       f"({s['coverage_cell_deg']:g}° cells)", f"{100 * s['coverage']:.1f} %"))
    parts = sorted(s.get("points_per_part", {}).items(), key=lambda kv: -kv[1])
    figures = "\n".join(
        f'<figure id="{html.escape(f.key)}"><h2>{html.escape(f.title)}</h2>{_image(f.path)}'
        f"<figcaption>{html.escape(f.caption)}</figcaption></figure>"
        for f in report.figures)
    notes = "".join(f'<p class="note">{html.escape(n)}</p>' for n in report.notes)
    return f"""<!DOCTYPE html>
<html lang="en"><head><meta charset="utf-8">
<meta name="viewport" content="width=device-width, initial-scale=1">
<title>lidarsim report: {html.escape(s['sensor'])}, {html.escape(s['targets'])}</title>
<style>{_CSS}</style></head><body>
<h1>lidarsim report: {html.escape(s['sensor'])} scanning {html.escape(s['targets'])}</h1>
<p>Run <code>{html.escape(str(report.run_dir))}</code>, written by {html.escape(s['software'])}.
The figures follow the seed paper's (Figs. 5, 6, 7, 9, 11 and 12).</p>
{notes}
<h2>Run</h2><table>{_rows(overview)}</table>
<h2>Injected errors and coverage</h2><table>{_rows(errors)}</table>
<h2>Points per part</h2><table>{_rows(parts)}</table>
{figures}
<h2>Regenerate</h2>
<pre>{html.escape(report.command)}</pre>
</body></html>
"""


def write_html(report: "Report", path: str | Path) -> Path:
    """Write the self-contained report page to ``path`` (atomic)."""
    return write_text_atomic(path, render_html(report))
