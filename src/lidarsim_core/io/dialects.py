"""Column naming dialects of the PLY and CSV exporters: the standard names, or CloudCompare's.

CloudCompare (checked with Debian's 2.11.3, command-line and GUI) decides what a column is from
its name, then from its values:

- **PLY** (its ``PlyFilter``): a vertex property whose upper-cased name contains ``SCAL`` is a
  scalar field (a ``scalar_`` prefix is removed, and ``_`` shown as a space); one containing
  ``INTENSITY`` is a scalar field too; the first names ending in ``X``, ``Y``, ``Z`` are the
  coordinates; ``NX``/``RED``/... are normals and colours. Every other property (``range``,
  ``part``, ``timestamp``...) is left unassigned, so it is dropped by the command line and
  must be picked by hand in the GUI's open dialog.
- **CSV** (its ``AsciiFilter``): a header is read only from a first line that starts with
  ``//``; a column whose header contains ``SCALAR`` is a scalar field; other columns are
  guessed from their first values: three consecutive integer columns in 0..255 become red,
  green, blue, three columns within ±1 become a normal, and a column headed ``intensity``
  becomes a grey colour (dropped beside red, green, blue). Scalar-field names show ``_`` as a
  space.

The ``cloudcompare`` dialect therefore writes every column but x, y, z as
``scalar_<column>`` (CloudCompare's own naming: it saves a scalar field ``x true`` as
``scalar_x_true``), and the CSV header line starts with ``//``. ``ls.read`` maps both back to
the point-record names. The ``standard`` dialect (the default) keeps the documented names that
Open3D, plyfile, trimesh and pandas users index by.
"""

from __future__ import annotations

from collections.abc import Iterable
from typing import Any, Literal

from pydantic import SerializerFunctionWrapHandler, model_serializer

from ..base.components import ComponentOptions

#: Dialect names accepted by the ``dialect`` option of the PLY and CSV exporters.
Dialect = Literal["standard", "cloudcompare"]
DIALECTS: tuple[str, ...] = ("standard", "cloudcompare")
#: Prefix that makes CloudCompare load a column as a scalar field.
CLOUDCOMPARE_PREFIX = "scalar_"
#: Start of a header line that CloudCompare's ASCII loader reads as column names.
CLOUDCOMPARE_HEADER = "//"
_COORDINATES = ("x", "y", "z")


class DialectOptions(ComponentOptions):
    """Base of the options of an exporter with a ``dialect`` (PLY, CSV; subclasses declare the
    field). The standard dialect is left out of the options' dump, so that a dataset manifest
    written before the option existed keeps its identity (and resumes)."""

    dialect: Dialect = "standard"

    @model_serializer(mode="wrap")
    def _dump(self, handler: SerializerFunctionWrapHandler) -> Any:
        data = handler(self)
        if isinstance(data, dict) and data.get("dialect") == "standard":
            data.pop("dialect")
        return data


def column_name(column: str, dialect: str) -> str:
    """The name ``column`` is written under in ``dialect``."""
    if dialect == "cloudcompare" and column not in _COORDINATES:
        return CLOUDCOMPARE_PREFIX + column
    return column


def record_names(names: list[str], known: Iterable[str]) -> list[str]:
    """The point-record columns of ``names`` read from a file of either dialect:
    ``scalar_<column>`` becomes ``<column>`` when ``<column>`` is one of the ``known`` columns
    and not in the file under its own name; every other name is kept as is."""
    known, present = set(known), set(names)
    out = []
    for name in names:
        bare = name[len(CLOUDCOMPARE_PREFIX):] if name.startswith(CLOUDCOMPARE_PREFIX) else ""
        out.append(bare if bare in known and bare not in present else name)
    return out


def cloudcompare_label(column: str) -> str:
    """The scalar-field name CloudCompare shows for ``column`` read from a ``cloudcompare``
    PLY (its loaders show ``_`` as a space)."""
    return column.replace("_", " ")
