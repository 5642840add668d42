"""The simulation pipeline: scenario → rays → poses → ray casting → noise → point record.

For every chunk of rays (vectorised throughout):

1. the scan pattern gives each ray's index, emission time, nominal direction and channel;
   pulses that cannot reach any target even after their angular error are dropped here
   (:mod:`lidarsim_core.pipeline.cull`, with the compiled kernels; it changes no result);
2. ray-stage noise models perturb the directions actually flown (paper: angular error);
3. the sensor and every target pose are looked up at each ray's time (or at frame start when
   ``scan.motion`` is ``frozen``) and the rays are moved into each target's body frame; with
   ``sensor.beam`` every pulse becomes K sub-rays over its divergence footprint, all cast in
   the same batch (:mod:`lidarsim_core.instrument.beam`);
4. the backend finds the first hit on every target; the closest target wins;

steps 5-8 are the measurement stages (:mod:`lidarsim_core.pipeline.stages`, one module each, run in
order on a :class:`~lidarsim_core.pipeline.stages.Piece`; :class:`Simulation` only coordinates), with
the optional multipath, Sun and receiver stages in between when the scenario asks for them:

5. hits become candidate returns: one per pulse, or the pulse's sub-ray hits grouped by
   range (:mod:`lidarsim_core.instrument.returns`), each with a signal and an intensity from the parts'
   materials (:mod:`lidarsim_core.scene.materials`, :mod:`lidarsim_core.instrument.linkbudget`); false-alarm
   models add spurious ones;
6. returns outside ``[range_min_m, range_max_m]`` are not detected; with
   ``sensor.detection`` each return is detected with the link budget's probability;
7. the return mode picks the reported returns of each pulse;
8. return-stage noise models perturb the reported range/direction (paper: range error,
   Eq. 4), with independent draws for second and later returns (:mod:`lidarsim_core.noise.streams`);
9. the point record is assembled in the sensor frame at the ray's emission time.

With none of ``sensor.beam``, ``sensor.detection`` and a false-alarm model, steps 5-7 keep
every hit inside the range gate, one per pulse: the seed paper's model, to the bit.
"""

from __future__ import annotations

import threading
import time
from dataclasses import fields
from pathlib import Path
from typing import Any, Iterator, Sequence

import numpy as np

from ..base.allocator import keep_freed_memory
from ..base.errors import ConfigError
from ..base.pinning import pin_mode
from ..base.signals import interrupt_behind
from ..base.threads import ordered_map, piece_size, split_range, worker_threads
from ..instrument.beam import SubRays, sub_rays_for
from ..instrument.linkbudget import LinkBudget, detection_range_limit, link_budget
from ..noise.outliers import SpuriousReturnModel
from ..noise.rng import INVERSE_CDF
from ..plugins.guards import guard_components
from ..plugins.manager import get_registry
from ..plugins.registry import Registry
from ..plugins.resolve import (
    datasheet_for,
    noise_chain,
    pattern_for,
    resolve_backend,
    target_mesh,
    trajectory_for,
)
from ..records.pointcloud import FrameInfo, PointCloud
from ..scenario.load import as_scenario
from ..scenario.model import NamedComponent, Scenario
from ..scenario.sensor import ReturnsConfig
from ..scene.materials import Material, MaterialTable, material_library, part_materials
from .balance import PiecePlan
from .budget import check_simulation
from .cast import process_piece
from .context import RunContext, Target
from .cull import PulseCuller, culled_piece
from .frameinfo import frame_infos, pose_records
from .fused import FusedPath
from .inside import check_sensor_outside, clear_of_targets
from .spanposes import SpanPoses
from .stages import Stage, measurement_stages
from .units import warn_about_units

