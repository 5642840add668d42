"""What a report produced: its figures (file, caption, what the paper's figure shows) and the
statistics and files of the run, for ``report.json`` and the HTML page."""

from __future__ import annotations

from dataclasses import dataclass, field
from pathlib import Path
from typing import Any

#: File names of the figures, by key.
FIGURE_FILES = {
    "pattern": "fig05_pattern.png",
    "angular_error": "fig06_angular_error.png",
    "scene": "fig07_scene.png",
    "range_error": "fig09_range_error.png",
    "errors": "fig11_without_with_errors.png",
    "cloud": "fig12_cloud_by_{colour_by}.png",
    "coverage": "coverage.png",
}




@dataclass
class Figure:
    """One figure of a report.

    Attributes
    ----------
    key
        Which figure (a key of :data:`FIGURE_FILES`).
    path
        The PNG written.
    title, caption
        Heading and explanation on the report page.
    """

    key: str
    path: Path
    title: str
    caption: str


@dataclass
class Report:
    """What :func:`write_report` wrote.

    Attributes
    ----------
    run_dir, out_dir
        The run read and the directory written.
    html, json
        The report page and its numbers.
    figures
        The figures, in page order.
    summary
        The numbers on the page (also in ``report.json``).
    notes
        Remarks on what could not be drawn or had to be simulated.
    command
        The command that regenerates the report.
    """

    run_dir: Path
    out_dir: Path
    figures: list[Figure] = field(default_factory=list)
    summary: dict[str, Any] = field(default_factory=dict)
    notes: list[str] = field(default_factory=list)
    command: str = ""
    html: Path | None = None
    json: Path | None = None

    def files(self) -> list[Path]:
        """Every file this report wrote: the figures, ``report.json`` and ``report.html``."""
        return [f.path for f in self.figures] + [p for p in (self.json, self.html)
                                                  if p is not None]


#: Figures drawn with pyvista (skipped by ``three_d=False``).
