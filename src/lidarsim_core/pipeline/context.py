"""What the stages, culling, posing and checks of a run receive: the resolved scenario.

:class:`~lidarsim_core.pipeline.simulation.Simulation` resolves every name of a scenario
(sensor, pattern, noise chain, backend, trajectories, meshes, materials) and the measurement
model, and hands this small, read-only context down. Nothing below the simulation sees the
simulation itself, so each piece can be read, tested and replaced on its own.
"""

from __future__ import annotations

from dataclasses import dataclass, field
from functools import cached_property

import numpy as np

from ..backends.base import RayBackend
from ..base.errors import LidarsimError, PluginError
from ..geometry.posing import PoseMatrices
from ..instrument.beam import SubRays
from ..instrument.linkbudget import LinkBudget
from ..noise.base import NoiseContext, NoiseModel
from ..noise.outliers import SpuriousReturnModel
from ..patterns.base import ScanPattern
from ..scenario.datasheet import SensorDatasheet
from ..scenario.model import Scenario
from ..scene.materials import MaterialTable
from ..scene.mesh import Mesh
from ..trajectories.base import Trajectory
from ..trajectories.matrices import pose_matrices

#: Most fixed poses kept per run (one per static trajectory, and frame when frozen).
_FIXED_POSE_CACHE = 256


@dataclass
class Target:
    """A resolved target: label, mesh and trajectory.

    Attributes
    ----------
    name
        The target's name in the scenario.
    mesh
        Its triangle mesh (body frame).
    trajectory
        Its motion.
    part_offset
        Index of its first part among the run's scene-wide part labels.
    """

    name: str
    mesh: Mesh
    trajectory: Trajectory
    part_offset: int


@dataclass(eq=False)
class RunContext:
    """The resolved scenario: every component and measurement setting a run needs.

    Attributes
    ----------
    scenario
        The validated scenario.
    sensor
        The sensor's datasheet.
    pattern
        Its scan pattern.
    noise
        The noise chain, in order.
    backend
        The ray backend.
    sensor_trajectory
        The sensor's motion.
    targets
        The targets, in scenario order.
    part_names
        Scene-wide part labels (``target/part``, then the false-alarm part if any).
    materials
        Materials of every scene-wide part.
    spurious
        Noise models that add false alarms, with their chain positions.
    false_alarm_part
        Part index of false alarms (-1 when none can occur).
    link
        The calibrated link budget (None without ``sensor.detection``).
    range_limit
        Longest reported range (m).
    keep_undetected
        Whether missed returns are kept, flagged.
    return_mode, dual_return, max_returns
        The return mode and its settings.
    range_resolution_m
        Two surfaces farther apart give separate returns (None when not given).
    sub_rays
        The beam's sub-ray layout (None: one ray per pulse).
    keep_normals
        Whether the cast keeps hit normals (stages that cast secondary rays need them).
    """

    scenario: Scenario
    sensor: SensorDatasheet
    pattern: ScanPattern
    noise: list[NoiseModel]
    backend: RayBackend
    sensor_trajectory: Trajectory
    targets: list[Target]
    part_names: list[str]
    materials: MaterialTable
    spurious: list[tuple[int, SpuriousReturnModel]]
    false_alarm_part: int
    link: LinkBudget | None
    range_limit: float
    keep_undetected: bool
    return_mode: str
    dual_return: str
    max_returns: int
    range_resolution_m: float | None
    sub_rays: SubRays | None
    keep_normals: bool
    _fixed_poses: dict[tuple[int, float | None], PoseMatrices] = field(
        default_factory=dict, repr=False)

    @cached_property
    def config_hash(self) -> str:
        """The scenario's :meth:`~lidarsim_core.scenario.model.Scenario.config_hash`, made
        once: every frame's metadata carries it (a JSON dump and a SHA-256 of the scenario,
        ~40 µs a frame that held the GIL), and like every other part of the context it is
        the scenario's as the run was resolved."""
        return self.scenario.config_hash()

    @property
    def rays_per_pulse(self) -> int:
        """K: rays cast per emitted pulse (1 without beam divergence)."""
        return 1 if self.sub_rays is None else self.sub_rays.count

    def frame_start(self, frame: int) -> float:
        """Start time of ``frame`` (s)."""
        return self.scenario.scan.frame_interval(frame)[0]

    def noise_contexts(self, frame: int) -> list[NoiseContext]:
        """The noise chain's contexts of ``frame``, in chain order (one random stream each)."""
        return [NoiseContext(self.sensor, self.scenario.seed, frame, f"noise.{i}.{m.name}",
                             self.link, self.scenario.normals)
                for i, m in enumerate(self.noise)]

    def trajectory_poses(self, trajectory: Trajectory, t: np.ndarray, t_frame: float
                         ) -> PoseMatrices:
        """Poses of ``trajectory`` at the rays' times ``t`` (at ``t_frame`` when the scan's
        motion is ``frozen``): one pose, applied to all, when they cannot vary."""
        frozen = self.scenario.scan.motion == "frozen"
        if not (frozen or trajectory.is_static):
            return self._poses(trajectory, t, t_frame)
        # one pose per trajectory (and frame, when frozen): looked up once, not per piece
        key = (id(trajectory), t_frame if frozen else None)
        pose = self._fixed_poses.get(key)
        if pose is None:
            pose = self._poses(trajectory, np.array([t_frame]), t_frame)
            if len(self._fixed_poses) > _FIXED_POSE_CACHE:
                self._fixed_poses.clear()
            self._fixed_poses[key] = pose
        return pose

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
