"""Skipping the pulses that cannot reach any target, before anything else is computed for them.

In a typical close-range scan most pulses miss the satellite (89 % in the demo). A miss costs
Embree one bounding-box test, but the pipeline would first have turned the pulse by its
angular error, moved it into every target's body frame and assembled its ray: several times
what Embree spends. :class:`PulseCuller` decides from the pulse's *nominal* direction whether
it can reach a target at all; only those that can go on.

The test is conservative, so culling never changes a result. Every Gaussian draw of
:func:`lidarsim_core.noise.rng.ray_normals` is within ``MAX_ABS_NORMAL`` (8.21) standard deviations
by construction (the uniforms behind it are at least 2**-53 from 0 and 1); a draw of the
``ziggurat`` generator within 12.23 (its tail's bound), and the ray stage tells which
(:class:`~lidarsim_core.noise.base.GaussianRayRotation`). Two rotations by
``a1`` and ``a2`` about perpendicular axes turn a ray by ``arccos(cos a1 cos a2) <=
hypot(a1, a2)`` (a right spherical triangle), and a beam's sub-rays add its largest sub-ray
angle. So the flown ray and its sub-rays stay within ``margin`` of the nominal ray, and a pulse
can reach only a target whose boxes (:func:`cull_tree`), grown by ``margin`` times the
farthest distance to the target's bounding box, the nominal ray meets. When the sensor and
every target hold one pose for a whole piece (static scenes, ``motion: frozen``), the grown
leaf boxes are projected once onto a cube map of directions and each pulse costs one lookup
(:func:`lidarsim_core.kernels.cull.direction_grid`). With a pose per pulse (tumbling
targets, moving sensors) the map is built at the piece's middle pose with every box also grown
by how far any point of the target strays, relative to the sensor, from where that pose puts it
during the piece (:func:`lidarsim_core.kernels.cull.motion_bound`: ``‖Mᵢ − M₀‖_F`` times the
target's reach plus the shift of its origin, with ``Mᵢ`` the body→sensor rotation; a box grown
by ``d`` in the body frame holds every point that moves by at most ``d``). When a target is
nearer than its own size (its boxes would straddle the map's faces) or moves by more than a
tenth of it, each pulse's nominal ray is tested against the box tree in each target's frame
at its own pose instead (:func:`lidarsim_core.kernels.cull.cull_posed`). The tests run scans
with and without culling and compare every column.

When every trajectory bounds its own motion (:meth:`~lidarsim_core.trajectories.base.Trajectory.
motion_rates`), the cull runs before the pulses are posed (:meth:`PulseCuller.keep_before_poses`,
:func:`culled_with_poses`): the motion within a piece is bounded from those rates and one pose
at the piece's middle time, targets that stray by at most a tenth of their size share one
cube map, faster ones get a cone of directions per block of :data:`CONE_BLOCK` pulses, and
only the kept pulses are posed (a pose is a function of its pulse's time alone: the same bits).

Culling is used when the compiled kernels are (:mod:`lidarsim_core.kernels`) and every
ray-stage noise model describes itself through
:meth:`~lidarsim_core.noise.base.NoiseModel.ray_rotation`; not with false-alarm models, which
add returns to pulses that hit nothing, nor with ``earth`` (a pulse that misses every target
may see the sunlit Earth and raise a false alarm). Multipath bounces and the Sun's shadow rays and
background start from a pulse's direct hit, so a culled pulse (which hits nothing) has none of
them either: culling stays exact with ``sensor.multipath`` and ``sun`` (tested).
"""

from __future__ import annotations

import math
import threading
from dataclasses import dataclass, field
from typing import Any, NamedTuple

import numpy as np

from .. import kernels
from ..geometry.posing import PoseMatrices
from ..noise.outliers import SpuriousReturnModel
from ..patterns.base import DirectionGroups, RayBatch
from ..scene.mesh import Mesh
from ..trajectories.matrices import motion_rates
from .context import RunContext
from .posing import PiecePoses, piece_poses, with_piece_poses

