"""Built-in plugin: CSV text, one row per point, every column, exact values.

A header row names the columns (point-record order); floating-point values are written in
Python's shortest round-trip form (``repr``), so parsing them gives back the same float64 bits;
integers as integers. Plain RFC 4180 CSV with ``\\n`` line ends and no comment lines, so any
reader (pandas, numpy, spreadsheets) takes it; the frame metadata therefore lives only in the
sidecar JSON.

Option ``dialect: cloudcompare`` (CLI ``--dialect cloudcompare``) writes the header line as
``//x,y,z,scalar_x_true,...``: CloudCompare's ASCII loader reads column names only from a
first line starting with ``//``, and loads a column as a scalar field only when its name
contains ``scalar`` (otherwise it guesses from the values: small integers become colours,
values within ±1 normals; :mod:`lidarsim_core.io.dialects`). ``ls.read`` takes both headers.

Text is ~3x larger and much slower to write than the binary formats: use it for small clouds
and inspection.
"""

from __future__ import annotations

from typing import IO, TYPE_CHECKING, Any

import numpy as np

from pydantic import Field

from ..hookspecs import hookimpl
from .base import Exporter
from .dialects import CLOUDCOMPARE_HEADER, Dialect, DialectOptions, column_name

if TYPE_CHECKING:
    from .points import PointSource

_CHUNK_POINTS = 16384


def _texts(values: np.ndarray) -> list[str]:
    if values.dtype.kind == "f":
        return [repr(v) for v in values.tolist()]
    return [str(v) for v in values.tolist()]


class CsvOptions(DialectOptions):
    """Options of the CSV exporter."""

    dialect: Dialect = Field(
        "standard", description="Header row: 'standard' (the point-record names, for pandas "
                                "and spreadsheets) or 'cloudcompare' (//x,y,z,scalar_x_true,"
                                "...: every column a named scalar field in CloudCompare).")


class CsvExporter(Exporter):
    """CSV with a header row, every column, floats in shortest exact form (metadata: sidecar)."""

    name = "csv"
    suffixes = (".csv",)
    memory_stream = True
    Options = CsvOptions
    options: CsvOptions

    def write_points(self, points: "PointSource", stream: IO[bytes]) -> None:
        names = list(points.fields)
        header = ",".join(column_name(name, self.options.dialect) for name in names)
        if self.options.dialect == "cloudcompare":
            header = CLOUDCOMPARE_HEADER + header
        stream.write((header + "\n").encode("ascii"))
        for chunk in points.iter_chunks(names, size=_CHUNK_POINTS):
            columns = [_texts(chunk[name]) for name in names]
            rows = "\n".join(",".join(row) for row in zip(*columns))
            stream.write((rows + "\n").encode("ascii"))


@hookimpl
def lidarsim_register_exporters(register: Any) -> None:
    """Register the CSV exporter."""
    register(CsvExporter)
