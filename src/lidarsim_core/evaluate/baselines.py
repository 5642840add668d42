"""Built-in plugin: baseline pose estimators (``icp``, ``fpfh_ransac_icp`` on Open3D, and
``gt_noise``).

``icp`` tracks: point-to-plane ICP of the frame's points onto the target's mesh (closest points
on the triangles from Open3D's raycasting scene, the faces' exact normals), started from the
previous frame's estimate; the first
frame (and a frame after a failure) starts from the true pose perturbed by a fixed error.
``fpfh_ransac_icp`` acquires with no initial pose: FPFH features of the voxel-downsampled
frame and of points sampled over the mesh, RANSAC on feature matches, then the same ICP. ``gt_noise`` returns the true
pose plus Gaussian noise, to check the harness and the metrics. Open3D (extra ``eval``) is
imported when an estimator first runs, never at registration.
"""

from __future__ import annotations

import threading
import zlib
from typing import Any, Callable

import numpy as np
from pydantic import Field
from scipy.spatial.transform import Rotation

from ..base.components import ComponentOptions
from ..hookspecs import hookimpl
from .base import FrameInput, PoseEstimate, PoseEstimator, TargetModelData
from .extras import require


def _open3d() -> Any:
    o3d = require("open3d", "this estimator")
    o3d.utility.set_verbosity_level(o3d.utility.VerbosityLevel.Error)  # no chatter on stdout
    return o3d


def _rng(frame: FrameInput, stream: str) -> np.random.Generator:
    return np.random.default_rng([frame.seed, zlib.crc32(frame.sequence.encode()), frame.frame,
                                  zlib.crc32(stream.encode())])


def _perturb(pose: PoseEstimate, rotation_deg: float, translation_m: float,
             rng: np.random.Generator) -> PoseEstimate:
    """``pose`` turned by exactly ``rotation_deg`` about a random axis and moved by exactly
    ``translation_m`` in a random direction."""
    axis, direction = rng.normal(size=(2, 3))
    turn = Rotation.from_rotvec(np.deg2rad(rotation_deg) * axis / np.linalg.norm(axis))
    return PoseEstimate.from_rotation(
        turn * pose.rotation, pose.translation_m + translation_m * direction /
        np.linalg.norm(direction))


class _ModelCloud:
    """Open3D point clouds of a target's mesh samples, kept per model (for FPFH)."""

    def __init__(self) -> None:
        self._cache: dict[tuple[int, int, float], Any] = {}

    def get(self, model: TargetModelData, count: int, voxel: float = 0.0) -> Any:
        key = (id(model), count, voxel)
        if key not in self._cache:
            o3d = _open3d()
            points, normals = model.sample_points(count)
            cloud = o3d.geometry.PointCloud(o3d.utility.Vector3dVector(points))
            cloud.normals = o3d.utility.Vector3dVector(normals)
            if voxel > 0:
                cloud = cloud.voxel_down_sample(voxel)
            self._cache = {k: v for k, v in self._cache.items() if k[0] == id(model)}
            self._cache[key] = cloud
        return self._cache[key]


class _MeshIndex:
    """Closest points on a target's mesh (Open3D's raycasting scene), kept per model."""

    def __init__(self) -> None:
        self._model: TargetModelData | None = None
        self._scene: Any = None

    def closest(self, model: TargetModelData, points: np.ndarray
                ) -> tuple[np.ndarray, np.ndarray]:
        """Closest surface point and the face normal there, for (N, 3) body-frame points."""
        o3d = _open3d()
        if self._model is not model:
            scene = o3d.t.geometry.RaycastingScene()
            scene.add_triangles(o3d.core.Tensor(model.vertices.astype(np.float32)),
                                o3d.core.Tensor(model.faces.astype(np.uint32)))
            self._model, self._scene = model, scene
        answer = self._scene.compute_closest_points(
            o3d.core.Tensor(points.astype(np.float32)))
        face = answer["primitive_ids"].numpy().astype(np.int64)
        return answer["points"].numpy().astype(np.float64), model.mesh.face_normals[face]