#: Levels of median splits of a mesh's triangles into culling boxes (up to 2**levels leaves).
CULL_TREE_LEVELS = 10
#: Levels of the tree whose boxes make a cube map for a pose that will not come again (a
#: moving sensor or target: a map per piece): a map of the 1,024 leaves costs ~0.5 ms, of the
#: 64 boxes six levels down ~0.03 ms, and keeps 2 % more of the pulses ahead of a still sensor.
MOVING_GRID_LEVELS = 6
#: Cells along each edge of a face of the cube map of reachable directions (one pose).
GRID_CELLS = 256
#: Groups smaller than twice this are not split further.
MIN_BOX_TRIANGLES = 8
#: Fewest pulses of a block with a cube map of its own when targets move fast (below it, the
#: pulses are tested one by one at their own poses).
MIN_MOVING_BLOCK = 1024
#: Times a piece is halved at most for targets that move fast (up to 4 blocks): beyond that,
#: building a map per block cost more than testing each pulse on the two-target scene.
MAX_MOVING_SPLITS = 2
#: Fewest pulses of a piece culled by direction groups (:func:`pattern_candidates`) in a still
#: scene and when the sensor or a target moves (below them the groups cost more than they
#: save; :func:`_fewest_grouped`).
GROUPED_STILL = 8192
GROUPED_MOVING = 32768
#: Pulses per block that share one cone per fast target when culling before the poses
#: (:meth:`PulseCuller.keep_before_poses`).
CONE_BLOCK = 512


class CullTree(NamedTuple):
    """A mesh's tree of culling boxes (:func:`cull_tree`), in its own frame."""

    #: (B, 3) the boxes' low and high corners; node 0 is the mesh's bounding box.
    lo: np.ndarray
    hi: np.ndarray
    #: (B,) the first of each node's two children (consecutive), -1 for a leaf.
    child: np.ndarray
    #: (B,) each node's level (0 for the root).
    depth: np.ndarray

    def boxes(self, levels: int) -> np.ndarray:
        """The nodes that cover the mesh down to ``levels``: the leaves above it and the nodes
        at it (a mask)."""
        return ((self.child < 0) & (self.depth <= levels)) | (self.depth == levels)


