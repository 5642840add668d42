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

import numpy as np

from .. import kernels
from ..geometry.posing import PoseMatrices
from ..noise.outliers import SpuriousReturnModel
from ..patterns.base import RayBatch
from ..scene.mesh import Mesh
from .context import RunContext
from .posing import PiecePoses, piece_poses

#: Levels of median splits of a mesh's triangles into culling boxes (up to 2**levels leaves).
CULL_TREE_LEVELS = 6
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


@dataclass(frozen=True)
class PulseCuller:
    """The culling plan of one simulation (see the module docstring).

    Attributes
    ----------
    margin_rad
        Largest angle between a flown (sub-)ray and its pulse's nominal direction.
    """

    margin_rad: float
    #: Cube maps of reachable directions by pose (:meth:`keep`), newest last.
    _grids: dict[bytes, np.ndarray | None] = field(default_factory=dict, compare=False,
                                                   repr=False)

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
        # one pose for the piece: look the directions up in a cube map
        grid = self._pose_grid(posed, 0, [0.0] * len(trees), trees)
        if grid is None:  # the sensor is inside a target's box: nothing to cull
            return np.arange(len(batch), dtype=np.int64)
        return cull_by_grid(directions, grid)

    def _per_pulse(self, directions: np.ndarray, posed: PiecePoses,
                   trees: list[tuple[np.ndarray, ...]], start: int, stop: int) -> np.ndarray:
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
        roots = np.cumsum([0] + [len(lo) for lo, _, _ in trees])[:-1]
        return cull_posed(
            directions, sensor.matrix, sensor.position,
            np.concatenate([p.matrix for p in targets]),
            np.concatenate([p.position for p in targets]),
            first, moving, np.concatenate([t[0] for t in trees]),
            np.concatenate([t[1] for t in trees]),
            np.concatenate([np.where(t[2] >= 0, t[2] + root, -1)
                            for t, root in zip(trees, roots)]),
            roots, self.margin_rad)

    def _moving_blocks(self, posed: PiecePoses, trees: list[tuple[np.ndarray, ...]],
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

    def _pose_grid(self, posed: PiecePoses, k: int, motion: list[float],
                   trees: list[tuple[np.ndarray, ...]]) -> np.ndarray | None:
        """The cube map of the reachable directions at pose row ``k``, every target's boxes
        also grown by its ``motion`` (m)."""
        sensor_rotation = posed.sensor.matrix[min(k, len(posed.sensor.matrix) - 1)]
        sensor_position = posed.sensor.position[min(k, len(posed.sensor.position) - 1)]
        rotations, origins, grows = [], [], []
        for poses, (lo, hi, _), moved in zip(posed.targets, trees, motion):
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
        return self._grid(rotations, origins, grows, trees)

    def _moving_grid(self, posed: PiecePoses, trees: list[tuple[np.ndarray, ...]],
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
        for poses, (lo, hi, _) in zip(posed.targets, trees):
            size = float(np.linalg.norm(hi[0] - lo[0]))
            reach = float(np.sqrt((np.maximum(np.abs(lo[0]), np.abs(hi[0])) ** 2).sum()))
            moved = motion_bound(rows(posed.sensor.matrix), rows(posed.sensor.position),
                                 rows(poses.matrix), rows(poses.position), middle, reach)
            if not moved <= 0.1 * size:
                return None, True
            motion.append(moved * (1 + 1e-9) + 1e-9)
        return self._pose_grid(posed, start + middle, motion, trees), False

    def _grid(self, rotations: list[np.ndarray], origins: list[np.ndarray],
              grows: list[np.ndarray], trees: list[tuple[np.ndarray, ...]]
              ) -> np.ndarray | None:
        """The cube map of the directions that may reach a target from one pose of everything
        (:func:`lidarsim_core.kernels.cull.direction_grid`), cached by that pose."""
        from ..kernels.cull import direction_grid

        key = b"".join(np.ascontiguousarray(a).tobytes() for a in (*rotations, *origins, *grows))
        with _grids_lock:
            if key in self._grids:
                return self._grids[key]
        corners = []
        for rotation, origin, grow, (lo, hi, child) in zip(rotations, origins, grows, trees):
            leaf = child < 0
            low, high = lo[leaf] - grow[0], hi[leaf] + grow[0]
            # the eight corners of each grown leaf box, body frame -> sensor frame
            body = np.where(_CORNERS[None], high[:, None, :], low[:, None, :])
            corners.append((body - origin[0]) @ rotation[0])
        grid = direction_grid(np.ascontiguousarray(np.concatenate(corners)), GRID_CELLS)
        with _grids_lock:  # pieces on several threads may build the same map: keep one
            if len(self._grids) >= 16:  # poses of a frozen sequence: keep the newest few
                self._grids.pop(next(iter(self._grids)))
            self._grids[key] = grid
        return grid


_grids_lock = threading.Lock()
#: Which corner of a box takes the high end of each axis (8 corners x 3 axes).
_CORNERS = np.array([[i & 1, (i >> 1) & 1, (i >> 2) & 1] for i in range(8)], dtype=bool)
_trees: dict[str, tuple[np.ndarray, np.ndarray, np.ndarray]] = {}
_trees_lock = threading.Lock()


def _build_tree(mesh: Mesh) -> tuple[np.ndarray, np.ndarray, np.ndarray]:
    triangles = mesh.triangles
    tri_lo, tri_hi = triangles.min(axis=1), triangles.max(axis=1)
    lo, hi, child = [], [], []
    # breadth first, so that a node's two children are consecutive
    queue = [(np.arange(len(triangles)), 0)]
    while queue:
        group, level = queue.pop(0)
        lo.append(tri_lo[group].min(axis=0))
        hi.append(tri_hi[group].max(axis=0))
        if level == CULL_TREE_LEVELS or len(group) < 2 * MIN_BOX_TRIANGLES:
            child.append(-1)
            continue
        child.append(len(lo) + len(queue))
        axis = (hi[-1] - lo[-1]).argmax()  # split at the median of the longest axis
        order = np.argsort(tri_lo[group, axis] + tri_hi[group, axis], kind="stable")
        half = len(group) // 2
        queue += [(group[order[:half]], level + 1), (group[order[half:]], level + 1)]
    return np.array(lo), np.array(hi), np.array(child, dtype=np.int64)


def cull_tree(mesh: Mesh) -> tuple[np.ndarray, np.ndarray, np.ndarray]:
    """A shallow tree of boxes over ``mesh``'s triangles, in its own frame.

    Returns ``(lo, hi, first_child)``: (B, 3) box corners and (B,) the first of each node's
    two children (-1 for a leaf); node 0 is the mesh's bounding box. Triangles are split at
    the median of the longest axis for :data:`CULL_TREE_LEVELS` levels, so a satellite's body
    and its solar array get boxes of their own and rays passing between them are culled too.
    Cached per mesh content.
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