class IcpOptions(ComponentOptions):
    """Options of the point-to-plane ICP tracker."""

    correspondence_distances_m: tuple[float, ...] = Field(
        (1.0, 0.3, 0.1), min_length=1,
        description="Largest point-to-mesh distance paired in each ICP stage, coarse to fine "
                    "(m).")
    max_iterations: int = Field(50, ge=1, description="ICP iterations per stage.")
    robust_kernel_m: float = Field(
        0.0, ge=0, description="Tukey kernel width (m); 0: plain least squares.")
    min_points: int = Field(10, ge=6, description="Fewer points in the frame: the frame fails.")
    min_fitness: float = Field(0.3, ge=0, le=1, description="Smaller final fraction of points "
                                                            "paired with the mesh: the frame "
                                                            "fails.")
    initial_rotation_error_deg: float = Field(
        2.0, ge=0, description="First frame: the true attitude turned by this angle about a "
                               "random axis (deg).")
    initial_translation_error_m: float = Field(
        0.1, ge=0, description="First frame: the true position moved by this distance in a "
                               "random direction (m).")
    deskew: bool = Field(
        True, description="Undo the target's motion during the scan (per-point timestamps, "
                          "velocity from the previous estimate) and refine again; the pose is "
                          "then given at the mean timestamp of the points.")


def _icp(mesh: _MeshIndex, model: TargetModelData, scan: np.ndarray,
         body_in_sensor: np.ndarray, options: IcpOptions
         ) -> tuple[np.ndarray | None, float, float]:
    """Point-to-plane ICP of the scan (sensor frame) onto the target's mesh.

    Each iteration pairs every scan point, mapped into the body frame, with its closest point
    on the mesh (exact: no sampling of the model) and solves the linearised point-to-plane
    least squares for a small turn ``ω`` and shift ``v`` of the sensor → body transform:
    ``min Σ w (nᵀ(p − c) + ωᵀ(p × n) + nᵀv)²``. Stages use shrinking pairing distances.

    Returns
    -------
    pose, fitness, rms
        The body → sensor transform (``None`` if fewer than 6 points paired or the equations
        cannot be solved), the fraction of scan points paired in the last stage and their RMS
        point-to-plane distance (m).
    """
    sensor_to_body = np.linalg.inv(body_in_sensor)
    fitness, rms = 0.0, np.inf
    for distance in options.correspondence_distances_m:
        for _ in range(options.max_iterations):
            p = scan @ sensor_to_body[:3, :3].T + sensor_to_body[:3, 3]
            c, n = mesh.closest(model, p)
            gap = np.linalg.norm(p - c, axis=1)
            paired = gap < distance
            fitness = float(paired.mean())
            if paired.sum() < 6:
                return None, fitness, rms
            p, c, n = p[paired], c[paired], n[paired]
            r = np.einsum("ij,ij->i", n, p - c)
            rms = float(np.sqrt(np.mean(r ** 2)))
            w = np.ones_like(r)
            if options.robust_kernel_m > 0:
                w = np.clip(1 - (r / options.robust_kernel_m) ** 2, 0, None) ** 2
            centre = p.mean(axis=0)  # conditioning: turn about the points' centroid
            jac = np.hstack([np.cross(p - centre, n), n])
            # least squares with minimum norm: a view of one flat face leaves the slide along
            # it unconstrained, and that part of the step is then zero instead of arbitrary
            try:
                x = np.linalg.lstsq((jac * w[:, None]).T @ jac, -(jac * w[:, None]).T @ r,
                                    rcond=1e-12)[0]
            except np.linalg.LinAlgError:  # non-finite input: give up on this start
                return None, fitness, rms
            step = np.eye(4)
            step[:3, :3] = Rotation.from_rotvec(x[:3]).as_matrix()
            step[:3, 3] = centre - step[:3, :3] @ centre + x[3:]
            sensor_to_body = step @ sensor_to_body
            if np.linalg.norm(x[:3]) < 1e-8 and np.linalg.norm(x[3:]) < 1e-8:
                break  # steps of 10 nrad and 10 nm: converged far below any sensor's noise
    return np.linalg.inv(sensor_to_body), fitness, rms


