"""The simulation pipeline: scenario → rays → poses → ray casting → noise → point record.

For every chunk of rays (vectorised throughout):

1. the scan pattern gives each ray's index, emission time, nominal direction and channel;
   pulses that cannot reach any target even after their angular error are dropped here
   (:mod:`lidarsim_core.cull`, with the compiled kernels; it changes no result);
2. ray-stage noise models perturb the directions actually flown (paper: angular error);
3. the sensor and every target pose are looked up at each ray's time (or at frame start when
   ``scan.motion`` is ``frozen``) and the rays are moved into each target's body frame; with
   ``sensor.beam`` every pulse becomes K sub-rays over its divergence footprint, all cast in
   the same batch (:mod:`lidarsim_core.beam`);
4. the backend finds the first hit on every target; the closest target wins;

steps 5-8 are the measurement stages (:mod:`lidarsim_core.stages`, one module each, run in
order on a :class:`~lidarsim_core.stages.Piece`; :class:`Simulation` only coordinates), with
the optional multipath, Sun and receiver stages in between when the scenario asks for them:

5. hits become candidate returns: one per pulse, or the pulse's sub-ray hits grouped by
   range (:mod:`lidarsim_core.returns`), each with a signal and an intensity from the parts'
   materials (:mod:`lidarsim_core.materials`, :mod:`lidarsim_core.radiometry`); false-alarm
   models add spurious ones;
6. returns outside ``[range_min_m, range_max_m]`` are not detected; with
   ``sensor.detection`` each return is detected with the link budget's probability;
7. the return mode picks the reported returns of each pulse;
8. return-stage noise models perturb the reported range/direction (paper: range error,
   Eq. 4), with independent draws for second and later returns (:mod:`.noise.streams`);
9. the point record is assembled in the sensor frame at the ray's emission time.

With none of ``sensor.beam``, ``sensor.detection`` and a false-alarm model, steps 5-7 keep
every hit inside the range gate, one per pulse: the seed paper's model, to the bit.
"""

from __future__ import annotations

from dataclasses import dataclass
from pathlib import Path
from typing import Any, Iterator, Sequence

import numpy as np

from .backends.base import RayBackend
from .beam import SubRays, sub_rays_for
from .builtin_sensors import get_sensor
from .limits import check_simulation
from .chunks import ordered_map, piece_size, rotate, split_range, to_body, worker_threads
from .config_io import validate_model
from .cull import PulseCuller
from .datasheet import SensorDatasheet
from .guard import check_sensor_outside, guard_components, interrupt_behind
from .errors import ConfigError, LidarsimError, MeshError, PluginError
from .materials import Material, MaterialTable, material_library, part_materials
from .mesh import Mesh, load_mesh_file
from .units import warn_about_units
from .noise.base import NoiseContext, NoiseModel, perpendicular_basis
from .noise.outliers import SpuriousReturnModel
from .patterns.base import RayBatch, ScanPattern
from .plugins import get_registry
from .pointcloud import FrameInfo, PointCloud
from .posing import PoseMatrices, piece_poses, pose_matrices, with_piece_poses
from .radiometry import LinkBudget, detection_range_limit, link_budget
from .registry import Registry
from .returns import ReturnsConfig, SubRayHits
from .scenario import NamedComponent, Scenario, load_scenario, scenario_from_dict
from .trajectories.base import Trajectory
from .stages import Piece, SceneRays, Stage, measurement_stages, record_columns
from .vec3 import rowdot

DEFAULT_NOISE_CHAIN = ("angular", "range")
#: Most rays per unit of work handed to a pipeline thread (a chunk is split into such pieces,
#: about one per thread; with K sub-rays per pulse a piece holds PIECE_RAYS / K pulses).
PIECE_RAYS = 65536
#: Part label of false alarms (appended to the scene's parts when a model makes them).
FALSE_ALARM_PART = "noise/false_alarm"