@dataclass(frozen=True)
class PulseCuller:
    """The culling plan of one simulation (see the module docstring).

    Attributes
    ----------
    margin_rad
        Largest angle between a flown (sub-)ray and its pulse's nominal direction.
    """

    margin_rad: float
    #: Cube maps of reachable directions by pose (:meth:`keep`), newest last; a still
    #: scene's by its pose arrays' identity, with the arrays (:meth:`_still_grid`).
    _grids: dict[Any, Any] = field(default_factory=dict, compare=False, repr=False)
    #: Plans with a wider margin, by the extra angle (:meth:`widened`).
    _wider: dict[float, "PulseCuller"] = field(default_factory=dict, compare=False,
                                               repr=False)

    def widened(self, angle: float) -> "PulseCuller":
        """This plan with its margin grown by ``angle`` (rad): the culler of directions that
        stand for every direction within ``angle`` of them (cached)."""
        with _grids_lock:
            wider = self._wider.get(angle)
            if wider is None:
                wider = self._wider[angle] = PulseCuller(self.margin_rad + angle)
        return wider

    @classmethod
    def for_context(cls, ctx: RunContext) -> "PulseCuller | None":
        """The plan for ``ctx``, or None when culling does not apply (see module docstring)."""
        if not kernels.enabled() or any(isinstance(m, SpuriousReturnModel) for m in ctx.noise):
            return None
        if ctx.scenario.earth is not None:  # pulses that miss every target see the Earth
            return None
        margin = 0.0
        for model, nctx in zip(ctx.noise, ctx.noise_contexts(0)):
            rotation = model.ray_rotation(nctx)
            if rotation is None:  # a ray stage we cannot bound
                return None
            # two rotations by a1, a2 about perpendicular axes turn the ray by
            # arccos(cos a1 · cos a2) <= hypot(a1, a2) (a right spherical triangle), and
            # every draw is at most max_abs_normal standard deviations (MAX_ABS_NORMAL for
            # the seed paper's inverse CDF)
            margin += math.sqrt(2.0) * rotation.max_abs_normal * rotation.sigma_rad
        if ctx.sub_rays is not None:
            margin += float(np.arccos(np.clip(ctx.sub_rays.coefficients[:, 0].min(), -1, 1)))
        return cls(margin * (1.0 + 1e-6))  # a hair of slack for rounding

    def keep(self, ctx: RunContext, batch: RayBatch, t_frame: float) -> np.ndarray:
        """Rows of ``batch`` whose pulses may reach a target (int64, ascending)."""
        from ..kernels.cull import cull_by_grid

        posed = piece_poses(ctx, batch, t_frame)
        m = max(len(posed.sensor), *(len(p) for p in posed.targets))
        trees = [cull_tree(target.mesh) for target in ctx.targets]
        directions = batch.direction
        if directions.dtype != np.float64:
            directions = directions.astype(np.float64)
        if m > 1:
            # a cube map per block of pulses, each grown by its own motion; blocks in which
            # the target moves too much are halved, down to MIN_MOVING_BLOCK pulses
            kept = []
            for start, stop, grid in self._moving_blocks(posed, trees, 0, m):
                if grid is not None:
                    rows = cull_by_grid(directions[start:stop], grid)
                else:
                    rows = self._per_pulse(directions[start:stop], posed, trees, start, stop)
                kept.append(rows + start if start else rows)
            return kept[0] if len(kept) == 1 else np.concatenate(kept)
        # one pose for the piece: look the directions up in a cube map, of every leaf when
        # the pose comes again (a still scene: the map is kept)
        still = all(tr.is_static for tr in
                    [ctx.sensor_trajectory] + [target.trajectory for target in ctx.targets])
        grid = self._still_grid(posed, trees) if still else self._pose_grid(
            posed, 0, [0.0] * len(trees), trees, MOVING_GRID_LEVELS)
        if grid is None:  # the sensor is inside a target's box: nothing to cull
            return np.arange(len(batch), dtype=np.int64)
        return cull_by_grid(directions, grid)

    def keep_before_poses(self, ctx: RunContext, batch: RayBatch, t_frame: float,
                          span: tuple[float, float] | None = None, groups: bool = False
                          ) -> np.ndarray | None:
        """Rows of ``batch`` (without poses) that may reach a target, from a few poses per
        piece and the trajectories' rate bounds instead of a pose per pulse; None when a
        trajectory gives no bounds (:func:`lidarsim_core.trajectories.matrices.motion_rates`)
        or the sensor is within a target's grown box, and :meth:`keep` is to decide on the
        posed batch.

        Over the piece's times ``[t0, t1]`` the sensor turns at most at ``ωs`` and moves at
        ``vs``, a target at ``ωt`` and ``vt``. A body point ``x`` is seen in the sensor frame
        at ``M(t) x + o(t)`` with ``M = Rsᵀ Rt`` and ``o = Rsᵀ (pt − ps)``, so within ``Δ`` of
        the middle time ``tm`` it strays by at most ``(ωs + ωt) Δ |x| + (vs + vt) Δ + ωs Δ
        |pt − ps|(tm)`` (``‖M(t) − M(tm)‖₂ = 2 sin(θ/2) <= θ`` for the angle θ between them).
        Targets that stray by at most a tenth of their size join one cube map at ``tm``
        (:meth:`_pose_grid`); each other target gets a cone per block of
        :data:`CONE_BLOCK` pulses: the directions within the pulse margin of its bounding
        sphere, grown by how far it strays within the block, as seen at the block's middle
        time.

        ``span`` replaces the batch's time span (its rays then stand for groups of pulses
        emitted within it, :func:`culled_piece`), and with ``groups`` a target that needs
        cones gives None (the cones' blocks are made of pulses).
        """
        from ..kernels.cull import cull_by_grid_cones

        n = len(batch)
        if n == 0:
            return np.arange(0, dtype=np.int64)
        if _one_pose_a_frame(ctx):
            return self.keep(ctx, batch, t_frame)  # one pose each: no per-pulse poses either
        trajectories = [ctx.sensor_trajectory] + [target.trajectory for target in ctx.targets]
        t = batch.t
        t0, t1 = (float(t.min()), float(t.max())) if span is None else span
        rates = [motion_rates(tr, t0, t1) for tr in trajectories]
        if any(r is None for r in rates):
            return None
        (turn_s, speed_s), target_rates = rates[0], rates[1:]
        trees = [cull_tree(target.mesh) for target in ctx.targets]
        middle = 0.5 * (t0 + t1)
        half = max(middle - t0, t1 - middle) * (1.0 + 1e-12)

        def pose(trajectory, times: np.ndarray) -> PoseMatrices:  # noqa: ANN001
            return ctx.trajectory_poses(trajectory, times, t_frame).full(len(times))

        at_middle = np.array([middle])
        sensor = pose(ctx.sensor_trajectory, at_middle)
        grid_targets, cone_targets, motion = [], [], []
        for k, (target, tree, (turn_t, speed_t)) in enumerate(
                zip(ctx.targets, trees, target_rates)):
            lo, hi = tree[0][0], tree[1][0]
            posed = pose(target.trajectory, at_middle)
            moved = _strays(turn_s, speed_s, turn_t, speed_t, half, _reach(lo, hi),
                            float(np.linalg.norm(posed.position[0] - sensor.position[0])))
            if moved <= 0.1 * float(np.linalg.norm(hi - lo)):
                grid_targets.append((k, posed))
                motion.append(moved)
            elif groups:
                return None
            else:
                cone_targets.append(k)
        grid = np.zeros((6, 1, 1), dtype=np.uint8)
        if grid_targets:
            posed = PiecePoses(sensor, tuple(p for _, p in grid_targets))
            built = self._pose_grid(posed, 0, motion, [trees[k] for k, _ in grid_targets],
                                    MOVING_GRID_LEVELS)
            if built is None:  # the sensor is within a grown box
                return None
            grid = built
        directions = batch.direction
        if directions.dtype != np.float64:
            directions = directions.astype(np.float64)
        axes, cosines = self._cones(ctx, cone_targets, trees, t, (turn_s, speed_s),
                                    target_rates, t_frame)
        return cull_by_grid_cones(directions, grid, bool(grid_targets), CONE_BLOCK, axes,
                                  cosines)

    def _cones(self, ctx: RunContext, cone_targets: list[int],
               trees: list[CullTree], t: np.ndarray,
               sensor_rates: tuple[float, float], target_rates: list[tuple[float, float]],
               t_frame: float) -> tuple[np.ndarray, np.ndarray]:
        """Per block of :data:`CONE_BLOCK` pulses, the unit axis (blocks, K, 3) and the
        cosine of the half angle (blocks, K) of the cone of directions that may reach each
        of ``cone_targets`` (see :meth:`keep_before_poses`)."""
        starts = np.arange(0, len(t), CONE_BLOCK)
        blocks = len(starts)
        axes = np.zeros((blocks, len(cone_targets), 3))
        cosines = np.full((blocks, len(cone_targets)), np.inf)
        if not cone_targets:
            return axes, cosines
        first, last = np.minimum.reduceat(t, starts), np.maximum.reduceat(t, starts)
        middle = 0.5 * (first + last)
        span = np.maximum(middle - first, last - middle) * (1.0 + 1e-12)
        sensor = ctx.trajectory_poses(ctx.sensor_trajectory, middle, t_frame).full(blocks)
        turn_s, speed_s = sensor_rates
        for j, k in enumerate(cone_targets):
            lo, hi = trees[k][0][0], trees[k][1][0]
            centre, radius = 0.5 * (lo + hi), 0.5 * float(np.linalg.norm(hi - lo))
            posed = ctx.trajectory_poses(ctx.targets[k].trajectory, middle, t_frame).full(blocks)
            # the sphere's centre in the sensor frame: Rsᵀ (Rt c + pt − ps)
            offset = posed.position - sensor.position
            scene = np.einsum("nij,j->ni", posed.matrix, centre) + offset
            seen = np.einsum("nji,nj->ni", sensor.matrix, scene)
            distance = np.linalg.norm(seen, axis=1)
            turn_t, speed_t = target_rates[k]
            strays = _strays(turn_s, speed_s, turn_t, speed_t, span, _reach(lo, hi),
                             np.linalg.norm(offset, axis=1))
            grown = radius + strays + 1e-9 + 1e-12 * distance
            inside = grown >= distance
            angle = np.arcsin(np.minimum(grown / np.where(inside, grown, distance), 1.0)) + \
                self.margin_rad
            cosine = np.cos(np.minimum(angle, np.pi)) - 1e-9
            cosines[:, j] = np.where(inside | (angle >= np.pi), -2.0, cosine)  # -2: every direction
            axes[:, j] = seen / np.where(distance > 0, distance, 1.0)[:, None]
        return axes, cosines

    def _per_pulse(self, directions: np.ndarray, posed: PiecePoses,
                   trees: list[CullTree], start: int, stop: int) -> np.ndarray:
        """Rows (from 0) of the pulses ``start:stop`` that may reach a target, each tested
        against the box trees at its own pose (:func:`lidarsim_core.kernels.cull.cull_posed`):
        the fallback for a sensor inside a target's box, or a block of pulses within which a
        target moves by more than a tenth of its size."""
        from ..kernels.cull import cull_posed

        m = stop - start

        def rows(poses: PoseMatrices) -> PoseMatrices:
            position = poses.position if len(poses.position) == 1 else \
                poses.position[start:stop]
            matrix = poses.matrix if len(poses.matrix) == 1 else poses.matrix[start:stop]
            return PoseMatrices(position, matrix)

        sensor = rows(posed.sensor)
        sensor = sensor.full(m) if len(sensor) > 1 else sensor.full(1)
        targets = [rows(p) for p in posed.targets]
        moving = np.array([len(p) > 1 for p in targets])
        targets = [p.full(m) if len(p) > 1 else p.full(1) for p in targets]
        first = np.cumsum([0] + [len(p) for p in targets])[:-1]
        roots = np.cumsum([0] + [len(t.lo) for t in trees])[:-1]
        return cull_posed(
            directions, sensor.matrix, sensor.position,
            np.concatenate([p.matrix for p in targets]),
            np.concatenate([p.position for p in targets]),
            first, moving, np.concatenate([t[0] for t in trees]),
            np.concatenate([t[1] for t in trees]),
            np.concatenate([np.where(t[2] >= 0, t[2] + root, -1)
                            for t, root in zip(trees, roots)]),
            roots, self.margin_rad)

    def _moving_blocks(self, posed: PiecePoses, trees: list[CullTree],
                       start: int, stop: int, splits: int = 0
                       ) -> list[tuple[int, int, np.ndarray | None]]:
        """``(start, stop, grid)`` for consecutive blocks of the pulses ``start:stop``: the
        cube map of each block (:meth:`_moving_grid`), or None where the pulses are to be
        tested one by one."""
        grid, too_fast = self._moving_grid(posed, trees, start, stop)
        if grid is None and too_fast and stop - start >= 2 * MIN_MOVING_BLOCK and \
                splits < MAX_MOVING_SPLITS:
            middle = (start + stop) // 2
            return self._moving_blocks(posed, trees, start, middle, splits + 1) + \
                self._moving_blocks(posed, trees, middle, stop, splits + 1)
        return [(start, stop, grid)]

    def _still_grid(self, posed: PiecePoses, trees: list[CullTree]) -> np.ndarray | None:
        """:meth:`_pose_grid` of a still scene, looked up by its pose arrays: the run's context
        gives every piece the same ones (it looks a static trajectory's pose up once), so the
        map is found without the ~15 small NumPy calls that make the key of a pose (they held
        the GIL that other threads' pieces wait for). The arrays are kept with the map, so an
        identity cannot be reused while it is cached."""
        poses = tuple(a for p in (posed.sensor, *posed.targets) for a in (p.position, p.matrix))
        key = ("still", *(id(a) for a in poses))
        with _grids_lock:
            found = self._grids.get(key)
        if found is not None and all(a is b for a, b in zip(found[1], poses)):
            return found[0]
        grid = self._pose_grid(posed, 0, [0.0] * len(trees), trees, CULL_TREE_LEVELS)
        with _grids_lock:
            if len(self._grids) >= 16:
                self._grids.pop(next(iter(self._grids)))
            self._grids[key] = (grid, poses)
        return grid

    def _pose_grid(self, posed: PiecePoses, k: int, motion: list[float],
                   trees: list[CullTree], levels: int) -> np.ndarray | None:
        """The cube map of the reachable directions at pose row ``k`` from the trees' boxes
        down to ``levels``, every target's boxes also grown by its ``motion`` (m)."""
        sensor_rotation = posed.sensor.matrix[min(k, len(posed.sensor.matrix) - 1)]
        sensor_position = posed.sensor.position[min(k, len(posed.sensor.position) - 1)]
        rotations, origins, grows = [], [], []
        for poses, (lo, hi, _, _), moved in zip(posed.targets, trees, motion):
            to_body = poses.matrix[min(k, len(poses.matrix) - 1)].T
            rotations.append((to_body @ sensor_rotation)[None])
            origin = to_body @ (sensor_position - poses.position[min(k, len(poses.position) - 1)])
            origins.append(origin[None])
            # farthest corner of the target's box from the origin (plus how far the target
            # moves): the chord between two rays at angle a is below s·a for every distance s
            # up to it; the last terms cover the rounding of the box test itself
            far = np.sqrt((np.maximum(np.abs(lo[0] - origin), np.abs(hi[0] - origin)) ** 2
                           ).sum()) + moved
            grows.append(np.array([far * (self.margin_rad + 1e-9) + moved * (1 + 1e-9)
                                   + 1e-9]))
        return self._grid(rotations, origins, grows, trees, levels)

    def _moving_grid(self, posed: PiecePoses, trees: list[CullTree],
                     start: int, stop: int) -> tuple[np.ndarray | None, bool]:
        """With a pose per pulse, the cube map of the pulses ``start:stop`` at their middle
        pose with every box grown by how far the target moves relative to the sensor among
        them (a box grown by ``d`` in the body frame holds every point that strays by at
        most ``d``), and whether a target moves more than a tenth of its size among them
        (then the grid is None, and smaller blocks may do). The grid is also None when the
        sensor is within a grown box."""
        from ..kernels.cull import motion_bound

        def rows(array: np.ndarray) -> np.ndarray:
            return array if len(array) == 1 else array[start:stop]

        middle = (stop - start) // 2
        motion = []
        for poses, (lo, hi, _, _) in zip(posed.targets, trees):
            size = float(np.linalg.norm(hi[0] - lo[0]))
            reach = float(np.sqrt((np.maximum(np.abs(lo[0]), np.abs(hi[0])) ** 2).sum()))
            moved = motion_bound(rows(posed.sensor.matrix), rows(posed.sensor.position),
                                 rows(poses.matrix), rows(poses.position), middle, reach)
            if not moved <= 0.1 * size:
                return None, True
            motion.append(moved * (1 + 1e-9) + 1e-9)
        return self._pose_grid(posed, start + middle, motion, trees, MOVING_GRID_LEVELS), False

    def _grid(self, rotations: list[np.ndarray], origins: list[np.ndarray],
              grows: list[np.ndarray], trees: list[CullTree], levels: int
              ) -> np.ndarray | None:
        """The cube map of the directions that may reach a target from one pose of everything
        (:func:`lidarsim_core.kernels.cull.direction_grid`), cached by that pose."""
        from ..kernels.cull import direction_grid

        key = bytes([levels]) + b"".join(np.ascontiguousarray(a).tobytes()
                                         for a in (*rotations, *origins, *grows))
        with _grids_lock:
            if key in self._grids:
                return self._grids[key]
        corners = []
        for rotation, origin, grow, tree in zip(rotations, origins, grows, trees):
            leaf = tree.boxes(levels)
            low, high = tree.lo[leaf] - grow[0], tree.hi[leaf] + grow[0]
            # the eight corners of each grown leaf box, body frame -> sensor frame
            body = np.where(_CORNERS[None], high[:, None, :], low[:, None, :])
            corners.append((body - origin[0]) @ rotation[0])
        grid = direction_grid(np.ascontiguousarray(np.concatenate(corners)), GRID_CELLS)
        with _grids_lock:  # pieces on several threads may build the same map: keep one
            if len(self._grids) >= 16:  # poses of a frozen sequence: keep the newest few
                self._grids.pop(next(iter(self._grids)))
            self._grids[key] = grid
        return grid


