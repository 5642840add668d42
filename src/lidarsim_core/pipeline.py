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
from typing import Any, Iterator

import numpy as np

from ._version import __version__
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
from .noise.base import NoiseContext, NoiseModel, Returns, perpendicular_basis
from .noise.outliers import SpuriousReturnModel
from .noise.streams import for_return
from .patterns.base import RayBatch, ScanPattern
from .patterns.geometry import az_el_from_directions
from .plugins import get_registry
from .pointcloud import FrameInfo, PointCloud
from .poses import Poses
from .radiometry import LinkBudget, detection_range_limit, link_budget
from .registry import Registry
from .returns import Candidates, ReturnsConfig, SubRayHits, group_sub_rays, select_returns
from .rng import ray_uniforms
from .scenario import NamedComponent, Scenario, load_scenario, scenario_from_dict
from .trajectories.base import Trajectory
from .vec3 import rowdot, scale_rows

DEFAULT_NOISE_CHAIN = ("angular", "range")
#: Most rays per unit of work handed to a pipeline thread (a chunk is split into such pieces,
#: about one per thread; with K sub-rays per pulse a piece holds PIECE_RAYS / K pulses).
PIECE_RAYS = 65536
#: Part label of false alarms (appended to the scene's parts when a model makes them).
FALSE_ALARM_PART = "noise/false_alarm"
#: Random stream of the detection draws.
DETECTION_STREAM = "detection"


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
        self._fixed_poses: dict[tuple[int, float | None], Poses] = {}
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
        if self.spurious:
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
        return self.pattern.index_range(t0, t1)

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
                                 list[tuple[np.ndarray, list[np.ndarray]]]]:
        """Directions flown (sensor frame), the beam's cross axes (u, v; sensor frame; empty
        without divergence) and, per target, the sensor origin and those vectors in its body
        frame."""
        flown = batch.direction
        for model, ctx in zip(self.noise, contexts):
            flown = model.perturb_rays(flown, batch.index, ctx)
        axes = list(perpendicular_basis(flown)) if self.sub_rays is not None else []
        sensor_poses = self._chunk_poses(self.sensor_trajectory, batch.t, t_frame)
        origin_scene = sensor_poses.position
        scene = [rotate(sensor_poses, vec) for vec in (flown, *axes)]
        bodies = []
        for target in self.targets:
            poses = self._chunk_poses(target.trajectory, batch.t, t_frame)
            bodies.append((to_body(poses, origin_scene),
                           [rotate(poses, vec, inverse=True) for vec in scene]))
        return flown, axes, bodies

    def _body_rays(self, batch: RayBatch, contexts: list[NoiseContext], t_frame: float
                   ) -> tuple[np.ndarray, list[tuple[np.ndarray, np.ndarray]]]:
        """Directions flown (sensor frame) and, per target, the rays in its body frame (one
        ray per pulse: the pulses' central rays)."""
        flown, _, bodies = self._pulse_frames(batch, contexts, t_frame)
        return flown, [(np.broadcast_to(origin, vecs[0].shape), vecs[0])
                       for origin, vecs in bodies]

    def _cast(self, batch: RayBatch, contexts: list[NoiseContext], t_frame: float
              ) -> tuple[np.ndarray, list[np.ndarray], SubRayHits]:
        """Cast every (sub-)ray of the pulses on every target; the closest target wins."""
        flown, axes, bodies = self._pulse_frames(batch, contexts, t_frame)
        k = self.rays_per_pulse
        n = len(batch) * k
        best = np.full(n, np.inf)
        target_id = np.full(n, -1, dtype=np.int16)
        face = np.full(n, -1, dtype=np.int64)
        part = np.full(n, -1, dtype=np.int16)
        cos_inc = np.zeros(n)
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
        return flown, axes, SubRayHits(best, target_id, face, part, cos_inc)

    def _candidates(self, batch: RayBatch, hits: SubRayHits,
                    contexts: list[NoiseContext]) -> Candidates:
        """Candidate returns of the pulses, sorted by (pulse, range)."""
        link = self.link
        exponent = link.exponent if link is not None else 2.0
        if self.sub_rays is None:
            idx = np.flatnonzero(hits.target >= 0)
            rng = hits.distance[idx]
            part, cos_inc = hits.part[idx], hits.cos_incidence[idx]
            rho = self.materials.effective(part, cos_inc)
            power = rho / rng ** exponent
            zeros = np.zeros(len(idx), dtype=np.int64)
            cand = Candidates(idx, zeros, rng, rng, zeros,
                              link.constant * power if link is not None else power, rho,
                              hits.target[idx], hits.face[idx], part, cos_inc)
        else:
            k = self.sub_rays.count
            pulse, rank, rng, flat, power, rng_true = group_sub_rays(
                hits, k, self.sub_rays.weights, self.materials.effective, exponent,
                self.range_resolution_m)
            cand = Candidates(pulse, rank, rng, rng_true, flat % k,
                              link.constant * power if link is not None else power,
                              power * rng ** exponent, hits.target[flat], hits.face[flat],
                              hits.part[flat], hits.cos_incidence[flat])
        extra = [self._false_alarms(batch, model, contexts[i]) for i, model in self.spurious]
        extra = [c for c in extra if len(c)]
        return Candidates.concatenate([cand, *extra]) if extra else cand

    def _false_alarms(self, batch: RayBatch, model: SpuriousReturnModel,
                      ctx: NoiseContext) -> Candidates:
        rng = model.spurious_ranges(batch.index, ctx, self.sensor.range_min_m, self.range_limit)
        pulse = np.flatnonzero(np.isfinite(rng))
        rng = rng[pulse]
        m = len(pulse)
        # a false alarm just crosses the threshold: S = 1 (0 without a calibrated budget)
        signal = np.ones(m) if self.link is not None else np.zeros(m)
        intensity = (self.link.apparent_reflectivity(signal, rng) if self.link is not None
                     else np.zeros(m))
        return Candidates(pulse, np.full(m, -1, dtype=np.int64), rng, np.full(m, np.nan),
                          np.zeros(m, dtype=np.int64), signal, intensity,
                          np.full(m, -1, dtype=np.int16), np.full(m, -1, dtype=np.int64),
                          np.full(m, self.false_alarm_part, dtype=np.int16), np.full(m, np.nan))

    def _detected(self, batch: RayBatch, cand: Candidates, frame: int) -> np.ndarray:
        """Which candidates the sensor detects: range gate, then the link budget's draw."""
        sheet = self.sensor
        detected = (cand.range >= sheet.range_min_m) & (cand.range <= self.range_limit)
        if self.link is None or not len(cand):
            return detected
        real = cand.group >= 0
        draws = ray_uniforms(self.scenario.seed, frame, DETECTION_STREAM,
                             batch.index[cand.pulse], self.rays_per_pulse)
        draw = draws[np.arange(len(cand)), np.maximum(cand.group, 0)]
        return detected & (~real | (draw < self.link.detection_probability(cand.signal)))

    def _reported(self, cand: Candidates, detected: np.ndarray
                  ) -> tuple[np.ndarray, np.ndarray, np.ndarray, np.ndarray]:
        """Rows of ``cand`` written to the record (the return mode's picks, plus the
        undetected ones when kept), whether each was detected, and their return numbers and
        returns per pulse (0 for undetected ones)."""
        det = np.flatnonzero(detected)
        pulse = cand.pulse[det]
        if len(det) > 1 and bool((pulse[1:] == pulse[:-1]).any()):
            keep, number, count = select_returns(pulse, cand.signal[det], self.return_mode,
                                                 dual=self.dual_return,
                                                 max_returns=self.max_returns)
            det, number, count = det[keep], number[keep], count[keep]
        else:  # at most one detected return per pulse: every mode reports it
            number = count = np.ones(len(det), dtype=np.uint8)
        if not self.keep_undetected:
            return det, np.ones(len(det), dtype=bool), number, count
        rows = np.sort(np.concatenate([det, np.flatnonzero(~detected)]))
        where = np.searchsorted(rows, det)
        number_all = np.zeros(len(rows), dtype=np.uint8)
        count_all = np.zeros(len(rows), dtype=np.uint8)
        number_all[where], count_all[where] = number, count
        return rows, detected[rows], number_all, count_all

    def _process(self, batch: RayBatch, contexts: list[NoiseContext], t_frame: float,
                 frame: int = 0) -> dict[str, np.ndarray]:
        flown, axes, hits = self._cast(batch, contexts, t_frame)
        cand = self._candidates(batch, hits, contexts)
        rows, flag, number, count = self._reported(cand, self._detected(batch, cand, frame))
        pulse = cand.pulse[rows]
        direction = flown[pulse]
        range_measured = cand.range[rows]
        direction_measured = direction
        reported = np.flatnonzero(flag)
        if len(reported) == len(rows):
            range_measured, direction_measured = self._noise(
                batch, contexts, pulse, direction, cand.range_true[rows], range_measured, number)
        else:  # noise on the reported returns only; kept undetected ones stay noiseless
            range_measured, direction_measured = range_measured.copy(), direction.copy()
            r_meas, d_meas = self._noise(batch, contexts, pulse[reported], direction[reported],
                                         cand.range_true[rows][reported],
                                         range_measured[reported], number[reported])
            range_measured[reported], direction_measured[reported] = r_meas, d_meas
        measured = scale_rows(direction_measured, range_measured)
        range_true = cand.range_true[rows]
        if self.sub_rays is None:
            true = scale_rows(direction, range_true)
        else:  # the strongest sub-ray's own surface point
            true = scale_rows(self.sub_rays.direction_of(cand.sub_ray[rows], direction,
                                                         axes[0][pulse], axes[1][pulse]),
                              range_true)
        azimuth, elevation = az_el_from_directions(batch.direction[pulse])
        return {
            "x": measured[:, 0], "y": measured[:, 1], "z": measured[:, 2],
            "x_true": true[:, 0], "y_true": true[:, 1], "z_true": true[:, 2],
            "range": range_measured, "range_true": range_true,
            "azimuth": azimuth, "elevation": elevation, "timestamp": batch.t[pulse],
            "return_number": number, "number_of_returns": count,
            "channel": batch.channel[pulse], "ray_index": batch.index[pulse],
            "face_index": cand.face[rows], "target": cand.target[rows], "part": cand.part[rows],
            "incidence_angle": np.arccos(np.clip(cand.cos_incidence[rows], 0.0, 1.0)),
            "intensity": cand.intensity[rows].astype(np.float32),
            "detected": flag.astype(np.uint8),
        }

    def _noise(self, batch: RayBatch, contexts: list[NoiseContext], pulse: np.ndarray,
               direction: np.ndarray, range_true: np.ndarray, range_measured: np.ndarray,
               number: np.ndarray) -> tuple[np.ndarray, np.ndarray]:
        """Return-stage noise of reported returns; return r > 1 of a pulse draws from its own
        streams (:func:`~lidarsim_core.noise.streams.for_return`)."""
        if len(number) == 0 or number.min() == number.max():  # the usual case: one value
            numbers = number[:1]
        else:
            numbers = np.unique(number)
        if len(numbers) <= 1:
            r = int(numbers[0]) if len(numbers) else 1
            returns = Returns(batch.index[pulse], direction, range_true, range_measured.copy(),
                              direction)
            for model, ctx in zip(self.noise, contexts):
                returns = model.perturb_returns(returns, for_return(ctx, r))
            return returns.range_measured, returns.direction_measured
        out_range = np.empty(len(pulse))
        out_direction = np.empty((len(pulse), 3))
        for r in numbers:
            sel = np.flatnonzero(number == r)
            out_range[sel], out_direction[sel] = self._noise(
                batch, contexts, pulse[sel], direction[sel], range_true[sel],
                range_measured[sel], number[sel])
        return out_range, out_direction

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
            software=f"lidarsim-core {__version__}", extra=self.measurement_info())

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