DEFAULT_NOISE_CHAIN = ("angular", "range")
#: Frames whose poses :meth:`Simulation.frame_ahead` looks up together.
FRAME_BLOCK = 64
#: Frames whose metadata :meth:`Simulation.keep_frame_infos` keeps at most.
FRAMES_KEPT = 512
#: Guards every simulation's block of :meth:`Simulation.frame_ahead`.
_ahead_lock = threading.Lock()
#: Most rays per unit of work handed to a pipeline thread (a chunk is split into such pieces,
#: about one per thread; with K sub-rays per pulse a piece holds PIECE_RAYS / K pulses). A
#: piece of the general path costs ~0.4 ms of fixed work, most of it holding the GIL, so few
#: large pieces: with 7 sub-rays a 100,000-pulse frame took 27 ms on two threads in 11 pieces
#: of 65,536 rays and 18 ms in 2 of this size, its peak memory 66 and 95 MB (docs/performance.md,
#: "Threads"); a piece never exceeds the chunk (``chunk_rays``), the run's memory bound.
PIECE_RAYS = 2 ** 19
#: Part label of false alarms (appended to the scene's parts when a model makes them).
FALSE_ALARM_PART = "noise/false_alarm"
#: The context's public fields, also readable and settable as the simulation's attributes.
_CONTEXT_FIELDS = frozenset(f.name for f in fields(RunContext) if not f.name.startswith("_"))