def _reach(lo: np.ndarray, hi: np.ndarray) -> float:
    """The farthest corner of the box ``lo``–``hi`` from the origin."""
    return float(np.sqrt((np.maximum(np.abs(lo), np.abs(hi)) ** 2).sum()))


def _strays(turn_s: float, speed_s: float, turn_t: float, speed_t: float,
            span: float | np.ndarray, reach: float, distance: float | np.ndarray
            ) -> float | np.ndarray:
    """How far a body point within ``reach`` of a target's origin strays in the sensor frame
    within ``span`` seconds of a time at which the target's origin is ``distance`` from the
    sensor's (see :meth:`PulseCuller.keep_before_poses`), with slack for rounding."""
    moved = (turn_s + turn_t) * span * reach + (speed_s + speed_t) * span + \
        turn_s * span * distance
    return moved * (1.0 + 1e-9) + 1e-9 + 1e-12 * (reach + distance)


def culled_piece(ctx: RunContext, culler: "PulseCuller | None", index: np.ndarray,
                 t_frame: float) -> RayBatch:
    """The rays of the pulses ``index`` (ascending, consecutive) that may reach a target, with
    their poses: the rays of :func:`pattern_candidates` only, culled and posed by
    :func:`culled_with_poses`."""
    candidates = pattern_candidates(ctx, culler, index, t_frame)
    return culled_with_poses(ctx, culler, ctx.pattern.rays_for_indices(candidates), t_frame)


