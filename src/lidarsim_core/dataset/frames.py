"""One frame of a dataset: simulate it, stream it to its file, write its sidecar.

:func:`run_frame_job` is what the serial loop calls in process and what Dask workers run. It
keeps a small per-process cache of built simulations keyed by the job's normalised scenario,
so every worker builds each sequence's meshes, and each mesh's acceleration structure (cached
by the ray backend per process), once and reuses them for every frame it is given.
"""

from __future__ import annotations

import hashlib
import os
import threading
from collections import OrderedDict
from dataclasses import dataclass, field
from pathlib import Path
from typing import Any

from ..io.points import DEFAULT_SPOOL_MEMORY, PointSpool
from ..io.write import write_points_file
from ..plugins.resolve import exporter_named

#: Built simulations kept per process (one per sequence being worked on).
CACHE_SIZE = 4

_simulations: "OrderedDict[str, Any]" = OrderedDict()
_stats = {"simulations_built": 0, "frames": 0}
#: Frames whose metadata are computed together, ahead of their simulation: the trajectories
#: are evaluated once per block (:meth:`~lidarsim_core.pipeline.simulation.Simulation.frame_infos`, the
#: same bits as one frame at a time). Each is handed out once, to its frame's job.
INFO_BLOCK = 64
_infos: "OrderedDict[tuple[str, int], tuple[Any, bool]]" = OrderedDict()
_infos_lock = threading.Lock()


@dataclass(frozen=True)
class FrameJob:
    """Everything needed to produce one frame file, picklable for Dask.

    Attributes
    ----------
    sequence
        Sequence name (for reports).
    frame
        Frame index within the sequence.
    path
        Absolute output path (on a cluster: on a file system every worker shares).
    scenario_json
        The normalised scenario as JSON.
    source
        The scenario's original file (relative mesh paths resolve against it), or ``None``.
    exporter
        Exporter name.
    exporter_options
        Exporter options.
    spool_memory
        Bytes of points held in memory before the frame spills to a temporary file.
    """

    sequence: str
    frame: int
    path: str
    scenario_json: str
    source: str | None
    exporter: str
    exporter_options: dict[str, Any] = field(default_factory=dict)
    spool_memory: int = DEFAULT_SPOOL_MEMORY

    @property
    def cache_key(self) -> str:
        """Key of the simulation this job needs."""
        text = f"{self.source}\n{self.scenario_json}"
        return hashlib.sha256(text.encode("utf-8")).hexdigest()


def _simulation(job: FrameJob) -> Any:
    import json

    from ..pipeline.simulation import Simulation
    from ..scenario.load import scenario_from_dict

    key = job.cache_key
    if key in _simulations:
        _simulations.move_to_end(key)
        return _simulations[key]
    scenario = scenario_from_dict(json.loads(job.scenario_json), source=job.source)
    sim = Simulation(scenario)
    _stats["simulations_built"] += 1
    _simulations[key] = sim
    while len(_simulations) > CACHE_SIZE:
        _simulations.popitem(last=False)
    return sim


def _frame_info(job: FrameJob, sim: Any) -> tuple[Any, bool]:
    """``sim.frame_info(job.frame)``, from a block of frames computed ahead when it is there,
    and whether the block found the sensor clear of every target in that frame
    (:func:`~lidarsim_core.pipeline.inside.clear_of_targets`: the frame's own check is then
    skipped; the in-memory frames keep theirs)."""
    from ..pipeline.inside import clear_of_targets  # the pipeline loads with the simulation

    key = (job.cache_key, job.frame)
    with _infos_lock:
        ahead = _infos.pop(key, None)
    if ahead is not None:
        return ahead
    last = max(job.frame + 1, min(sim.scenario.scan.frames, job.frame + INFO_BLOCK))
    block = range(job.frame, last)
    infos = sim.frame_infos(block)
    clear = clear_of_targets(sim.context, block)
    with _infos_lock:
        for later, later_clear in zip(infos[1:], clear[1:]):
            _infos[(job.cache_key, later.frame)] = (later, bool(later_clear))
        while len(_infos) > 4 * INFO_BLOCK:  # frames other workers made, or never asked for
            _infos.popitem(last=False)
    return infos[0], bool(clear[0])


def simulate_frame_job(job: FrameJob) -> tuple[PointSpool, Any]:
    """Simulate ``job.frame`` into a :class:`~lidarsim_core.io.points.PointSpool` (the caller
    closes it, usually through :func:`write_frame_job`); returns it and the frame's info."""
    sim = _simulation(job)
    info, clear = _frame_info(job, sim)
    spool = PointSpool(info, memory_limit=job.spool_memory)
    try:
        spool.extend(sim.iter_chunks(job.frame, outside_checked=clear))
    except BaseException:
        spool.close()
        raise
    return spool, info


def write_frame_job(job: FrameJob, spool: PointSpool, info: Any) -> dict[str, Any]:
    """Write a simulated frame's file and sidecar atomically and close its spool.

    Returns
    -------
    dict
        ``sequence``, ``frame``, ``file`` (name), ``points``, ``rays``, ``bytes``, ``sha256``.
    """
    with spool:
        exporter = exporter_named(job.exporter, job.exporter_options)
        path = Path(job.path)
        path.parent.mkdir(parents=True, exist_ok=True)
        record = write_points_file(spool, path, exporter=exporter)
    _stats["frames"] += 1
    return {"sequence": job.sequence, "frame": job.frame, "file": record["file"],
            "points": record["points"], "rays": info.rays_emitted, "bytes": record["bytes"],
            "sha256": record["sha256"]}


def run_frame_job(job: FrameJob) -> dict[str, Any]:
    """Simulate ``job.frame`` and write its file and sidecar atomically (what a Dask worker
    runs; see :func:`write_frame_job` for the result)."""
    return write_frame_job(job, *simulate_frame_job(job))


def worker_cache_info() -> dict[str, Any]:
    """What this process has built and done (for tests and diagnostics on Dask workers).

    ``prepared_meshes`` counts the acceleration structures held by the backends of the cached
    simulations.
    """
    prepared = set()
    for sim in _simulations.values():
        prepared |= {(type(sim.backend).__name__, key) for key in type(sim.backend)._prepared}
    return {"pid": os.getpid(), "simulations_built": _stats["simulations_built"],
            "simulations_cached": len(_simulations), "frames": _stats["frames"],
            "prepared_meshes": len(prepared)}
