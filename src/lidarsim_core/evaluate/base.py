"""The pose-estimator contract: what an estimator is given for one frame and what it returns.

An estimator is a plugin component (registered through
:func:`~lidarsim_core.hookspecs.lidarsim_register_pose_estimators`) with a ``name``, a pydantic
``Options`` model and one method, :meth:`PoseEstimator.estimate`, called once per frame in
frame order. It receives a :class:`FrameInput` (the frame's points in the sensor frame with
their per-point timestamps and the whole point record, the target's model in its body frame,
and the previous frame's estimate) and returns a :class:`PoseEstimate`: the target body
frame's pose in the sensor frame, ``x_sensor = R · x_body + t`` (the convention of the
ground-truth files, :mod:`lidarsim_core.records.groundtruth`). It reports failure by returning
:meth:`PoseEstimate.failure`; an exception or a non-finite pose is recorded as a failed frame
by the harness, which goes on with the next frame.
"""

from __future__ import annotations

import math
from dataclasses import dataclass, field
from typing import TYPE_CHECKING, Any, Callable, ClassVar, Mapping

import numpy as np
from scipy.spatial.transform import Rotation

from ..base.components import Component, ComponentOptions

if TYPE_CHECKING:  # pragma: no cover
    from ..scene.mesh import Mesh


class TargetModelData:
    """The target as the estimator knows it: its mesh in the body frame.

    Parameters
    ----------
    name
        The target's name in the scenario (its label in the point record).
    mesh
        The :class:`~lidarsim_core.scene.mesh.Mesh` the simulation traced, in body coordinates
        (metres), loaded by the same code (a mesh file with its scale, or a procedural model
        with its options).
    """

    def __init__(self, name: str, mesh: "Mesh") -> None:
        self.name = name
        self.mesh = mesh
        self._samples: dict[tuple[int, int], np.ndarray] = {}

    @property
    def vertices(self) -> np.ndarray:
        """(V, 3) vertices, body frame (m)."""
        return self.mesh.vertices

    @property
    def faces(self) -> np.ndarray:
        """(F, 3) vertex indices of the triangles."""
        return self.mesh.faces

    def sample_points(self, count: int, seed: int = 0) -> tuple[np.ndarray, np.ndarray]:
        """``count`` points drawn uniformly by area over the surface, and their face normals.

        Deterministic for a given ``(count, seed)`` and cached, so an estimator may call it
        every frame.

        Returns
        -------
        points, normals
            Two (count, 3) float64 arrays in the body frame.
        """
        key = (int(count), int(seed))
        if key not in self._samples:
            tri = self.mesh.triangles
            areas = self.mesh.face_areas
            rng = np.random.default_rng(seed)
            face = rng.choice(len(areas), size=count, p=areas / areas.sum())
            u, v = rng.random((2, count))
            flip = u + v > 1
            u[flip], v[flip] = 1 - u[flip], 1 - v[flip]
            a, b, c = tri[face, 0], tri[face, 1], tri[face, 2]
            points = a + u[:, None] * (b - a) + v[:, None] * (c - a)
            self._samples[key] = np.hstack([points, self.mesh.face_normals[face]])
        data = self._samples[key]
        return data[:, :3], data[:, 3:]


@dataclass
class FrameInput:
    """Everything an estimator is given for one frame.

    Attributes
    ----------
    sequence, frame
        Which frame this is.
    t_start_s, t_end_s
        The frame's scan interval (s from the scenario epoch).
    points
        The frame's point record: column name → array (every column of
        :data:`lidarsim_core.records.pointcloud.POINT_FIELDS`), only returns the sensor reported
        (``detected == 1``). Coordinates are in the sensor frame at each point's emission time.
    model
        The target's model (:class:`TargetModelData`).
    previous
        The estimate of the previous frame of the same sequence (``None`` on the first frame;
        a failed estimate is passed as it is, with ``success=False``).
    truth
        The true pose at the frame's reference time, given only to estimators whose class sets
        ``uses_truth = True`` (baselines that check the harness or start from the truth);
        ``None`` otherwise. Their scores are marked as such in every output.
    seed
        A seed for estimators that draw random numbers (from ``--seed`` and the frame), so that
        a run and its resumed copy give the same estimates.
    """

    sequence: str
    frame: int
    t_start_s: float
    t_end_s: float
    points: Mapping[str, np.ndarray]
    model: TargetModelData
    previous: "PoseEstimate | None"
    truth: "PoseEstimate | None" = None
    seed: int = 0

    @property
    def xyz(self) -> np.ndarray:
        """(N, 3) measured points, sensor frame (m)."""
        return np.column_stack([self.points["x"], self.points["y"], self.points["z"]])

    @property
    def timestamps(self) -> np.ndarray:
        """(N,) emission time of each point (s from the scenario epoch)."""
        return np.asarray(self.points["timestamp"])