@dataclass
class Target:
    """A resolved target: label, mesh and trajectory."""

    name: str
    mesh: Mesh
    trajectory: Trajectory
    part_offset: int


def _component(registry: Registry, kind: str, spec: NamedComponent, *, source: str,
               field: str) -> Any:
    cls = registry.get(kind, spec.name, source=source, field=f"{field}.name")
    return cls.from_config(spec.options, source=source, field=f"{field}.options")


def resolve_backend(registry: Registry, spec: NamedComponent, *, source: str) -> RayBackend:
    """Instantiate the configured backend; ``auto`` picks Embree when available, else NumPy."""
    if spec.name == "auto":
        embree = registry.entries["ray_backend"].get("embree")
        usable = embree is not None and embree.obj.is_available()[0]
        spec = NamedComponent(name="embree" if usable else "numpy", options=spec.options)
    backend = _component(registry, "ray_backend", spec, source=source, field="backend")
    ok, why = backend.is_available()
    if not ok:
        raise ConfigError(f"backend '{spec.name}' is not usable here: {why}", source=source,
                          field="backend.name")
    return backend


def _trajectory(registry: Registry, posed: Any, *, source: str, field: str) -> Trajectory:
    config = posed.trajectory_config()
    cls = registry.get("trajectory", config.kind, source=source, field=f"{field}.kind")
    return cls.from_config(config.plugin_options(), source=source, field=field)


