"""``lidarsim dataset --format mcap``: one ROS 2 bag per sequence instead of one file per frame.

Each sequence's frames go into ``<sequence root>/bag.mcap``, written by
:func:`lidarsim_core.io.rosbag.write_bag` (the bag of ``lidarsim simulate --out run.mcap``,
same topics), atomically: the bag is assembled under a hidden ``.part`` name and renamed when
complete. A sidecar ``bag.mcap.json`` (a ``lidarsim-frame`` record, so
:func:`~lidarsim_core.io.sidecar.frame_is_complete` checks it) then records its size, SHA-256,
frame count and points per frame. A sequence whose bag and sidecar are complete is skipped on
resume; any other is written again from its first frame.
"""

from __future__ import annotations

from dataclasses import dataclass
from pathlib import Path
from typing import TYPE_CHECKING, Any, Callable, Iterable

import numpy as np

from ..base.errors import ConfigError, UserInputError

if TYPE_CHECKING:
    from ..pipeline.simulation import Simulation
    from ..scenario.model import Scenario

#: ``--format`` value that selects bags.
BAG_FORMAT = "mcap"
#: File name of a sequence's bag, relative to the sequence root.
BAG_NAME = "bag.mcap"


@dataclass(frozen=True)
class BagFormat:
    """The ``mcap`` dataset format (stands where a per-frame exporter stands in the dataset's
    identity).

    Attributes
    ----------
    livox
        Also write ``livox_ros_driver2/msg/CustomMsg`` on ``/livox/lidar``.
    """

    livox: bool = False
    name: str = BAG_FORMAT
    suffixes: tuple[str, ...] = (".mcap",)
    requires: tuple[str, ...] = ("rosbags",)

    @classmethod
    def from_options(cls, options: dict[str, Any], *, source: Any = None) -> "BagFormat":
        """Check ``options`` (only ``livox``, a boolean) and that rosbags is installed."""
        from ..io.rosbag import require_rosbags

        unknown = sorted(set(options) - {"livox"})
        if unknown:
            raise ConfigError(f"unknown option '{unknown[0]}' for format mcap (it takes "
                              "'livox')", source=source, field="exporter_options")
        livox = options.get("livox", False)
        if not isinstance(livox, bool):
            raise ConfigError("option 'livox' of format mcap must be true or false",
                              source=source, field="exporter_options.livox")
        require_rosbags()  # missing extra 'ros': say so before anything is created
        return cls(livox=livox)

    def identity(self) -> dict[str, Any]:
        """The exporter entry of the dataset identity."""
        return {"name": self.name, "options": {"livox": self.livox}, "suffix": self.suffixes[0],
                "provider": "lidarsim-core"}


def check_bag_sequences(scenarios: Iterable["Scenario"]) -> None:
    """Refuse, before anything is created, sequences a bag cannot hold: a target name that is
    not a ROS topic / TF frame name (or is ``scene`` / ``sensor``), or frames longer than
    PointCloud2's uint32 ns per-point time field (4.29 s)."""
    from ..io.rosbag import check_target_names

    limit_s = np.iinfo(np.uint32).max * 1e-9
    for scenario in scenarios:
        try:
            check_target_names([target.name for target in scenario.targets])
        except UserInputError as exc:
            raise ConfigError(exc.message, source=scenario.source, field=exc.field) from None
        if scenario.scan.duration_s > limit_s:
            raise ConfigError(f"a frame of {scenario.scan.duration_s:g} s does not fit "
                              f"PointCloud2's uint32 ns point time field (at most "
                              f"{limit_s:.2f} s) with --format mcap", source=scenario.source,
                              field="scan.duration_s")


def write_sequence_bag(sim: "Simulation", frames: int, path: Path, *, livox: bool,
                       on_frame: Callable[[int], None] | None = None) -> dict[str, Any]:
    """Write frames ``0..frames-1`` of ``sim`` into the bag ``path``, then its sidecar.

    Parameters
    ----------
    sim
        The sequence's simulation.
    frames
        Number of frames.
    path
        The bag (replaced if an incomplete one is there).
    livox
        Also write the Livox CustomMsg topic.
    on_frame
        Called with the point count of each frame once it is written (progress).

    Returns
    -------
    dict
        The sidecar record: ``file``, ``bytes``, ``sha256``, ``frames``, ``points`` (total) and
        ``points_per_frame``.
    """
    from ..io.rosbag import write_bag
    from ..io.sidecar import SIDECAR_FORMAT, SIDECAR_VERSION, sha256_file, write_sidecar

    counts: list[int] = []

    def frame_done(_frame: int, cloud: Any) -> None:
        counts.append(len(cloud))
        if on_frame is not None:
            on_frame(len(cloud))

    write_bag((sim.run_frame(f) for f in range(frames)), path,
              target_names=[t.name for t in sim.targets], overwrite=True, livox=livox,
              on_frame=frame_done)
    record = {"format": SIDECAR_FORMAT, "version": SIDECAR_VERSION, "file": path.name,
              "exporter": BAG_FORMAT, "livox": livox, "frames": frames,
              "points": sum(counts), "points_per_frame": counts,
              "bytes": path.stat().st_size, "sha256": sha256_file(path)}
    write_sidecar(path, record)
    return record