def _deskew(xyz: np.ndarray, times: np.ndarray, t_ref: float, pose: np.ndarray,
            previous: np.ndarray, dt: float) -> np.ndarray:
    """Points moved to where they would be at ``t_ref``, for a target whose pose changes at the
    constant rate seen between ``previous`` (``dt`` seconds earlier) and ``pose``.

    The sensor-frame motion over ``dt`` is ``D = pose ∘ previous⁻¹``; a point measured at
    ``τ`` is mapped by ``D^(−s)``, ``s = (τ − t_ref) / dt``, to first order in the motion:
    ``p − s (ω × p + t)``, rotation part applied exactly.
    """
    motion = pose @ np.linalg.inv(previous)
    rotvec = Rotation.from_matrix(motion[:3, :3]).as_rotvec()
    s = (times - t_ref) / dt
    return Rotation.from_rotvec(-s[:, None] * rotvec).apply(xyz) - s[:, None] * motion[:3, 3]


def _refine(mesh: _MeshIndex, frame: FrameInput, initial: np.ndarray,
            opts: IcpOptions) -> tuple[PoseEstimate, float]:
    """ICP from ``initial`` and the RMS point-to-plane residual (m) of the result."""
    if not np.all(np.isfinite(initial)):
        return PoseEstimate.failure("non-finite initial pose"), np.inf
    pose, fitness, rms = _icp(mesh, frame.model, frame.xyz, initial, opts)
    if pose is None:
        return PoseEstimate.failure(f"ICP failed: fewer than 6 points paired or no solution "
                                    f"(fitness {fitness:.2f})"), np.inf
    if fitness < opts.min_fitness:
        return PoseEstimate.failure(f"ICP fitness {fitness:.2f} < min_fitness "
                                    f"{opts.min_fitness}"), np.inf
    return PoseEstimate.from_matrix(pose, fitness=fitness), rms


class IcpTracker(PoseEstimator):
    """Point-to-plane ICP tracking from the previous estimate (Open3D; first frame from the
    perturbed truth)."""

    name = "icp"
    Options = IcpOptions
    requires = ("open3d",)
    uses_truth = True  # only to start: the first frame and after a failed frame

    def __init__(self, options: IcpOptions | None = None) -> None:
        super().__init__(options)
        self._mesh = _MeshIndex()

    def estimate(self, frame: FrameInput) -> PoseEstimate:
        opts: IcpOptions = self.options  # type: ignore[assignment]
        if len(frame.xyz) < opts.min_points:
            return PoseEstimate.failure(f"{len(frame.xyz)} points (< min_points "
                                        f"{opts.min_points})")
        previous = frame.previous
        if previous is None or not previous.success:
            assert frame.truth is not None
            previous = _perturb(frame.truth, opts.initial_rotation_error_deg,
                                opts.initial_translation_error_m, _rng(frame, "icp-start"))
        estimate, _ = _refine(self._mesh, frame, previous.matrix(), opts)
        prior = frame.previous
        if not (opts.deskew and estimate.success and prior is not None and prior.success and
                prior.time_s is not None):
            return estimate
        times = frame.timestamps
        t_ref = float(times.mean())
        if t_ref <= prior.time_s:
            return estimate
        deskewed = _deskew(frame.xyz, times, t_ref, estimate.matrix(), prior.matrix(),
                           t_ref - prior.time_s)
        fine = opts.model_copy(update={"correspondence_distances_m":
                                       opts.correspondence_distances_m[-1:]})
        pose, fitness, _ = _icp(self._mesh, frame.model, deskewed, estimate.matrix(), fine)
        if pose is None:
            return estimate
        return PoseEstimate.from_matrix(pose, fitness=fitness, time_s=t_ref)