@dataclass
class PoseEstimate:
    """An estimator's answer for one frame.

    Attributes
    ----------
    quaternion_xyzw
        Attitude of the target body in the sensor frame (scalar-last, Hamilton, as SciPy).
    translation_m
        Position of the target body origin in the sensor frame (m).
    success
        ``False`` when the estimator gives up on this frame (then the pose is ignored).
    time_s
        The time the pose refers to (s from the epoch); ``None``: the frame's reference time
        (frame start with ``motion: frozen``, the mean timestamp of the points otherwise).
    fitness
        Optional quality figure (e.g. the inlier fraction of a registration).
    covariance
        Optional 6×6 covariance of (rotation vector rad, translation m).
    message
        Why it failed, or any note.
    """

    quaternion_xyzw: np.ndarray = field(default_factory=lambda: np.array([0.0, 0.0, 0.0, 1.0]))
    translation_m: np.ndarray = field(default_factory=lambda: np.zeros(3))
    success: bool = True
    time_s: float | None = None
    fitness: float | None = None
    covariance: np.ndarray | None = None
    message: str = ""

    @classmethod
    def from_matrix(cls, matrix: np.ndarray, **extra: Any) -> "PoseEstimate":
        """From a 4×4 homogeneous transform body → sensor."""
        matrix = np.asarray(matrix, dtype=np.float64)
        quat = Rotation.from_matrix(matrix[:3, :3]).as_quat()
        return cls(quat, matrix[:3, 3].copy(), **extra)

    @classmethod
    def from_rotation(cls, rotation: Rotation, translation_m: Any, **extra: Any
                      ) -> "PoseEstimate":
        """From a SciPy rotation and a translation."""
        return cls(rotation.as_quat(), np.asarray(translation_m, dtype=np.float64), **extra)

    @classmethod
    def failure(cls, message: str) -> "PoseEstimate":
        """A frame the estimator could not solve."""
        return cls(success=False, message=message)

    @property
    def rotation(self) -> Rotation:
        """The attitude as a SciPy rotation."""
        return Rotation.from_quat(self.quaternion_xyzw)

    def matrix(self) -> np.ndarray:
        """4×4 homogeneous transform body → sensor."""
        out = np.eye(4)
        out[:3, :3] = self.rotation.as_matrix()
        out[:3, 3] = self.translation_m
        return out

    def is_finite(self) -> bool:
        """Whether the pose holds finite numbers and a non-zero quaternion."""
        q = np.asarray(self.quaternion_xyzw, dtype=np.float64)
        t = np.asarray(self.translation_m, dtype=np.float64)
        return (q.shape == (4,) and t.shape == (3,) and bool(np.all(np.isfinite(q)))
                and bool(np.all(np.isfinite(t))) and float(np.linalg.norm(q)) > 1e-12)

    def to_record(self) -> dict[str, Any]:
        """JSON-ready dictionary (quaternion normalised with w ≥ 0)."""
        out: dict[str, Any] = {"success": bool(self.success)}
        if self.success:
            quat = Rotation.from_quat(self.quaternion_xyzw).as_quat(canonical=True) + 0.0
            out["q_target_in_sensor"] = quat.tolist()
            out["r_target_in_sensor_m"] = [float(v) for v in self.translation_m]
        if self.time_s is not None:
            out["time_s"] = float(self.time_s)
        if self.fitness is not None and math.isfinite(float(self.fitness)):
            out["fitness"] = float(self.fitness)
        if self.covariance is not None:
            out["covariance"] = np.asarray(self.covariance, dtype=np.float64).tolist()
        if self.message:
            out["message"] = self.message
        return out

    @classmethod
    def from_record(cls, record: Mapping[str, Any]) -> "PoseEstimate":
        """Inverse of :meth:`to_record`."""
        if not record.get("success"):
            return cls(success=False, message=record.get("message", ""),
                       time_s=record.get("time_s"))
        cov = record.get("covariance")
        return cls(np.asarray(record["q_target_in_sensor"], dtype=np.float64),
                   np.asarray(record["r_target_in_sensor_m"], dtype=np.float64),
                   time_s=record.get("time_s"), fitness=record.get("fitness"),
                   covariance=None if cov is None else np.asarray(cov),
                   message=record.get("message", ""))


