"""Report figures of a run, after the seed paper's: the scan pattern on a plane (Fig. 5), the
injected angular and range errors (Figs. 6, 9), the scene set-up (Fig. 7), the cloud without and
with errors (Fig. 11), model and cloud (Fig. 12) and the FOV coverage map; PNGs plus one
self-contained HTML page.

Needs the ``viz`` extra (matplotlib for the 2-D figures, pyvista/VTK rendering off-screen for the
3-D ones); both are imported only when a figure is drawn.

Examples
--------
>>> from lidarsim_core.report import write_report
>>> report = write_report("demo-out", "demo-out/report")      # doctest: +SKIP
>>> report.html                                                # doctest: +SKIP
PosixPath('demo-out/report/report.html')
"""

from __future__ import annotations

from .builder import (
                      FIGURE_FILES,
                      Figure,
                      Report,
                      VizMissing,
                      build_report,
                      require_viz,
                      write_report,
)
from .run import Run, load_run

__all__ = ["FIGURE_FILES", "Figure", "Report", "Run", "VizMissing", "build_report", "load_run",
           "require_viz", "write_report"]
