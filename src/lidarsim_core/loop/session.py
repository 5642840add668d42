"""The stepping API: a scan session opened from a scenario and stepped interval by interval.

Each :meth:`LoopSession.step` scans ``[t, t + dt)`` with the scenario's sensor, noise chain
and targets and returns that interval's point cloud, its frame metadata and the true relative
pose at its end. The chaser (the sensor's body) is *steered*: its pose at the step's end is
given (a pose, or a commanded impulse / constant acceleration in the target's LVLH frame
propagated with the Hill–Clohessy–Wiltshire equations, :mod:`.dynamics`), and every pulse of
the step sees the pose interpolated at its own time (constant velocity and rotation rate over
the step, :mod:`.steered`), so motion distortion stays right. Targets follow their scenario
trajectories unless they are named in ``steer_targets``.

Step ``j`` is frame ``j`` of a scenario run: its noise streams are frame ``j``'s, its ray
indices are the pattern's indices of its interval (so they continue from step to step), and
with steps of one ``dt`` its interval is ``start + j·dt .. + dt``, the scenario's own
arithmetic. :meth:`LoopSession.record` writes the steered poses as keyframe files and a
scenario that ``lidarsim simulate`` / ``lidarsim dataset`` replay to the bit.
"""

from __future__ import annotations

from dataclasses import dataclass
from pathlib import Path
from typing import Any, Mapping, Sequence

import numpy as np

from ..base.errors import ConfigError
from ..pipeline.context import Target
from ..pipeline.simulation import Simulation
from ..records.pointcloud import FrameInfo, PointCloud
from ..scenario.load import as_scenario
from ..scenario.model import Scenario
from ..trajectories.attitude import LookAtAttitude
from ..trajectories.base import Trajectory
from ..trajectories.hcw import HCWTrajectory
from .dynamics import propagate
from .pointing import Pointing
from .record import write_record
from .steered import SteeredPath

_SOURCE = "<loop step>"


@dataclass(frozen=True)
class ChaserState:
    """The steered chaser at an instant, LVLH (the scene frame of a rendezvous scenario).

    Attributes
    ----------
    t_s
        Time (s from the scenario epoch).
    position_m, velocity_m_s
        (3,) position and velocity.
    quaternion_xyzw
        (4,) body → scene rotation, scalar-last.
    """

    t_s: float
    position_m: np.ndarray
    velocity_m_s: np.ndarray
    quaternion_xyzw: np.ndarray


@dataclass(frozen=True)
class StepResult:
    """What one step gives back.

    Attributes
    ----------
    cloud
        The interval's point cloud (sensor frame, ground truth per point); ``cloud.frame``
        is its frame metadata.
    state
        The chaser at the step's end.
    """

    cloud: PointCloud
    state: ChaserState

    @property
    def info(self) -> FrameInfo:
        """The frame metadata (timing, poses at start and end, provenance)."""
        return self.cloud.frame

    def target_in_sensor(self, index: int = 0) -> tuple[np.ndarray, np.ndarray]:
        """True pose of target ``index`` in the sensor frame at the step's end:
        ``(translation_m, quaternion_xyzw)``, ``x_sensor = R · x_body + t``."""
        rec = self.cloud.frame.targets_in_sensor_end[index]
        return np.array(rec["translation_m"]), np.array(rec["quaternion_xyzw"])


def _vector(value: Any, size: int, name: str) -> np.ndarray:
    arr = np.asarray(value, dtype=np.float64).reshape(-1)
    if arr.shape != (size,) or not np.all(np.isfinite(arr)):
        raise ConfigError(f"needs {size} finite numbers, got {value!r}", source=_SOURCE,
                          field=name)
    return arr