def pattern_candidates(ctx: RunContext, culler: "PulseCuller | None", index: np.ndarray,
                       t_frame: float, grouped: "DirectionGroups | None" = None,
                       representatives: RayBatch | None = None) -> np.ndarray:
    """The pulses of ``index`` (ascending, consecutive) whose rays are to be computed. When
    the pattern groups its rays by direction
    (:meth:`~lidarsim_core.patterns.base.ScanPattern.direction_groups`: every ray of a group
    within an angle of its representative), the pulses of the groups whose representative
    passes the cull with the margin grown by that angle, over the piece's time span; else
    (and for pieces too short for the groups to pay, :data:`GROUPED_STILL`,
    :data:`GROUPED_MOVING`) every pulse. ``grouped`` and ``representatives`` may pass the
    groups and their rays when already computed."""
    pattern = ctx.pattern
    if grouped is None and culler is not None and len(index) >= _fewest_grouped(ctx) and \
            _defines(pattern, "direction_groups", "rays_for_indices"):
        grouped = pattern.direction_groups(index)
    if grouped is None:
        return index
    if representatives is None:
        representatives = pattern.rays_for_indices(grouped.representative)
    ends = pattern.time_of_index(index[[0, -1]])  # emitted in the order of the indices
    kept = culler.widened(grouped.angle).keep_before_poses(
        ctx, representatives, t_frame, span=(float(ends.min()), float(ends.max())),
        groups=True)
    return index if kept is None else grouped.members(kept)