class EstimationFailed(Exception):
    """Raise from :meth:`PoseEstimator.estimate` to report a failed frame with a reason
    (the same as returning :meth:`PoseEstimate.failure`)."""


class PoseEstimator(Component):
    """Base of pose estimators: subclass, set ``name`` and ``Options``, implement
    :meth:`estimate`.

    Attributes
    ----------
    uses_truth
        ``True`` for estimators that read :attr:`FrameInput.truth` (harness checks, baselines
        initialised from the truth); their results are flagged as such.
    requires
        Importable modules the estimator needs; the harness checks them before it starts and
        names the missing one (and the extra providing it) in a one-line error.
    """

    uses_truth: ClassVar[bool] = False
    requires: ClassVar[tuple[str, ...]] = ()

    def start_sequence(self, model: TargetModelData) -> None:
        """Called before the first frame of each sequence (optional: reset any state)."""

    def estimate(self, frame: FrameInput) -> PoseEstimate:
        """The target's pose in the sensor frame for ``frame`` (see :class:`FrameInput`)."""
        raise NotImplementedError


def function_estimator(name: str, function: Callable[[FrameInput, Any], Any], *,
                       options: type[ComponentOptions] = ComponentOptions,
                       summary: str | None = None, uses_truth: bool = False,
                       requires: tuple[str, ...] = ()) -> type[PoseEstimator]:
    """Wrap a plain function as a pose-estimator class, ready to ``register``.

    Parameters
    ----------
    name
        The name users give to ``--estimator``.
    function
        ``function(frame, options)`` with a :class:`FrameInput` and the validated options;
        returns a :class:`PoseEstimate`, a 4×4 body → sensor matrix, or ``None`` for "no
        estimate for this frame".
    options
        Its pydantic options model (a :class:`~lidarsim_core.base.components.ComponentOptions`
        subclass); none by default.
    summary
        One line for ``lidarsim plugins`` (default: the function's docstring's first line).
    uses_truth, requires
        As on :class:`PoseEstimator`.

    Examples
    --------
    >>> def centroid_only(frame, options):
    ...     return PoseEstimate(translation_m=frame.xyz.mean(axis=0))
    >>> Centroid = function_estimator("centroid", centroid_only)
    """

    def estimate(self: PoseEstimator, frame: FrameInput) -> PoseEstimate:
        result = function(frame, self.options)
        if result is None:
            return PoseEstimate.failure(f"{name} returned no estimate")
        if isinstance(result, PoseEstimate):
            return result
        matrix = np.asarray(result, dtype=np.float64)
        if matrix.shape != (4, 4):
            raise TypeError(f"{name} returned an array of shape {matrix.shape}, not 4×4")
        return PoseEstimate.from_matrix(matrix)

    doc = summary or (function.__doc__ or f"Pose estimator {name}.").strip().splitlines()[0]
    return type(f"FunctionEstimator_{name}", (PoseEstimator,),
                {"name": name, "Options": options, "uses_truth": uses_truth,
                 "requires": tuple(requires), "estimate": estimate, "__doc__": doc,
                 "__module__": getattr(function, "__module__", __name__)})
