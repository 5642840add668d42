"""``lidarsim simulate SCENARIO --out run.mcap``: every frame into one ROS 2 bag.

Called from ``simulate`` when the output is a ``.mcap`` file (or ``--format mcap``); the bag
itself is written by :func:`lidarsim_core.io.rosbag.write_bag`.
"""

from __future__ import annotations

from pathlib import Path
from typing import TYPE_CHECKING, Sequence

if TYPE_CHECKING:
    from ..scenario.model import Scenario


def simulate_to_bag(scenario: "Scenario", frames: Sequence[int], out: Path, *,
                    overwrite: bool, livox: bool, range_image: bool = False,
                    source: Path | None = None) -> None:
    """Simulate ``frames`` into the bag ``out`` with a progress bar, then say what was
    written."""
    from .output import markup_safe as escape

    from ..base.errors import OutputError

    if range_image:
        raise OutputError("--range-image writes beside per-frame cloud files, not into a bag",
                          source=out)
    from ..dataset.progress import FrameProgress
    from ..io.rosbag import check_bag_output, require_rosbags, write_bag
    from ..pipeline.simulation import Simulation
    from .progress import FrameBar, prepare_long_run

    require_rosbags()  # missing extra 'ros': say so before simulating
    check_bag_output(out, overwrite=overwrite)
    sim = Simulation(scenario)
    prepare_long_run()  # a bar while a first run on this machine compiles the kernels
    from ..base.outputs import check_not_input
    from ..io.rosbag import check_bag_frames

    check_not_input(out)  # the scenario, its meshes and keyframes are never replaced
    check_bag_frames([sim.frame_info(f) for f in frames], source=source)  # times and sizes, before any work
    with FrameProgress(len(frames), display=FrameBar()) as progress:
        write_bag((sim.run_frame(f) for f in frames), out,
                  target_names=[t.name for t in sim.targets], overwrite=overwrite, livox=livox,
                  on_frame=lambda _f, cloud: progress.frame_done(len(cloud)))
    topics = "/lidarsim/points, /tf, /lidarsim/ground_truth/<target>" + (
        ", /livox/lidar" if livox else "")
    from .output import console

    console().print(  # one line, never broken by the program (cli.output)
        f"wrote {len(frames)} frame(s), {progress.points:,} points in "
        f"{progress.elapsed:.2f} s → {escape(str(out))} (ROS 2 bag, MCAP; topics {topics})")