def _fewest_grouped(ctx: RunContext) -> int:
    """Fewest pulses of a piece culled by direction groups: the groups' cull costs a piece
    ~0.1 ms in a still scene (its cube map is kept) and ~1 ms when something moves (poses at
    the piece's middle time and a cube map of its own, on top of the pulses' own), and saves
    ~20 ns a pulse: pieces of 10,000 pulses of the tumbling Risley took 128 against 84 ns a
    pulse with groups, of 50,000 49 against 56, of 100,000 40 against 52."""
    return GROUPED_STILL if _one_pose_a_frame(ctx) else GROUPED_MOVING


def _one_pose_a_frame(ctx: RunContext) -> bool:
    """Whether the sensor and every target keep one pose through a frame (a frozen scan, or
    nothing moves)."""
    trajectories = [ctx.sensor_trajectory] + [target.trajectory for target in ctx.targets]
    return ctx.scenario.scan.motion == "frozen" or all(tr.is_static for tr in trajectories)


def _defines(obj: object, name: str, under: str) -> bool:
    """Whether ``obj``'s class defines ``name`` in the class that defines ``under`` or below
    it (a subclass that redefines ``under`` alone would break ``name``'s promise)."""
    mro = type(obj).__mro__

    def position(attribute: str) -> int:
        return next((i for i, k in enumerate(mro) if attribute in vars(k)), len(mro))

    return position(name) <= position(under)