class FpfhOptions(IcpOptions):
    """Options of the FPFH + RANSAC acquisition followed by ICP."""

    model_points: int = Field(200_000, ge=100, le=5_000_000,
                              description="Points sampled over the mesh before the voxel grid.")
    voxel_m: float = Field(0.4, gt=0, description="Voxel size for features and RANSAC (m).")
    normal_radius_voxels: float = Field(2.5, gt=0, description="Normal-estimation radius "
                                                               "(voxels).")
    feature_radius_voxels: float = Field(6.0, gt=0, description="FPFH radius (voxels).")
    ransac_distance_voxels: float = Field(1.5, gt=0, description="RANSAC inlier distance "
                                                                 "(voxels).")
    ransac_iterations: int = Field(200_000, ge=1, description="Most RANSAC iterations.")
    ransac_confidence: float = Field(0.999, gt=0, lt=1, description="RANSAC stop confidence.")
    restarts: int = Field(1, ge=1, le=100, description="RANSAC runs (different seeds), each "
                                                       "refined by ICP.")
    try_turns: bool = Field(
        True, description="Also refine each RANSAC pose turned by 180° and ±90° about the "
                          "model's principal axes (partial views of box-like bodies are nearly "
                          "symmetric); the candidate pairing most points, then with the "
                          "smallest residual, wins.")
    correspondence_distances_m: tuple[float, ...] = Field(
        (1.0, 0.3, 0.1), min_length=1,
        description="ICP stages after RANSAC, coarse to fine (m).")


def _fpfh(o3d: Any, cloud: Any, radius: float) -> Any:
    return o3d.pipelines.registration.compute_fpfh_feature(
        cloud, o3d.geometry.KDTreeSearchParamHybrid(radius=radius, max_nn=100))


def _principal_turns(model: TargetModelData) -> list[np.ndarray]:
    """Identity, then turns of 180° and ±90° about the principal axes of the model's surface
    (through its centroid), as 4×4 body transforms."""
    points, _ = model.sample_points(20_000)
    centre = points.mean(axis=0)
    _, vectors = np.linalg.eigh(np.cov((points - centre).T))
    turns = [np.eye(4)]
    for axis in vectors.T:
        for angle in (np.pi, np.pi / 2, -np.pi / 2):
            turn = np.eye(4)
            turn[:3, :3] = Rotation.from_rotvec(angle * axis).as_matrix()
            turn[:3, 3] = centre - turn[:3, :3] @ centre
            turns.append(turn)
    return turns