class Simulation:
    """A scenario with every name resolved: sensor, pattern, noise chain, backend, targets.

    Build once, then call :meth:`run_frame` for each frame; acceleration structures are built
    on first use and cached per mesh.

    Parameters
    ----------
    scenario
        A validated :class:`~lidarsim_core.scenario.Scenario`.
    registry
        The plugin registry (default: the process-wide one).
    """

    def __init__(self, scenario: Scenario, registry: Registry | None = None) -> None:
        self.scenario = scenario
        self._fixed_poses: dict[tuple[int, float | None], PoseMatrices] = {}
        registry = registry or get_registry()
        src = scenario.source
        self.sensor: SensorDatasheet = self._datasheet(scenario, registry)
        pattern_spec = self.sensor.scan_pattern
        pattern_cls = registry.get("scan_pattern", pattern_spec.name, source=src,
                                   field="sensor.datasheet.scan_pattern.name")
        self.pattern: ScanPattern = pattern_cls.for_sensor(
            self.sensor, scenario.sensor.pattern_options, source=src)
        chain = scenario.noise if scenario.noise is not None else \
            [NamedComponent(name=n) for n in DEFAULT_NOISE_CHAIN]
        self.noise: list[NoiseModel] = [
            _component(registry, "noise_model", spec, source=src, field=f"noise.{i}")
            for i, spec in enumerate(chain)]
        self.backend: RayBackend = resolve_backend(registry, scenario.backend, source=src)
        self.sensor_trajectory = _trajectory(registry, scenario.sensor, source=src,
                                             field="sensor.trajectory")
        self.targets: list[Target] = []
        offset = 0
        for i, cfg in enumerate(scenario.targets):
            mesh = self._mesh(registry, scenario, i)
            traj = _trajectory(registry, cfg, source=src, field=f"targets.{i}.trajectory")
            self.targets.append(Target(cfg.name, mesh, traj, offset))
            offset += len(mesh.part_names)
        self.part_names = [f"{t.name}/{p}" for t in self.targets for p in t.mesh.part_names]
        warn_about_units(self)  # a mesh in millimetres: a warning that suggests 'scale'
        self._setup_measurement(scenario)
        check_simulation(self)  # the resource budget, before any ray is generated
        #: Plan for skipping pulses that cannot reach a target (None: every pulse is cast).
        self.culler: PulseCuller | None = PulseCuller.for_simulation(self)
        # third-party components that fail mid-run are reported with their name
        guard_components(self, registry)

    def _setup_measurement(self, scenario: Scenario) -> None:
        """Materials, link budget, range gate, beam and return mode (docs/realism.md)."""
        src, sheet = scenario.source, self.sensor
        library = material_library(scenario.materials, source=src)
        materials: list[Material] = []
        for i, (cfg, target) in enumerate(zip(scenario.targets, self.targets)):
            materials += part_materials(target.mesh.part_names, target.mesh.part_materials,
                                        cfg.materials, library, source=src,
                                        field=f"targets.{i}.materials")
        #: Noise models that add spurious echoes (false alarms), with their chain position.
        self.spurious = [(i, m) for i, m in enumerate(self.noise)
                         if isinstance(m, SpuriousReturnModel)]
        self.false_alarm_part = -1
        if self.spurious or scenario.sun is not None:
            self.false_alarm_part = len(self.part_names)
            self.part_names.append(FALSE_ALARM_PART)
            materials.append(Material(description="false alarm (no surface)"))
        #: Materials of every scene-wide part.
        self.materials = MaterialTable.from_materials(materials)
        detection = scenario.sensor.detection
        #: The calibrated link budget, None without ``sensor.detection``.
        self.link: LinkBudget | None = None
        self.range_limit = sheet.range_max_m
        if detection is not None:
            self.link = link_budget(detection, sheet, source=src)
            self.range_limit = detection_range_limit(detection, sheet)
        self.keep_undetected = bool(detection is not None and detection.keep_undetected)
        returns = scenario.sensor.returns or ReturnsConfig()
        self.return_mode = returns.mode or sheet.return_mode
        self.dual_return = returns.dual or sheet.dual_return
        self.max_returns = returns.max_returns or sheet.max_returns
        resolution = returns.range_resolution_m or sheet.range_resolution_m
        beam = scenario.sensor.beam
        #: Sub-ray layout, None for one ray per pulse.
        self.sub_rays: SubRays | None = None
        if beam is not None and beam.sub_rays > 1:
            divergence = beam.divergence_deg or sheet.beam_divergence_deg
            if divergence is None:
                raise ConfigError(f"datasheet '{sheet.name}' gives no beam_divergence_deg; "
                                  "give it here", source=src, field="sensor.beam.divergence_deg")
            if resolution is None:
                raise ConfigError(f"sub-rays are grouped into returns by the range resolution "
                                  f"and datasheet '{sheet.name}' gives none; give it here",
                                  source=src, field="sensor.returns.range_resolution_m")
            self.sub_rays = sub_rays_for(beam, divergence)
        self.range_resolution_m = resolution
        #: Whether the cast keeps the hit normals (stages that cast secondary rays need them).
        self.keep_normals = scenario.sensor.multipath is not None or scenario.sun is not None
        #: The measurement stages, run in order on every piece (:mod:`lidarsim_core.stages`).
        self.stages: list[Stage] = measurement_stages(self)

    @property
    def rays_per_pulse(self) -> int:
        """K: rays cast per emitted pulse (1 without beam divergence)."""
        return 1 if self.sub_rays is None else self.sub_rays.count

    @staticmethod
    def _datasheet(scenario: Scenario, registry: Registry) -> SensorDatasheet:
        spec = scenario.sensor.datasheet
        src = scenario.source
        if isinstance(spec, dict):
            return validate_model(SensorDatasheet, spec, source=src, prefix="sensor.datasheet")
        if spec.endswith((".yaml", ".yml", ".toml", ".json")):
            path = scenario.resolve(Path(spec))
            if not path.is_file():
                raise ConfigError(f"datasheet file not found: {path}", source=src,
                                  field="sensor.datasheet")
            return get_sensor(path)
        return registry.get("sensor", spec, source=src, field="sensor.datasheet")

    @staticmethod
    def _mesh(registry: Registry, scenario: Scenario, index: int) -> Mesh:
        cfg = scenario.targets[index].mesh
        field = f"targets.{index}.mesh"
        if cfg.path is not None:
            return load_mesh_file(scenario.resolve(cfg.path), scale=cfg.scale,
                                  source=scenario.source, field=f"{field}.path")
        model_cls = registry.get("target_model", cfg.model, source=scenario.source,
                                 field=f"{field}.model")
        model = model_cls.from_config(cfg.options, source=scenario.source,
                                      field=f"{field}.options")
        try:  # a model's options or the scale can make an unusable mesh: name the field
            mesh = model.mesh()
            if cfg.scale != 1.0:
                mesh = Mesh.from_arrays(mesh.vertices * cfg.scale, mesh.faces, mesh.face_part,
                                        mesh.part_names, name=mesh.name,
                                        part_materials=mesh.part_materials)
        except MeshError as exc:  # a procedural model reads no file: the scenario is to blame
            raise MeshError(f"model '{cfg.model}': {exc.message}", source=scenario.source,
                            field=field) from None
        return mesh

    # ---- running ------------------------------------------------------------------------
    def frame_rays(self, frame: int) -> tuple[int, int]:
        """Global ray index range ``[k0, k1)`` of ``frame``."""
        t0, t1 = self.scenario.scan.frame_interval(frame)
        return self.pattern.frame_index_range(t0, t1)  # a flash LiDAR's frame: one flash

    def _noise_contexts(self, frame: int) -> list[NoiseContext]:
        return [NoiseContext(self.sensor, self.scenario.seed, frame, f"noise.{i}.{m.name}")
                for i, m in enumerate(self.noise)]

    def iter_chunks(self, frame: int, chunk_rays: int | None = None
                    ) -> Iterator[dict[str, np.ndarray]]:
        """Point-record columns of ``frame``, one dictionary per chunk of emitted rays.

        Each chunk is processed in about one piece per thread (at most :data:`PIECE_RAYS`
        rays each) on :func:`~lidarsim_core.chunks.worker_threads` threads
        (``LIDARSIM_THREADS``; one thread if the backend is not ``thread_safe``); every ray's
        result depends only on its index, so neither setting changes the output.
        """
        check_sensor_outside(self, frame)
        chunk = chunk_rays or self.scenario.chunk_rays
        k0, k1 = self.frame_rays(frame)
        contexts = self._noise_contexts(frame)
        t_frame = self.scenario.scan.frame_interval(frame)[0]
        for target in self.targets:  # build acceleration structures before the workers start
            self.backend.prepared(target.mesh)
        workers = worker_threads() if self.backend.thread_safe else 1
        piece_pulses = piece_size(min(chunk, k1 - k0), workers,
                                  max(1, PIECE_RAYS // self.rays_per_pulse))
        pieces = [(c, lo, hi) for c, (start, stop) in enumerate(split_range(k0, k1, chunk))
                  for lo, hi in split_range(start, stop, piece_pulses)]

        def work(piece: tuple[int, int, int]) -> dict[str, np.ndarray]:
            batch = self.pattern.rays_for_indices(np.arange(piece[1], piece[2], dtype=np.int64))
            batch = with_piece_poses(self, batch, t_frame)  # shared by culling and casting
            if self.culler is not None:  # only pulses that may reach a target go on
                batch = batch.take(self.culler.keep(self, batch, t_frame))
            return self._process(batch, contexts, t_frame, frame)

        def merged(parts: list[dict[str, np.ndarray]]) -> dict[str, np.ndarray]:
            if len(parts) == 1:
                return parts[0]
            return {key: np.concatenate([p[key] for p in parts]) for key in parts[0]}

        done: list[dict[str, np.ndarray]] = []
        current = 0
        try:
            for (c, _, _), columns in zip(pieces, ordered_map(work, pieces, workers)):
                if c != current:
                    yield merged(done)
                    done, current = [], c
                done.append(columns)
        except Exception as exc:  # Ctrl-C or SIGTERM while a compiled kernel was called
            interrupt = interrupt_behind(exc)
            if interrupt is None:
                raise
            raise interrupt from None
        if done:
            yield merged(done)

    def _poses(self, trajectory: Trajectory, t: np.ndarray, t_frame: float) -> PoseMatrices:
        if self.scenario.scan.motion == "frozen":
            t = np.full_like(t, t_frame)
        try:
            return pose_matrices(trajectory, t)
        except LidarsimError:
            raise
        except Exception as exc:
            raise PluginError(f"trajectory '{trajectory.name}' failed: "
                              f"{type(exc).__name__}: {exc}") from exc

    def _chunk_poses(self, trajectory: Trajectory, t: np.ndarray, t_frame: float
                     ) -> PoseMatrices:
        """Poses for a piece's rays: one pose (applied to all) when it cannot vary."""
        frozen = self.scenario.scan.motion == "frozen"
        if not (frozen or trajectory.is_static):
            return self._poses(trajectory, t, t_frame)
        # one pose per trajectory (and frame, when frozen): looked up once, not per piece
        key = (id(trajectory), t_frame if frozen else None)
        pose = self._fixed_poses.get(key)
        if pose is None:
            pose = self._poses(trajectory, np.array([t_frame]), t_frame)
            if len(self._fixed_poses) > 256:
                self._fixed_poses.clear()
            self._fixed_poses[key] = pose
        return pose

    def _pulse_frames(self, batch: RayBatch, contexts: list[NoiseContext], t_frame: float
                      ) -> tuple[np.ndarray, list[np.ndarray],
                                 list[tuple[np.ndarray, list[np.ndarray]]], SceneRays]:
        """Directions flown (sensor frame), the beam's cross axes (u, v; sensor frame; empty
        without divergence), per target the sensor origin and those vectors in its body frame,
        and the scene-frame geometry (for stages that cast secondary rays)."""
        flown = batch.direction
        for model, ctx in zip(self.noise, contexts):
            flown = model.perturb_rays(flown, batch.index, ctx)
        axes = list(perpendicular_basis(flown)) if self.sub_rays is not None else []
        posed = piece_poses(self, batch, t_frame)
        origin_scene = posed.sensor.position
        scene = [rotate(posed.sensor, vec) for vec in (flown, *axes)]
        bodies = []
        for poses in posed.targets:
            bodies.append((to_body(poses, origin_scene),
                           [rotate(poses, vec, inverse=True) for vec in scene]))
        return flown, axes, bodies, SceneRays(origin_scene, scene, posed.sensor,
                                              list(posed.targets))

    def _body_rays(self, batch: RayBatch, contexts: list[NoiseContext], t_frame: float
                   ) -> tuple[np.ndarray, list[tuple[np.ndarray, np.ndarray]]]:
        """Directions flown (sensor frame) and, per target, the rays in its body frame (one
        ray per pulse: the pulses' central rays)."""
        flown, _, bodies, _ = self._pulse_frames(batch, contexts, t_frame)
        return flown, [(np.broadcast_to(origin, vecs[0].shape), vecs[0])
                       for origin, vecs in bodies]

    def _cast(self, batch: RayBatch, contexts: list[NoiseContext], t_frame: float,
              frame: int = 0) -> Piece:
        """Cast every (sub-)ray of the pulses on every target; the closest target wins."""
        flown, axes, bodies, scene = self._pulse_frames(batch, contexts, t_frame)
        k = self.rays_per_pulse
        n = len(batch) * k
        best = np.full(n, np.inf)
        target_id = np.full(n, -1, dtype=np.int16)
        face = np.full(n, -1, dtype=np.int64)
        part = np.full(n, -1, dtype=np.int16)
        cos_inc = np.zeros(n)
        normal = np.zeros((n, 3)) if self.keep_normals else None
        for j, (target, (origin, vecs)) in enumerate(zip(self.targets, bodies)):
            if self.sub_rays is None:
                d_body = vecs[0]
            else:  # K sub-rays per pulse, formed from the rotated axes: one batch of N·K rays
                d_body = self.sub_rays.directions(*vecs)
                if len(origin) > 1:
                    origin = np.repeat(origin, k, axis=0)
            hits = self.backend.cast(target.mesh, np.broadcast_to(origin, d_body.shape), d_body)
            closer = np.flatnonzero(hits.hit & (hits.distance < best))
            hit_face = hits.face[closer]
            best[closer] = hits.distance[closer]
            target_id[closer] = j
            face[closer] = hit_face
            part[closer] = target.mesh.face_part[hit_face] + target.part_offset
            cos_inc[closer] = np.abs(rowdot(hits.normal[closer], d_body[closer]))
            if normal is not None:
                normal[closer] = hits.normal[closer]
        hits = SubRayHits(best, target_id, face, part, cos_inc, normal)
        return Piece(batch, frame, contexts, flown, axes, hits, scene)

    def _process(self, batch: RayBatch, contexts: list[NoiseContext], t_frame: float,
                 frame: int = 0) -> dict[str, np.ndarray]:
        """Cast a piece of pulses, run the measurement stages in order, record the points."""
        piece = self._cast(batch, contexts, t_frame, frame)
        for stage in self.stages:
            stage.run(piece)
        return record_columns(self, piece)

    def frame_info(self, frame: int) -> FrameInfo:
        """Metadata of ``frame``: timing, poses at start and end, provenance."""
        return self.frame_infos([frame])[0]

    def frame_infos(self, frames: Sequence[int]) -> list[FrameInfo]:
        """:meth:`frame_info` of each of ``frames``, every trajectory evaluated once for all
        (:mod:`lidarsim_core.frameinfo`; the same bits as one frame at a time)."""
        from .frameinfo import frame_infos

        return frame_infos(self, frames)

    def measurement_info(self) -> dict[str, Any]:
        """The measurement model beyond the seed paper's, for frame metadata (empty when
        none of beam, detection and false alarms is on)."""
        info: dict[str, Any] = {}
        if self.link is not None:
            info["link_budget"] = {"constant": self.link.constant,
                                   "exponent": self.link.exponent,
                                   "threshold_to_noise": self.link.threshold_to_noise,
                                   "range_limit_m": self.range_limit}
        if self.sub_rays is not None:
            info["beam"] = {"sub_rays": self.sub_rays.count,
                            "range_resolution_m": self.range_resolution_m}
        for stage in self.stages:  # the optional stages describe themselves
            if hasattr(stage, "info"):
                info[stage.name] = stage.info()
        if info or self.spurious:
            info["return_mode"] = self.return_mode
            if self.return_mode == "dual":
                info["dual_return"] = self.dual_return
            if self.return_mode == "multi":
                info["max_returns"] = self.max_returns
        return {"measurement": info} if info else {}

    def run_frame(self, frame: int = 0, chunk_rays: int | None = None) -> PointCloud:
        """Simulate one frame and return its point cloud."""
        if not 0 <= frame < self.scenario.scan.frames:
            raise ConfigError(f"frame {frame} is outside 0..{self.scenario.scan.frames - 1}",
                              source=self.scenario.source, field="scan.frames")
        chunks = list(self.iter_chunks(frame, chunk_rays))
        return PointCloud.concatenate(chunks, self.frame_info(frame))


def as_scenario(scenario: Scenario | str | Path | dict[str, Any]) -> Scenario:
    """Accept a :class:`Scenario`, a path to a scenario file, or a mapping."""
    if isinstance(scenario, Scenario):
        return scenario
    if isinstance(scenario, dict):
        return scenario_from_dict(scenario)
    return load_scenario(scenario)


def simulate(scenario: Scenario | str | Path | dict[str, Any], *, frame: int = 0,
             chunk_rays: int | None = None) -> PointCloud:
    """Simulate one frame of a scenario.

    Parameters
    ----------
    scenario
        A :class:`~lidarsim_core.scenario.Scenario`, a scenario file path, or a mapping.
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