class Simulation:
    """A scenario with every name resolved: sensor, pattern, noise chain, backend, targets.

    The one place that assembles a run: it resolves the scenario's names through the plugin
    registry (:mod:`lidarsim_core.plugins.resolve`), builds the measurement model, and hands
    the :class:`~lidarsim_core.pipeline.context.RunContext` (readable here as
    ``sim.context``, its fields also as attributes: ``sim.sensor``, ``sim.pattern``,
    ``sim.targets``...) to the culling, posing, cast and measurement stages. Build once, then
    call :meth:`run_frame` for each frame; acceleration structures are built on first use and
    cached per mesh.

    Parameters
    ----------
    scenario
        A validated :class:`~lidarsim_core.scenario.model.Scenario`.
    registry
        The plugin registry (default: the process-wide one).
    """

    def __init__(self, scenario: Scenario, registry: Registry | None = None) -> None:
        registry = registry or get_registry()
        keep_freed_memory()  # frames reuse the last one's pages (lidarsim_core.base.allocator)
        pin_mode()  # a mistyped LIDARSIM_PIN_THREADS is refused before any work
        src = scenario.source
        sheet = datasheet_for(scenario, registry)
        pattern = pattern_for(sheet, scenario.sensor.pattern_options, source=src,
                              field="sensor.datasheet.scan_pattern.name", registry=registry)
        chain = scenario.noise if scenario.noise is not None else \
            [NamedComponent(name=n) for n in DEFAULT_NOISE_CHAIN]
        noise = noise_chain(registry, chain, source=src)
        backend = resolve_backend(registry, scenario.backend, source=src)
        sensor_trajectory = trajectory_for(registry, scenario.sensor, source=src,
                                           field="sensor.trajectory")
        targets: list[Target] = []
        offset = 0
        for i, cfg in enumerate(scenario.targets):
            mesh = target_mesh(registry, scenario, i)
            traj = trajectory_for(registry, cfg, source=src, field=f"targets.{i}.trajectory")
            targets.append(Target(cfg.name, mesh, traj, offset))
            offset += len(mesh.part_names)
        part_names = [f"{t.name}/{p}" for t in targets for p in t.mesh.part_names]
        #: The resolved scenario that culling, posing, the cast and the stages receive.
        self.context = RunContext(
            scenario, sheet, pattern, noise, backend, sensor_trajectory, targets, part_names,
            **_measurement(scenario, sheet, targets, noise, part_names))
        warn_about_units(self.context)  # a mesh in millimetres: a warning that suggests 'scale'
        #: The measurement stages, run in order on every piece (:mod:`.stages`).
        self.stages: list[Stage] = measurement_stages(self.context)
        check_simulation(self.context)  # the resource budget, before any ray is generated
        #: Plan for skipping pulses that cannot reach a target (None: every pulse is cast).
        self.culler: PulseCuller | None = PulseCuller.for_context(self.context)
        #: The compiled path of the seed paper's model (None: the general path, :mod:`.fused`).
        self.fused: FusedPath | None = FusedPath.for_context(self.context, self.stages)
        #: How spans are cut into pieces for the threads (:mod:`.balance`).
        self._plan = PiecePlan()
        # third-party components that fail mid-run are reported with their name
        parts: list[tuple[str, Any]] = [("scan_pattern", pattern), ("ray_backend", backend),
                                        ("trajectory", sensor_trajectory)]
        parts += [("noise_model", model) for model in noise]
        parts += [("trajectory", target.trajectory) for target in targets]
        guard_components(parts, registry)

    def __getattr__(self, name: str) -> Any:
        # the context's fields read as the simulation's own (sim.sensor, sim.targets, ...)
        context = self.__dict__.get("context")
        if context is not None and (name in _CONTEXT_FIELDS or name == "rays_per_pulse"):
            return getattr(context, name)
        raise AttributeError(f"'Simulation' object has no attribute {name!r}")

    def __setattr__(self, name: str, value: Any) -> None:
        # ...and are set on the context, which the pieces of the run read
        context = self.__dict__.get("context")
        if context is not None and name in _CONTEXT_FIELDS:
            setattr(context, name, value)
        else:
            super().__setattr__(name, value)

    # ---- running ------------------------------------------------------------------------
    def frame_rays(self, frame: int) -> tuple[int, int]:
        """Global ray index range ``[k0, k1)`` of ``frame``."""
        t0, t1 = self.context.scenario.scan.frame_interval(frame)
        return self.context.pattern.frame_index_range(t0, t1)  # a flash LiDAR's frame: one flash

    def iter_chunks(self, frame: int, chunk_rays: int | None = None, *,
                    outside_checked: bool = False) -> Iterator[dict[str, np.ndarray]]:
        """Point-record columns of ``frame``, one dictionary per chunk of emitted rays.

        Each chunk is processed in about one piece per thread (at most :data:`PIECE_RAYS`
        rays each) on :func:`~lidarsim_core.base.threads.worker_threads` threads
        (``LIDARSIM_THREADS``; one thread if the backend is not ``thread_safe``); every ray's
        result depends only on its index, so neither setting changes the output.
        ``outside_checked``: the caller found the sensor clear of every target at the frame's
        start and end (:func:`~lidarsim_core.pipeline.inside.clear_of_targets`, a block of
        frames at once), so the frame's own check is skipped.
        """
        yield from self.iter_span_chunks(
            frame, *self.context.scenario.scan.frame_interval(frame), chunk_rays,
            outside_checked=outside_checked)

    def iter_pieces(self, frame: int, *, outside_checked: bool = False
                    ) -> Iterator[dict[str, np.ndarray]]:
        """The columns :meth:`iter_chunks` yields, piece by piece as the threads make them
        (a chunk is its pieces concatenated): for a consumer that concatenates them itself,
        as :class:`~lidarsim_core.io.points.PointSpool` does, without the copy in between."""
        for _, columns in self._span_pieces(
                frame, *self.context.scenario.scan.frame_interval(frame), None,
                outside_checked=outside_checked):
            yield columns

    def iter_span_chunks(self, frame: int, t_start: float, t_end: float,
                         chunk_rays: int | None = None, *, outside_checked: bool = False
                         ) -> Iterator[dict[str, np.ndarray]]:
        """:meth:`iter_chunks` of a frame numbered ``frame`` (its noise streams) that covers
        ``[t_start, t_end)`` instead of the scenario's interval (the stepping API,
        :mod:`lidarsim_core.loop`, scans intervals it is given; a scenario frame is this span
        of its own interval, to the bit)."""
        done: list[dict[str, np.ndarray]] = []
        current = 0
        for c, columns in self._span_pieces(frame, t_start, t_end, chunk_rays,
                                            outside_checked=outside_checked):
            if c != current:
                yield _merged(done)
                done, current = [], c
            done.append(columns)
        if done:
            yield _merged(done)

    def _span_pieces(self, frame: int, t_start: float, t_end: float, chunk_rays: int | None,
                     poses: SpanPoses | None = None, *, outside_checked: bool = False
                     ) -> Iterator[tuple[int, dict[str, np.ndarray]]]:
        """The point-record columns of every piece of ``[t_start, t_end)`` in order, each
        with the number of its chunk (``poses``: the trajectories' poses at ``t_start`` and
        ``t_end`` when already looked up; ``outside_checked``: as in :meth:`iter_chunks`)."""
        ctx = self.context
        if not outside_checked:
            check_sensor_outside(ctx, frame, (t_start, t_end), poses)
        chunk = chunk_rays or ctx.scenario.chunk_rays
        k0, k1 = ctx.pattern.frame_index_range(t_start, t_end)
        contexts = ctx.noise_contexts(frame)
        t_frame = t_start
        for target in ctx.targets:  # build acceleration structures before the workers start
            ctx.backend.prepared(target.mesh)
        workers = worker_threads() if ctx.backend.thread_safe else 1
        largest = max(1, PIECE_RAYS // ctx.rays_per_pulse)
        chunks = split_range(k0, k1, chunk)
        # a span whose chunks make one piece per thread runs so, or on this thread, as the
        # plan measured faster; its pieces are cut where the last ones took equal times
        # (:mod:`.balance`)
        piece_pulses = piece_size(min(chunk, k1 - k0), workers, largest)
        planned = workers > 1 and any(len(split_range(a, b, piece_pulses)) == workers
                                      for a, b in chunks)
        threaded = not planned or self._plan.threaded()
        if not threaded:
            workers = 1
            piece_pulses = piece_size(min(chunk, k1 - k0), 1, largest)
        pieces: list[tuple[int, int, int]] = []
        balanced: dict[int, list[float]] = {}  # chunk -> the fractions it was cut at
        for c, (start, stop) in enumerate(chunks):
            cut = split_range(start, stop, piece_pulses)
            if workers > 1 and len(cut) == workers:
                balanced[c] = self._plan.bounds(workers)
                cut = self._plan.cuts(start, stop, balanced[c])
            pieces += [(c, lo, hi) for lo, hi in cut]
        seconds: dict[tuple[int, int, int], float] = {}
        began = time.perf_counter()

        def work(piece: tuple[int, int, int]) -> dict[str, np.ndarray]:
            start = time.perf_counter()
            # only pulses that may reach a target go on, with their rays and poses
            batch = culled_piece(ctx, self.culler,
                                 np.arange(piece[1], piece[2], dtype=np.int64), t_frame)
            if self.fused is not None:  # the seed paper's model, compiled: the same bits
                columns = self.fused.process(batch, contexts, t_frame)
            else:
                columns = process_piece(ctx, self.stages, batch, contexts, t_frame, frame)
            seconds[piece] = time.perf_counter() - start
            return columns

        try:
            for (c, _, _), columns in zip(pieces, ordered_map(work, pieces, workers)):
                yield c, columns
        except Exception as exc:  # Ctrl-C or SIGTERM while a compiled kernel was called
            interrupt = interrupt_behind(exc)
            if interrupt is None:
                raise
            raise interrupt from None
        if planned:
            self._plan.timed(threaded, time.perf_counter() - began, k1 - k0)
        for c, bounds in balanced.items():
            times = [seconds[p] for p in pieces if p[0] == c]
            if len(times) == workers:  # (a piece of no pulse leaves the cuts alone)
                self._plan.record(bounds, times)

    def frame_info(self, frame: int) -> FrameInfo:
        """Metadata of ``frame``: timing, poses at start and end, provenance."""
        return self.frame_infos([frame])[0]

    def frame_infos(self, frames: Sequence[int],
                    intervals: Sequence[tuple[float, float]] | None = None) -> list[FrameInfo]:
        """:meth:`frame_info` of each of ``frames``, every trajectory evaluated once for all
        (:mod:`lidarsim_core.pipeline.frameinfo`; the same bits as one frame at a time);
        ``intervals`` replace the scenario's frame intervals (see :meth:`iter_span_chunks`)."""
        return frame_infos(self.context, frames, self.measurement_info(), intervals)

    def measurement_info(self) -> dict[str, Any]:
        """The measurement model beyond the seed paper's, for frame metadata (empty when
        none of beam, detection and false alarms is on, and the normals are the seed
        paper's inverse CDF; ``{"normals": "ziggurat"}`` names the other generator)."""
        ctx = self.context
        info: dict[str, Any] = {}
        if ctx.link is not None:
            info["link_budget"] = {"constant": ctx.link.constant,
                                   "exponent": ctx.link.exponent,
                                   "threshold_to_noise": ctx.link.threshold_to_noise,
                                   "range_limit_m": ctx.range_limit}
        if ctx.sub_rays is not None:
            info["beam"] = {"sub_rays": ctx.sub_rays.count,
                            "range_resolution_m": ctx.range_resolution_m}
        for stage in self.stages:  # the optional stages describe themselves
            if hasattr(stage, "info"):
                info[stage.name] = stage.info()
        if info or ctx.spurious:
            info["return_mode"] = ctx.return_mode
            if ctx.return_mode == "dual":
                info["dual_return"] = ctx.dual_return
            if ctx.return_mode == "multi":
                info["max_returns"] = ctx.max_returns
        extra: dict[str, Any] = {"measurement": info} if info else {}
        if ctx.scenario.normals != INVERSE_CDF:  # the seed paper's stream stays unnamed
            extra["normals"] = ctx.scenario.normals
        return extra

    def run_frame(self, frame: int = 0, chunk_rays: int | None = None) -> PointCloud:
        """Simulate one frame and return its point cloud."""
        # the metadata and the inside check from a block of frames (frame_ahead, which also
        # refuses a frame outside the scan); the pieces are joined once (one piece: its
        # arrays as they are), not per chunk
        info, clear = self.frame_ahead(frame)
        t_start, t_end = self.context.scenario.scan.frame_interval(frame)
        pieces = [columns for _, columns in
                  self._span_pieces(frame, t_start, t_end, chunk_rays, outside_checked=clear)]
        return PointCloud.concatenate(pieces, info)

    def frame_ahead(self, frame: int) -> tuple[FrameInfo, bool]:
        """``frame``'s metadata, and whether the sensor is clearly outside every target's
        bounding box at the frame's start and end
        (:func:`~lidarsim_core.pipeline.inside.clear_of_targets`: the frame's own inside
        check may be skipped), from a block of :data:`FRAME_BLOCK` frames from ``frame`` on.

        The block's poses are looked up in one call per trajectory (SciPy's path, the bits of
        one frame at a time: :mod:`.frameinfo`) and kept for the next frames of a sequence,
        or the same frame again; a frame pays ~20 µs of the block instead of ~0.3 ms of its
        own lookups. The block is made again when a frame outside it is asked for, or when a
        trajectory, a mesh or the frame timing changed.
        """
        ctx = self.context
        scan = ctx.scenario.scan
        frames = scan.frames
        if not 0 <= frame < frames:
            raise ConfigError(f"frame {frame} is outside 0..{frames - 1}",
                              source=ctx.scenario.source, field="scan.frames")
        t_start, t_end = scan.frame_interval(frame)
        key = self._ahead_key()
        with _ahead_lock:
            kept = self.__dict__.get("_kept")
            info = kept[1].pop(frame, None) if kept is not None and kept[0] == key else None
            if info is not None and (info.t_start, info.t_end) != (t_start, t_end):
                info = None  # made for another frame timing
            ahead = self.__dict__.get("_ahead")
            rows = None
            if ahead is not None and ahead[0] == key and 0 <= frame - ahead[1] < len(ahead[3]):
                i = frame - ahead[1]
                if info is not None:  # made already: the block gives the inside check only
                    return info, bool(ahead[3][i])
                rows = ahead[2].rows(2 * i, 2 * i + 2).at(
                    np.array([t_start, t_end], dtype=np.float64))
            if rows is None:  # a new block from this frame on
                block = range(frame, max(frame + 1, min(frames, frame + FRAME_BLOCK)))
                times = np.array([scan.frame_interval(f) for f in block],
                                 dtype=np.float64).reshape(-1)
                try:
                    ahead = (key, frame, pose_records(ctx, times),
                             clear_of_targets(ctx, block))
                except Exception:  # noqa: BLE001 - a later frame's trouble is its own
                    ahead = None
                self.__dict__["_ahead"] = ahead
                if ahead is not None:
                    rows = ahead[2].rows(0, 2)
            clear = ahead is not None and bool(ahead[3][frame - ahead[1]])
        if info is None:
            info = frame_infos(ctx, [frame], self.measurement_info(), records=rows)[0]
        return info, clear

    def keep_frame_infos(self, infos: Sequence[FrameInfo]) -> None:
        """Hand the first :data:`FRAMES_KEPT` of ``infos``, made by :meth:`frame_infos` of
        this simulation as it is now (its trajectories, meshes and timing), to
        :meth:`frame_ahead`, each once, instead of making them again: a dataset's poses file
        makes its frames' metadata before the frames run (~70 µs a frame)."""
        kept = {info.frame: info for info in infos[:FRAMES_KEPT]}
        with _ahead_lock:
            self.__dict__["_kept"] = (self._ahead_key(), kept)

    def _ahead_key(self) -> tuple[Any, ...]:
        """What the frames' metadata depends on beside their times: the trajectories, the
        meshes and the motion mode (:meth:`frame_ahead`)."""
        ctx = self.context
        return (id(ctx.sensor_trajectory), ctx.scenario.scan.motion,
                tuple((id(t.trajectory), id(t.mesh)) for t in ctx.targets))


def _merged(parts: list[dict[str, np.ndarray]]) -> dict[str, np.ndarray]:
    """The columns of consecutive pieces as one chunk."""
    if len(parts) == 1:
        return parts[0]
    return {key: np.concatenate([p[key] for p in parts]) for key in parts[0]}


def _measurement(scenario: Scenario, sheet: Any, targets: list[Target], noise: list[Any],
                 part_names: list[str]) -> dict[str, Any]:
    """Materials, link budget, range gate, beam and return mode (docs/realism.md): the
    measurement fields of the run's context. ``part_names`` gains the false-alarm part when
    false alarms can occur."""
    src = scenario.source
    library = material_library(scenario.materials, source=src)
    materials: list[Material] = []
    for i, (cfg, target) in enumerate(zip(scenario.targets, targets)):
        materials += part_materials(target.mesh.part_names, target.mesh.part_materials,
                                    cfg.materials, library, source=src,
                                    field=f"targets.{i}.materials")
    spurious = [(i, m) for i, m in enumerate(noise) if isinstance(m, SpuriousReturnModel)]
    false_alarm_part = -1
    if spurious or scenario.sun is not None:
        false_alarm_part = len(part_names)
        part_names.append(FALSE_ALARM_PART)
        materials.append(Material(description="false alarm (no surface)"))
    detection = scenario.sensor.detection
    link: LinkBudget | None = None
    range_limit = sheet.range_max_m
    if detection is not None:
        link = link_budget(detection, sheet, source=src)
        range_limit = detection_range_limit(detection, sheet)
    returns = scenario.sensor.returns or ReturnsConfig()
    resolution = returns.range_resolution_m or sheet.range_resolution_m
    beam = scenario.sensor.beam
    sub_rays: SubRays | None = None
    if beam is not None and beam.sub_rays > 1:
        divergence = beam.divergence_deg or sheet.beam_divergence_deg
        if divergence is None:
            raise ConfigError(f"datasheet '{sheet.name}' gives no beam_divergence_deg; "
                              "give it here", source=src, field="sensor.beam.divergence_deg")
        if resolution is None:
            raise ConfigError(f"sub-rays are grouped into returns by the range resolution "
                              f"and datasheet '{sheet.name}' gives none; give it here",
                              source=src, field="sensor.returns.range_resolution_m")
        sub_rays = sub_rays_for(beam, divergence)
    return {"materials": MaterialTable.from_materials(materials), "spurious": spurious,
            "false_alarm_part": false_alarm_part, "link": link, "range_limit": range_limit,
            "keep_undetected": bool(detection is not None and detection.keep_undetected),
            "return_mode": returns.mode or sheet.return_mode,
            "dual_return": returns.dual or sheet.dual_return,
            "max_returns": returns.max_returns or sheet.max_returns,
            "range_resolution_m": resolution, "sub_rays": sub_rays,
            # stages that cast secondary rays need the hit normals
            "keep_normals": scenario.sensor.multipath is not None or scenario.sun is not None}


def sequence_frame_infos(scenario: Scenario | Simulation,
                         frames: Sequence[int] | None = None) -> list[FrameInfo]:
    """Frame metadata of a scenario's frames without casting a ray (poses come from the
    trajectories alone)."""
    sim = scenario if isinstance(scenario, Simulation) else Simulation(scenario)
    indices = range(sim.context.scenario.scan.frames) if frames is None else frames
    return sim.frame_infos(indices)


def simulate(scenario: Scenario | str | Path | dict[str, Any], *, frame: int = 0,
             chunk_rays: int | None = None) -> PointCloud:
    """Simulate one frame of a scenario.

    Parameters
    ----------
    scenario
        A :class:`~lidarsim_core.scenario.model.Scenario`, a scenario file path, or a mapping.
    frame
        Which frame of the scenario's sequence (default the first).
    chunk_rays
        Rays per processing chunk (default the scenario's ``chunk_rays``); results do not
        depend on it.

    Returns
    -------
    PointCloud
        The points with their ground truth and the frame's metadata.

    Examples
    --------
    >>> import lidarsim_core as ls
    >>> cloud = ls.simulate(ls.demo_scenario(duration_s=0.01))
    >>> len(cloud) > 0
    True
    """
    return Simulation(as_scenario(scenario)).run_frame(frame, chunk_rays)
