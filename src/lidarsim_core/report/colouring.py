"""What the points of a cloud figure are coloured by: a part palette and per-point values."""

from __future__ import annotations

from dataclasses import dataclass

import numpy as np

from ..base.errors import ConfigError
from ..records.pointcloud import PointCloud

#: Names accepted by ``--color-by`` besides any numeric column of the point record.
COLOUR_ALIASES = {"part": "part", "range": "range", "time": "timestamp", "intensity": "intensity"}

#: Categorical colours of parts (Okabe-Ito-like, distinguishable, then repeated darker).
PART_PALETTE = ("#0072b2", "#e69f00", "#009e73", "#cc79a7", "#d55e00", "#56b4e9", "#8c564b",
                "#7f3c8d", "#11a579", "#3969ac", "#4d4d4d", "#e73f74", "#80ba5a", "#e68310")


def part_colour(index: int) -> str:
    """The colour of part ``index`` (cycling through :data:`PART_PALETTE`)."""
    return PART_PALETTE[index % len(PART_PALETTE)]


@dataclass(frozen=True)
class PointColours:
    """Per-point values to colour by.

    Attributes
    ----------
    values
        (N,) float values (part index for ``categorical``).
    label
        Legend / colour-bar title with the unit.
    categorical
        True for part labels (a legend of names instead of a colour bar).
    names
        For categorical values: the name of each category index.
    """

    values: np.ndarray
    label: str
    categorical: bool = False
    names: tuple[str, ...] = ()


def colour_choices(cloud: PointCloud) -> list[str]:
    """The ``--color-by`` names usable with ``cloud``."""
    usable = [k for k, col in COLOUR_ALIASES.items() if col in cloud.columns]
    return usable + sorted(k for k, v in cloud.columns.items()
                           if k not in usable and k not in COLOUR_ALIASES.values()
                           and np.asarray(v).dtype.kind in "fiu")


def point_colours(cloud: PointCloud, colour_by: str) -> PointColours:
    """The values of ``colour_by`` for every point of ``cloud``.

    ``colour_by`` is ``part``, ``range`` (m), ``time`` (ms from frame start), ``intensity``
    (when the cloud has that column) or any other numeric column name.

    Raises
    ------
    ConfigError
        Naming ``--color-by`` and listing the usable names when ``colour_by`` is unknown.
    """
    column = COLOUR_ALIASES.get(colour_by, colour_by)
    if column not in cloud.columns or np.asarray(cloud.columns[column]).dtype.kind not in "fiu":
        raise ConfigError(f"cannot colour by {colour_by!r}; choose one of "
                          f"{', '.join(colour_choices(cloud))}", field="--color-by")
    values = np.asarray(cloud[column], dtype=np.float64)
    if column == "part":
        return PointColours(values, "part", True, tuple(short_part_names(cloud.frame.part_names)))
    if column == "timestamp":
        return PointColours(1e3 * (values - cloud.frame.t_start), "time from frame start (ms)")
    if column in ("range", "range_true"):
        return PointColours(values, f"{column} (m)")
    if column in ("incidence_angle", "azimuth", "elevation"):
        return PointColours(np.degrees(values), f"{column} (deg)")
    return PointColours(values, column)


def short_part_names(names: list[str] | tuple[str, ...]) -> list[str]:
    """Part names without the ``target/`` prefix when every part belongs to one target."""
    prefixes = {n.split("/", 1)[0] for n in names if "/" in n}
    if len(prefixes) == 1 and all("/" in n for n in names):
        return [n.split("/", 1)[1] for n in names]
    return list(names)