def culled_with_poses(ctx: RunContext, culler: "PulseCuller | None", batch: RayBatch,
                      t_frame: float) -> RayBatch:
    """``batch``'s pulses that may reach a target, with their poses attached
    (:func:`~lidarsim_core.pipeline.posing.with_piece_poses`): culled first and posed after
    when the culler can decide without per-pulse poses (:meth:`PulseCuller.keep_before_poses`),
    else posed first. A pose is a function of the pulse's time alone, so either order gives
    a kept pulse the same bits."""
    if culler is None:
        return with_piece_poses(ctx, batch, t_frame)
    rows = culler.keep_before_poses(ctx, batch, t_frame)
    if rows is not None:
        return with_piece_poses(ctx, batch.take(rows), t_frame)
    batch = with_piece_poses(ctx, batch, t_frame)
    return batch.take(culler.keep(ctx, batch, t_frame))


_grids_lock = threading.Lock()
#: Which corner of a box takes the high end of each axis (8 corners x 3 axes).
_CORNERS = np.array([[i & 1, (i >> 1) & 1, (i >> 2) & 1] for i in range(8)], dtype=bool)
_trees: dict[str, CullTree] = {}
_trees_lock = threading.Lock()


def _build_tree(mesh: Mesh) -> CullTree:
    """:func:`cull_tree`'s tree, made a level at a time: the level's nodes hold consecutive
    runs of ``order``, their boxes are reductions over the runs and the splitting nodes' runs
    are sorted in one stable sort keyed by node, then by the split axis: the nodes, boxes and
    children of the node-at-a-time definition, in its breadth-first order, in a quarter of
    its time for the demo's Envisat (9,884 triangles: 18 against 76 ms, part of a new
    process's first frame; 148 against 228 ms for the 95,804 of ``detail: fine``)."""
    triangles = mesh.triangles
    tri_lo, tri_hi = triangles.min(axis=1), triangles.max(axis=1)
    order = np.arange(len(triangles))  # the level's triangles, node after node
    sizes = np.array([len(triangles)])  # how many each node of the level holds
    lo, hi, child, depth = [], [], [], []
    made = 0  # nodes of the levels above
    for level in range(CULL_TREE_LEVELS + 1):
        starts = np.cumsum(sizes) - sizes
        lo.append(np.minimum.reduceat(tri_lo[order], starts, axis=0))
        hi.append(np.maximum.reduceat(tri_hi[order], starts, axis=0))
        depth.append(np.full(len(sizes), level, dtype=np.int64))
        split = (sizes >= 2 * MIN_BOX_TRIANGLES) & (level < CULL_TREE_LEVELS)
        # breadth first: a level's children follow it, two per splitting node, in its order
        child.append(np.where(split, made + len(sizes) + 2 * (np.cumsum(split) - split), -1))
        made += len(sizes)
        if not split.any():
            break
        kept = np.repeat(split, sizes)  # the triangles of the nodes that split
        node, order = np.repeat(np.arange(len(sizes)), sizes)[kept], order[kept]
        axis = (hi[-1] - lo[-1]).argmax(axis=1)  # split at the median of the longest axis
        key = tri_lo[order, axis[node]] + tri_hi[order, axis[node]]
        order = order[np.lexsort((key, node))]
        halves = sizes[split] // 2
        sizes = np.stack([halves, sizes[split] - halves], axis=1).reshape(-1)
    return CullTree(np.concatenate(lo), np.concatenate(hi),
                    np.concatenate(child).astype(np.int64), np.concatenate(depth))


def cull_tree(mesh: Mesh) -> CullTree:
    """A tree of boxes over ``mesh``'s triangles, in its own frame (:class:`CullTree`).

    Triangles are split at the median of the longest axis for :data:`CULL_TREE_LEVELS`
    levels (groups of fewer than ``2 * MIN_BOX_TRIANGLES`` are not split), so a satellite's
    body and its solar array get boxes of their own and rays passing between them are culled
    too; node 0 is the mesh's bounding box. Cached per mesh content.
    """
    with _trees_lock:
        tree = _trees.get(mesh.key)
    if tree is None:
        tree = _build_tree(mesh)
        with _trees_lock:
            if len(_trees) >= 64:  # meshes come and go in long sessions: keep the newest
                _trees.pop(next(iter(_trees)))
            _trees[mesh.key] = tree
    return tree
