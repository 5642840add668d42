"""One frame of a dataset: simulate it, stream it to its file, write its sidecar.

:func:`run_frame_job` is what the serial loop calls in process and what Dask workers run. It
keeps a small per-process cache of built simulations keyed by the job's normalised scenario,
so every worker builds each sequence's meshes, and each mesh's acceleration structure (cached
by the ray backend per process), once and reuses them for every frame it is given.
"""

from __future__ import annotations

import hashlib
import os
from collections import OrderedDict
from dataclasses import dataclass, field
from functools import lru_cache
from pathlib import Path
from typing import Any

from ..io.points import DEFAULT_SPOOL_MEMORY, PointSpool
from ..io.write import write_points_file
from ..plugins.resolve import exporter_named

#: Built simulations kept per process (one per sequence being worked on).
CACHE_SIZE = 4

_simulations: "OrderedDict[str, Any]" = OrderedDict()
_stats = {"simulations_built": 0, "frames": 0}
#: Directories this process made (or found) for frame files.
_parents: set[str] = set()


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
        return _cache_key(self.source, self.scenario_json)


@lru_cache(maxsize=CACHE_SIZE)
def _cache_key(source: str | None, scenario_json: str) -> str:
    # every frame of a sequence asks with the same strings (their hashes are kept by Python)
    return hashlib.sha256(f"{source}\n{scenario_json}".encode("utf-8")).hexdigest()


def keep_simulation(source: str | None, scenario_json: str, sim: Any) -> None:
    """Let the jobs of this scenario (``scenario_json`` read from ``source``) run in ``sim``,
    built from them already (a serial run's sequence: one build instead of two)."""
    _remember(_cache_key(source, scenario_json), sim)


def _remember(key: str, sim: Any) -> None:
    """Keep ``sim`` under ``key``, the most recent of at most :data:`CACHE_SIZE`."""
    _simulations[key] = sim
    _simulations.move_to_end(key)
    while len(_simulations) > CACHE_SIZE:
        _simulations.popitem(last=False)


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
    _remember(key, sim)
    return sim


def simulate_frame_job(job: FrameJob) -> tuple[PointSpool, Any]:
    """Simulate ``job.frame`` into a :class:`~lidarsim_core.io.points.PointSpool` (the caller
    closes it, usually through :func:`write_frame_job`); returns it and the frame's info."""
    sim = _simulation(job)
    info, clear = sim.frame_ahead(job.frame)  # from a block of frames looked up at once
    spool = PointSpool(info, memory_limit=job.spool_memory)
    try:
        spool.extend(sim.iter_pieces(job.frame, outside_checked=clear))
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
        make_parent(path)
        record = write_points_file(spool, path, exporter=exporter)
    return frame_result(job, info, record)


def frame_result(job: FrameJob, info: Any, record: dict[str, Any]) -> dict[str, Any]:
    """What a frame job returns once its file is written (``record``: the file's sidecar
    record, or its ``file``, ``points``, ``bytes`` and ``sha256``)."""
    _stats["frames"] += 1
    return {"sequence": job.sequence, "frame": job.frame, "file": record["file"],
            "points": record["points"], "rays": info.rays_emitted, "bytes": record["bytes"],
            "sha256": record["sha256"]}


def make_parent(path: Path) -> None:
    """Create ``path``'s directory unless this process made it already (a sequence's
    frames share one: a ``mkdir`` a frame would be one more system call for the writer,
    see :mod:`lidarsim_core.io.filegroup`)."""
    parent = os.fspath(path.parent)
    if parent not in _parents:
        path.parent.mkdir(parents=True, exist_ok=True)
        if len(_parents) >= CACHE_SIZE * 64:
            _parents.clear()
        _parents.add(parent)


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
