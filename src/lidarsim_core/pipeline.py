"""The simulation pipeline: scenario → rays → poses → ray casting → noise → point record.

For every chunk of rays (vectorised throughout):

1. the scan pattern gives each ray's index, emission time, nominal direction and channel;
2. ray-stage noise models perturb the directions actually flown (paper: angular error);
3. the sensor and every target pose are looked up at each ray's time (or at frame start when
   ``scan.motion`` is ``frozen``) and the rays are moved into each target's body frame;
4. the backend finds the first hit on every target; the closest target wins;
5. hits outside ``[range_min_m, range_max_m]`` are not detected;
6. return-stage noise models perturb the reported range/direction (paper: range error, Eq. 4);
7. the point record is assembled in the sensor frame at the ray's emission time.
"""

from __future__ import annotations

from dataclasses import dataclass
from pathlib import Path
from typing import Any, Iterator

import numpy as np

from ._version import __version__
from .backends.base import RayBackend
from .builtin_sensors import get_sensor
from .chunks import ordered_map, rotate, split_range, to_body, worker_threads
from .config_io import validate_model
from .datasheet import SensorDatasheet
from .errors import ConfigError, LidarsimError, PluginError
from .mesh import Mesh, load_mesh_file
from .noise.base import NoiseContext, NoiseModel, Returns
from .patterns.base import RayBatch, ScanPattern
from .patterns.geometry import az_el_from_directions
from .plugins import get_registry
from .pointcloud import FrameInfo, PointCloud
from .poses import Poses
from .registry import Registry
from .scenario import NamedComponent, Scenario, load_scenario, scenario_from_dict
from .trajectories.base import Trajectory