class FpfhRansacIcp(PoseEstimator):
    """Global registration (FPFH features, RANSAC) then point-to-plane ICP: acquisition with no
    initial pose (Open3D)."""

    name = "fpfh_ransac_icp"
    Options = FpfhOptions
    requires = ("open3d",)

    def __init__(self, options: FpfhOptions | None = None) -> None:
        super().__init__(options)
        self._models = _ModelCloud()
        self._mesh = _MeshIndex()
        self._features: dict[tuple[int, float], Any] = {}

    def estimate(self, frame: FrameInput) -> PoseEstimate:
        opts: FpfhOptions = self.options  # type: ignore[assignment]
        if len(frame.xyz) < opts.min_points:
            return PoseEstimate.failure(f"{len(frame.xyz)} points (< min_points "
                                        f"{opts.min_points})")
        o3d = _open3d()
        reg = o3d.pipelines.registration
        voxel = opts.voxel_m
        scan_down = o3d.geometry.PointCloud(
            o3d.utility.Vector3dVector(frame.xyz)).voxel_down_sample(voxel)
        if len(scan_down.points) < opts.min_points:
            return PoseEstimate.failure(f"{len(scan_down.points)} voxels (< min_points)")
        scan_down.estimate_normals(o3d.geometry.KDTreeSearchParamHybrid(
            radius=opts.normal_radius_voxels * voxel, max_nn=30))
        scan_down.orient_normals_towards_camera_location(np.zeros(3))  # seen from the sensor
        model_down = self._models.get(frame.model, opts.model_points, voxel)
        key = (id(model_down), voxel)
        if key not in self._features:
            self._features = {key: _fpfh(o3d, model_down, opts.feature_radius_voxels * voxel)}
        distance = opts.ransac_distance_voxels * voxel
        scan_features = _fpfh(o3d, scan_down, opts.feature_radius_voxels * voxel)
        seeds = _rng(frame, "ransac").integers(2 ** 31, size=opts.restarts)
        sparse = np.asarray(scan_down.points)
        quick = opts.model_copy(update={"max_iterations": min(opts.max_iterations, 30)})
        turns = _principal_turns(frame.model) if opts.try_turns else [np.eye(4)]
        candidates: list[tuple[tuple[float, float], int, np.ndarray]] = []
        for seed in seeds:
            o3d.utility.random.seed(int(seed))
            ransac = _one_thread(o3d, lambda: reg.registration_ransac_based_on_feature_matching(
                scan_down, model_down, scan_features, self._features[key], False, distance,
                reg.TransformationEstimationPointToPoint(False), 3,
                [reg.CorrespondenceCheckerBasedOnEdgeLength(0.9),
                 reg.CorrespondenceCheckerBasedOnDistance(distance)],
                reg.RANSACConvergenceCriteria(opts.ransac_iterations, opts.ransac_confidence)))
            if ransac.fitness == 0:
                continue
            hypothesis = np.linalg.inv(np.asarray(ransac.transformation))
            for turn in turns:  # ranked briefly on the voxel-grid points...
                pose, fitness, rms = _icp(self._mesh, frame.model, sparse, hypothesis @ turn,
                                          quick)
                if pose is not None:
                    candidates.append(((-round(fitness, 3), rms), len(candidates), pose))
        if not candidates:
            return PoseEstimate.failure("RANSAC found no consistent match")
        best, best_key = None, (np.inf, np.inf)
        for _, _, pose in sorted(candidates, key=lambda c: c[:2])[:4]:
            # ...and the four best refined on every point: the right attitude pairs the most
            # points, then fits the surface best
            estimate, rms = _refine(self._mesh, frame, pose, opts)
            score = (-round(estimate.fitness or 0.0, 3), rms)
            if estimate.success and score < best_key:
                best, best_key = estimate, score
        return best if best is not None else PoseEstimate.failure(
            "no candidate pose refined to min_fitness")


_open3d_threads = threading.Lock()


def _one_thread(o3d: Any, run: Callable[[], Any]) -> Any:
    """``run()`` with Open3D on one thread: its RANSAC draws its samples on every thread at
    once, so on several its result depends on their timing (a view of Envisat flipped by
    180° in one CI run); on one it is the seed's alone."""
    with _open3d_threads:
        before = o3d.utility.get_max_threads()
        o3d.utility.set_max_threads(1)
        try:
            return run()
        finally:
            o3d.utility.set_max_threads(before)


class GtNoiseOptions(ComponentOptions):
    """Options of the ground-truth-plus-noise estimator."""

    translation_sigma_m: float = Field(0.0, ge=0, description="Standard deviation of the "
                                                              "position error per axis (m).")
    rotation_sigma_deg: float = Field(0.0, ge=0, description="Standard deviation of the "
                                                             "rotation-vector error per axis "
                                                             "(deg).")


class GtNoise(PoseEstimator):
    """The true pose plus Gaussian noise: checks the harness and the metrics (0 noise scores
    exactly 0)."""

    name = "gt_noise"
    Options = GtNoiseOptions
    uses_truth = True

    def estimate(self, frame: FrameInput) -> PoseEstimate:
        opts: GtNoiseOptions = self.options  # type: ignore[assignment]
        truth = frame.truth
        assert truth is not None
        if opts.translation_sigma_m == 0 and opts.rotation_sigma_deg == 0:
            return PoseEstimate(truth.quaternion_xyzw.copy(), truth.translation_m.copy())
        rng = _rng(frame, "gt_noise")
        turn = Rotation.from_rotvec(np.deg2rad(opts.rotation_sigma_deg) * rng.normal(size=3))
        return PoseEstimate.from_rotation(
            turn * truth.rotation,
            truth.translation_m + opts.translation_sigma_m * rng.normal(size=3))


@hookimpl
def lidarsim_register_pose_estimators(register: Any) -> None:
    """Register the baseline estimators."""
    register(IcpTracker)
    register(FpfhRansacIcp)
    register(GtNoise)