class LoopSession:
    """A scan session stepped by a guidance loop (see the module docstring).

    Parameters
    ----------
    scenario
        A scenario (object, file or mapping), or a built :class:`Simulation` to reuse (its
        acceleration structures and compiled kernels are then warm; the session changes
        nothing in it between steps).
    steer_sensor
        Steer the chaser (default). With ``False`` it flies the scenario's own sensor
        trajectory and a step takes no command.
    steer_targets
        Names of targets whose poses the steps give (the others follow the scenario).
    seed
        Seed of the noise (default: the scenario's).
    start_s
        Time of the first step's start (default: the scenario's ``scan.start_s``).
    mean_motion_rad_s
        Mean motion for Δv / acceleration commands (default: the orbit of the scenario's
        ``hcw`` sensor trajectory).
    position_m, quaternion_xyzw
        The chaser's pose at the start (default: its scenario trajectory's; the rotation
        defaults to the attitude law at a given position).
    velocity_m_s
        The chaser's LVLH velocity at the start (default: the ``hcw`` trajectory's, else 0).
    chunk_rays
        Rays per processing chunk (results do not depend on it).
    """

    def __init__(self, scenario: Scenario | Simulation | str | Path | Mapping[str, Any], *,
                 steer_sensor: bool = True, steer_targets: Sequence[str] = (),
                 seed: int | None = None, start_s: float | None = None,
                 mean_motion_rad_s: float | None = None, position_m: Any = None,
                 quaternion_xyzw: Any = None, velocity_m_s: Any = None,
                 chunk_rays: int | None = None) -> None:
        sim = scenario if isinstance(scenario, Simulation) else \
            Simulation(as_scenario(scenario))  # type: ignore[arg-type]
        self.simulation = sim
        ctx = sim.context
        base = ctx.scenario
        self.scenario: Scenario = base if seed is None or seed == base.seed else \
            base.with_updates(seed=int(seed))
        self.chunk_rays = chunk_rays
        self.start_s = float(base.scan.start_s if start_s is None else start_s)
        names = [t.name for t in ctx.targets]
        unknown = [n for n in steer_targets if n not in names]
        if unknown:
            raise ConfigError(f"no target named {unknown[0]!r}; targets: {', '.join(names)}",
                              source=_SOURCE, field="steer_targets")
        #: The scenario's own trajectories (the bodies not steered keep flying them).
        self._sensor_trajectory: Trajectory = ctx.sensor_trajectory
        self._targets: list[Target] = list(ctx.targets)
        traj = self._sensor_trajectory
        hcw = traj if isinstance(traj, HCWTrajectory) else None
        self.mean_motion = mean_motion_rad_s if mean_motion_rad_s is not None else \
            (hcw.n if hcw is not None else None)
        #: The chaser's attitude law when a step gives no rotation (the ``hcw``
        #: trajectory's, else boresight at the target's centre).
        self.pointing = Pointing(hcw.options.attitude if hcw is not None else LookAtAttitude())
        t0 = np.array([self.start_s])
        self.steer_sensor = bool(steer_sensor)
        self.sensor_path: SteeredPath | None = None
        if not self.steer_sensor and (position_m is not None or quaternion_xyzw is not None):
            raise ConfigError("a start pose needs a steered sensor (steer_sensor=True)",
                              source=_SOURCE, field="position_m")
        if self.steer_sensor:
            pose = traj.poses_at(t0)
            p0, q0 = pose.position[0], pose.rotation.as_quat()[0]
            if position_m is not None:
                p0 = _vector(position_m, 3, "position_m")
                q0 = self._quaternion(p0, quaternion_xyzw)
            elif quaternion_xyzw is not None:
                q0 = self._quaternion(p0, quaternion_xyzw)
            self.sensor_path = SteeredPath()
            self.sensor_path.add(self.start_s, p0, q0)
        if velocity_m_s is not None:
            self._velocity = _vector(velocity_m_s, 3, "velocity_m_s")
        elif hcw is not None:
            self._velocity = hcw.states_at(t0)[1][0]
        else:
            self._velocity = np.zeros(3)
        self.target_paths: dict[int, SteeredPath] = {}
        for name in steer_targets:
            i = names.index(name)
            pose = self._targets[i].trajectory.poses_at(t0)
            path = SteeredPath()
            path.add(self.start_s, pose.position[0], pose.rotation.as_quat()[0])
            self.target_paths[i] = path
        self.frame = 0
        self.time_s = self.start_s
        #: The step length while every step had the same (None after one differed).
        self.uniform_dt: float | None = None
        self._uniform = True

    # ---- state -----------------------------------------------------------------------
    @property
    def state(self) -> ChaserState:
        """The chaser now (the end of the last step)."""
        if self.sensor_path is not None:
            p, q = self.sensor_path.positions[-1], self.sensor_path.quaternions[-1]
        else:
            pose = self._sensor_trajectory.poses_at(np.array([self.time_s]))
            p, q = pose.position[0], pose.rotation.as_quat()[0]
        return ChaserState(self.time_s, p.copy(), self._velocity.copy(), q.copy())

    def _interval(self, dt: float) -> tuple[float, float]:
        if self._uniform and self.uniform_dt in (None, dt):
            t0 = self.start_s + self.frame * dt  # ScanConfig.frame_interval's arithmetic
            return t0, t0 + dt
        return self.time_s, self.time_s + dt

    # ---- stepping --------------------------------------------------------------------
    def step(self, dt: float | None = None, *, position_m: Any = None,
             quaternion_xyzw: Any = None, velocity_m_s: Any = None, delta_v_m_s: Any = None,
             acceleration_m_s2: Any = None,
             targets: Mapping[str, tuple[Any, Any]] | None = None) -> StepResult:
        """Scan the next interval and move the steered bodies to their poses at its end.

        Parameters
        ----------
        dt
            Length of the interval (s; default the scenario's ``scan.duration_s``).
        position_m, quaternion_xyzw
            The chaser's pose at the step's end (LVLH / scene frame; the rotation defaults to
            the attitude law at that position).
        velocity_m_s
            Its velocity at the end (default: the mean velocity over the step).
        delta_v_m_s
            An impulse at the step's start (LVLH, m/s); the chaser then moves by the HCW
            equations (with no command: natural motion).
        acceleration_m_s2
            A constant acceleration over the step (LVLH, m/s²), with or without ``delta_v``.
        targets
            For steered targets: name → ``(position_m, quaternion_xyzw)`` at the step's end
            (a steered target not named holds its pose).

        Returns
        -------
        StepResult
            The interval's cloud and metadata, and the chaser's state at its end.
        """
        scan = self.scenario.scan
        dt = float(scan.duration_s if dt is None else dt)
        if not (np.isfinite(dt) and dt > 0):
            raise ConfigError(f"the step must last a positive time, got {dt!r}",
                              source=_SOURCE, field="dt")
        t0, t1 = self._interval(dt)
        commanded = delta_v_m_s is not None or acceleration_m_s2 is not None
        posed = position_m is not None or quaternion_xyzw is not None
        velocity = self._velocity
        if not self.steer_sensor:
            if commanded or posed or velocity_m_s is not None:
                raise ConfigError("the session flies the scenario's sensor trajectory "
                                  "(steer_sensor=False): a step takes no chaser command",
                                  source=_SOURCE, field="step")
            velocity = self._scenario_velocity(t0, t1)
        elif posed:
            if commanded:
                raise ConfigError("give the chaser's pose or a Δv / acceleration, not both",
                                  source=_SOURCE, field="position_m")
            if position_m is None:
                raise ConfigError("a rotation needs its position", source=_SOURCE,
                                  field="position_m")
            p1 = _vector(position_m, 3, "position_m")
            start = self.sensor_path.positions[-1]  # type: ignore[union-attr]
            velocity = (p1 - start) / (t1 - t0) if velocity_m_s is None else \
                _vector(velocity_m_s, 3, "velocity_m_s")
            q1 = self._quaternion(p1, quaternion_xyzw)
        else:
            if self.mean_motion is None:
                raise ConfigError("a Δv or acceleration command needs the target's orbit: "
                                  "give mean_motion_rad_s, or fly an 'hcw' sensor trajectory",
                                  source=_SOURCE, field="delta_v_m_s")
            dv = None if delta_v_m_s is None else _vector(delta_v_m_s, 3, "delta_v_m_s")
            acc = None if acceleration_m_s2 is None else \
                _vector(acceleration_m_s2, 3, "acceleration_m_s2")
            p1, velocity = propagate(self.sensor_path.positions[-1],  # type: ignore[union-attr]
                                     self._velocity, self.mean_motion, t1 - t0,
                                     delta_v=dv, acceleration=acc)
            q1 = self._quaternion(p1, None)
        given = dict(targets or {})
        names = [t.name for t in self._targets]
        for name in given:
            if name not in names or names.index(name) not in self.target_paths:
                raise ConfigError(f"target {name!r} is not steered (steer_targets)",
                                  source=_SOURCE, field=f"targets.{name}")
        added: list[SteeredPath] = []
        try:
            if self.sensor_path is not None:
                self.sensor_path.add(t1, p1, q1)
                added.append(self.sensor_path)
            for i, path in self.target_paths.items():
                if names[i] in given:
                    pos, quat = given[names[i]]
                    path.add(t1, _vector(pos, 3, f"targets.{names[i]}"),
                             _vector(quat, 4, f"targets.{names[i]}"))
                else:
                    path.add(t1, path.positions[-1], path.quaternions[-1])
                added.append(path)
            cloud = self._scan(t0, t1)
        except BaseException:
            for path in added:
                path.drop_last()
            raise
        if self._uniform and self.uniform_dt not in (None, dt):
            self._uniform = False
        self.uniform_dt = dt if self._uniform else None
        self.frame += 1
        self.time_s = t1
        self._velocity = np.asarray(velocity, dtype=np.float64)
        return StepResult(cloud, self.state)

    def _scenario_velocity(self, t0: float, t1: float) -> np.ndarray:
        """The unsteered chaser's velocity at ``t1``: the ``hcw`` trajectory's, else the mean
        over the step."""
        traj = self._sensor_trajectory
        if isinstance(traj, HCWTrajectory):
            return traj.states_at(np.array([t1]))[1][0]
        p = traj.poses_at(np.array([t0, t1])).position
        return (p[1] - p[0]) / (t1 - t0)

    def _quaternion(self, position: np.ndarray, quaternion: Any) -> np.ndarray:
        if quaternion is not None:
            q = _vector(quaternion, 4, "quaternion_xyzw")
            if np.linalg.norm(q) < 1e-12:
                raise ConfigError("the quaternion has zero norm", source=_SOURCE,
                                  field="quaternion_xyzw")
            return q
        return self.pointing.quaternion(position)

    def _scan(self, t0: float, t1: float) -> PointCloud:
        sim = self.simulation
        ctx = sim.context
        saved = (ctx.scenario, ctx.sensor_trajectory, ctx.targets)
        try:
            ctx.scenario = self.scenario
            if self.sensor_path is not None:
                ctx.sensor_trajectory = self.sensor_path.trajectory()
            if self.target_paths:
                ctx.targets = [Target(t.name, t.mesh, self.target_paths[i].trajectory(),
                                      t.part_offset) if i in self.target_paths else t
                               for i, t in enumerate(self._targets)]
            chunks = list(sim.iter_span_chunks(self.frame, t0, t1, self.chunk_rays))
            info = sim.frame_infos([self.frame], [(t0, t1)])[0]
        finally:
            ctx.scenario, ctx.sensor_trajectory, ctx.targets = saved
        return PointCloud.concatenate(chunks, info)

    # ---- the record ------------------------------------------------------------------
    def record(self, path: str | Path, *, overwrite: bool = True) -> Path:
        """Write the session as a scenario that replays its frames to the bit.

        ``path`` is the scenario file (``.yaml``); each steered body's keyframes go beside
        it as ``<stem>.<body>.csv`` (``sensor`` or the target's name). Needs steps of one
        length (a scenario's frames are evenly spaced).

        Returns
        -------
        Path
            The scenario file.
        """
        paths: dict[str, SteeredPath] = {}
        if self.sensor_path is not None:
            paths["sensor"] = self.sensor_path
        for i, steered in self.target_paths.items():
            paths[self._targets[i].name] = steered
        return write_record(Path(path), self.scenario, paths, start_s=self.start_s,
                            dt=self.uniform_dt, frames=self.frame, overwrite=overwrite)