DEFAULT_NOISE_CHAIN = ("angular", "range")
#: Rays per unit of work handed to a pipeline thread (a chunk is split into such pieces).
PIECE_RAYS = 16384


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
        mesh = model.mesh()
        if cfg.scale != 1.0:
            mesh = Mesh.from_arrays(mesh.vertices * cfg.scale, mesh.faces, mesh.face_part,
                                    mesh.part_names, name=mesh.name)
        return mesh

    # ---- running ------------------------------------------------------------------------
    def frame_rays(self, frame: int) -> tuple[int, int]:
        """Global ray index range ``[k0, k1)`` of ``frame``."""
        t0, t1 = self.scenario.scan.frame_interval(frame)
        return self.pattern.index_range(t0, t1)

    def _noise_contexts(self, frame: int) -> list[NoiseContext]:
        return [NoiseContext(self.sensor, self.scenario.seed, frame, f"noise.{i}.{m.name}")
                for i, m in enumerate(self.noise)]

    def iter_chunks(self, frame: int, chunk_rays: int | None = None
                    ) -> Iterator[dict[str, np.ndarray]]:
        """Point-record columns of ``frame``, one dictionary per chunk of emitted rays.

        Each chunk is processed in pieces of at most :data:`PIECE_RAYS` rays on
        :func:`~lidarsim_core.chunks.worker_threads` threads (``LIDARSIM_THREADS``; one thread
        if the backend is not ``thread_safe``); every ray's result depends only on its index,
        so neither setting changes the output.
        """
        chunk = chunk_rays or self.scenario.chunk_rays
        k0, k1 = self.frame_rays(frame)
        contexts = self._noise_contexts(frame)
        t_frame = self.scenario.scan.frame_interval(frame)[0]
        for target in self.targets:  # build acceleration structures before the workers start
            self.backend.prepared(target.mesh)
        pieces = [(c, lo, hi) for c, (start, stop) in enumerate(split_range(k0, k1, chunk))
                  for lo, hi in split_range(start, stop, PIECE_RAYS)]

        def work(piece: tuple[int, int, int]) -> dict[str, np.ndarray]:
            batch = self.pattern.rays_for_indices(np.arange(piece[1], piece[2], dtype=np.int64))
            return self._process(batch, contexts, t_frame)

        def merged(parts: list[dict[str, np.ndarray]]) -> dict[str, np.ndarray]:
            if len(parts) == 1:
                return parts[0]
            return {key: np.concatenate([p[key] for p in parts]) for key in parts[0]}

        done: list[dict[str, np.ndarray]] = []
        current = 0
        workers = worker_threads() if self.backend.thread_safe else 1
        for (c, _, _), columns in zip(pieces, ordered_map(work, pieces, workers)):
            if c != current:
                yield merged(done)
                done, current = [], c
            done.append(columns)
        if done:
            yield merged(done)

    def _poses(self, trajectory: Trajectory, t: np.ndarray, t_frame: float) -> Poses:
        if self.scenario.scan.motion == "frozen":
            t = np.full_like(t, t_frame)
        try:
            return trajectory.poses_at(t)
        except LidarsimError:
            raise
        except Exception as exc:
            raise PluginError(f"trajectory '{trajectory.name}' failed: "
                              f"{type(exc).__name__}: {exc}") from exc

    def _chunk_poses(self, trajectory: Trajectory, t: np.ndarray, t_frame: float) -> Poses:
        """Poses for a piece's rays: one pose (applied to all) when it cannot vary."""
        if self.scenario.scan.motion == "frozen" or trajectory.is_static:
            return self._poses(trajectory, t[:1], t_frame)
        return self._poses(trajectory, t, t_frame)

    def _body_rays(self, batch: RayBatch, contexts: list[NoiseContext], t_frame: float
                   ) -> tuple[np.ndarray, list[tuple[np.ndarray, np.ndarray]]]:
        """Directions flown (sensor frame) and, per target, the rays in its body frame."""
        flown = batch.direction
        for model, ctx in zip(self.noise, contexts):
            flown = model.perturb_rays(flown, batch.index, ctx)
        sensor_poses = self._chunk_poses(self.sensor_trajectory, batch.t, t_frame)
        origin_scene = sensor_poses.position
        dir_scene = rotate(sensor_poses, flown)
        bodies = []
        for target in self.targets:
            poses = self._chunk_poses(target.trajectory, batch.t, t_frame)
            d_body = rotate(poses, dir_scene, inverse=True)
            bodies.append((np.broadcast_to(to_body(poses, origin_scene), d_body.shape), d_body))
        return flown, bodies

    def _process(self, batch: RayBatch, contexts: list[NoiseContext],
                 t_frame: float) -> dict[str, np.ndarray]:
        flown, bodies = self._body_rays(batch, contexts, t_frame)
        n = len(batch)
        best = np.full(n, np.inf)
        target_id = np.full(n, -1, dtype=np.int16)
        face = np.full(n, -1, dtype=np.int64)
        part = np.full(n, -1, dtype=np.int16)
        cos_inc = np.zeros(n)
        for j, (target, (o_body, d_body)) in enumerate(zip(self.targets, bodies)):
            hits = self.backend.cast(target.mesh, o_body, d_body)
            closer = np.flatnonzero(hits.hit & (hits.distance < best))
            hit_face = hits.face[closer]
            best[closer] = hits.distance[closer]
            target_id[closer] = j
            face[closer] = hit_face
            part[closer] = target.mesh.face_part[hit_face] + target.part_offset
            cos_inc[closer] = np.abs(np.einsum("ij,ij->i", hits.normal[closer], d_body[closer]))
        sheet = self.sensor
        keep = (target_id >= 0) & (best >= sheet.range_min_m) & (best <= sheet.range_max_m)
        idx = np.flatnonzero(keep)
        returns = Returns(batch.index[idx], flown[idx], best[idx], best[idx].copy(), flown[idx])
        for model, ctx in zip(self.noise, contexts):
            returns = model.perturb_returns(returns, ctx)
        measured = returns.direction_measured * returns.range_measured[:, None]
        true = returns.direction_flown * returns.range_true[:, None]
        azimuth, elevation = az_el_from_directions(batch.direction[idx])
        ones = np.ones(len(idx), dtype=np.uint8)
        return {
            "x": measured[:, 0], "y": measured[:, 1], "z": measured[:, 2],
            "x_true": true[:, 0], "y_true": true[:, 1], "z_true": true[:, 2],
            "range": returns.range_measured, "range_true": returns.range_true,
            "azimuth": azimuth, "elevation": elevation, "timestamp": batch.t[idx],
            "return_number": ones, "number_of_returns": ones,
            "channel": batch.channel[idx], "ray_index": batch.index[idx],
            "face_index": face[idx], "target": target_id[idx], "part": part[idx],
            "incidence_angle": np.arccos(np.clip(cos_inc[idx], 0.0, 1.0)),
        }

    def frame_info(self, frame: int) -> FrameInfo:
        """Metadata of ``frame``: timing, poses at start and end, provenance."""
        t0, t1 = self.scenario.scan.frame_interval(frame)
        k0, k1 = self.frame_rays(frame)
        times = np.array([t0, t1])
        sensor = self.sensor_trajectory.poses_at(times)
        targets = [t.trajectory.poses_at(times) for t in self.targets]
        return FrameInfo(
            frame=frame, t_start=t0, t_end=t1, sensor=self.sensor.name,
            seed=self.scenario.seed, config_hash=self.scenario.config_hash(),
            backend=self.backend.name, noise=[m.name for m in self.noise],
            motion=self.scenario.scan.motion, target_names=[t.name for t in self.targets],
            part_names=self.part_names, rays_emitted=k1 - k0,
            sensor_pose_start=sensor[0].to_records()[0],
            sensor_pose_end=sensor[1].to_records()[0],
            target_poses_start=[p[0].to_records()[0] for p in targets],
            target_poses_end=[p[1].to_records()[0] for p in targets],
            targets_in_sensor=[p[0].relative_to(sensor[0]).to_records()[0] for p in targets],
            targets_in_sensor_end=[p[1].relative_to(sensor[1]).to_records()[0] for p in targets],
            software=f"lidarsim-core {__version__}")

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
