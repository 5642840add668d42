"""The fast path of the seed paper's model: one piece of pulses after culling, in compiled
loops around the cast, with the same bits as the general path.

The general path (:func:`lidarsim_core.pipeline.cast.process_piece`) runs the noise chain's
``perturb_rays``, the frame changes, the cast and every measurement stage as vectorised NumPy
on a :class:`~lidarsim_core.pipeline.stages.Piece`: about a hundred nanoseconds of array
temporaries per pulse on top of the cast. When a scenario runs exactly the seed paper's model,
:class:`FusedPath` does the same work in the kernels of :mod:`lidarsim_core.kernels.fused`
(GIL released):

1. the angular error (Philox uniforms, inverse-CDF normals, two rotations) and the rotation
   into the scene frame; per target, the origin and directions in its body frame;
2. the backend's cast of those arrays on each target (``backend.cast``, as the general path);
   or, when every target's backend gives a compiled cast
   (:meth:`~lidarsim_core.backends.base.RayBackend.compiled_cast`: Embree through its
   binding), :func:`lidarsim_core.kernels.fused_cast.cast_closest` instead of steps 1's body
   arrays, 2 and 3: per packet of rays, the body-frame rays, Embree's packet cast, the
   float64 refinement and the closest target in one compiled loop;
3. the closest target with its face, part and incidence cosine; the range gate; the range
   errors; the measured and true points, written into arrays of the returned pulses' length;
4. the columns that need NumPy's own transcendental functions (azimuth, elevation, incidence
   angle, intensity from the materials), computed on the returned pulses only, so that they
   are NumPy's bits.

When it applies (:meth:`FusedPath.for_context`): the compiled kernels are on
(``LIDARSIM_KERNELS`` is not ``numpy``), every noise model is the built-in ``angular``,
``range``, ``range_systematic`` or ``range_quantisation`` (not a subclass, not another model,
not a third-party one), the normals are the seed paper's inverse CDF (``normals:
inverse_cdf``) or the Ziggurat (``normals: ziggurat``), and the measurement stages are exactly
the seed paper's (candidates, detection, returns, noise: no ``sensor.beam`` sub-rays,
``sensor.detection``, multipath, Sun or Earth, receiver, false alarms or kept undetected
returns). Patterns, trajectories and backends may be anyone's: the path reads only the
piece's rays and poses and casts through ``backend.cast``. Everything else runs the general
path, which stays the reference; ``tests/test_fused.py`` compares the two column by column.
"""

from __future__ import annotations

from dataclasses import dataclass
from typing import Sequence

import numpy as np

from .. import kernels
from ..noise.base import NoiseContext
from ..noise.gaussian import AngularError, RangeError
from ..noise.range_models import RangeBias, RangeQuantisation
from ..backends.base import CompiledCast
from ..noise import ziggurat
from ..noise.rng import INVERSE_CDF, NORMAL_GENERATORS, stream_key
from ..patterns.base import RayBatch
from .bodyframe import body_frame_columns
from .context import RunContext
from .posing import piece_poses
from .stages import CandidateStage, DetectionStage, NoiseStage, SelectionStage, Stage

#: The seed paper's measurement stages, in order: the only chain the fast path computes.
SEED_STAGES = (CandidateStage, DetectionStage, SelectionStage, NoiseStage)
#: The return-stage models the fast path computes (the classes themselves, not subclasses).
RANGE_MODELS = (RangeError, RangeBias, RangeQuantisation)


@dataclass
class CastRays:
    """A piece between the two halves of the fast path: its rays in every frame the cast
    needs (written by :meth:`FusedPath.before_cast`)."""

    batch: RayBatch
    #: (N, 3) directions flown, sensor frame.
    flown: np.ndarray
    #: Per target: (N, 3) origins and (N, 3) directions in its body frame (empty when the
    #: cast runs in the compiled loop, which computes them per packet).
    bodies: list[tuple[np.ndarray, np.ndarray]]
    #: (N, 3) directions in the scene frame.
    scene: np.ndarray | None = None
    #: The piece's poses (:func:`lidarsim_core.pipeline.posing.piece_poses`).
    posed: object = None


@dataclass
class ClosestHits:
    """The closest hit of every pulse of a piece (written by :meth:`FusedPath.closest`)."""

    distance: np.ndarray
    target: np.ndarray
    face: np.ndarray
    part: np.ndarray
    cos_incidence: np.ndarray


@dataclass
class Returned:
    """The pulses of a piece that return (written by :meth:`FusedPath.measure`)."""

    #: (M,) their rows in the piece, in order.
    rows: np.ndarray
    range_true: np.ndarray
    range_measured: np.ndarray
    #: (3, M) measured and true points, sensor frame.
    point: np.ndarray
    truth: np.ndarray


class FusedPath:
    """The compiled path of one run (see the module docstring); build it with
    :meth:`for_context`."""

    def __init__(self, ctx: RunContext) -> None:
        self.ctx = ctx
        self.angular = [i for i, m in enumerate(ctx.noise) if type(m) is AngularError]
        self.ranges = [i for i, m in enumerate(ctx.noise) if type(m) in RANGE_MODELS]
        #: Whether the normals are the Ziggurat's (else the seed paper's inverse CDF).
        self.ziggurat = ctx.scenario.normals != INVERSE_CDF
        self._compiled: list[CompiledCast] | None | bool = False  # False: not asked yet
        self._cached: tuple[tuple, tuple] | None = None  # (frame, parameters), _parameters

    @property
    def compiled(self) -> list[CompiledCast] | None:
        """Per target, the backend's compiled cast (asked on first use: it prepares the
        meshes); None: the cast goes through ``backend.cast`` (a backend without one)."""
        if self._compiled is False:
            casts = [self.ctx.backend.compiled_cast(target.mesh) for target in self.ctx.targets]
            self._compiled = casts if casts and all(c is not None for c in casts) else None
        return self._compiled  # type: ignore[return-value]

    @classmethod
    def for_context(cls, ctx: RunContext, stages: Sequence[Stage]) -> "FusedPath | None":
        """The fast path of ``ctx``'s run, or None when the run needs the general path."""
        if not kernels.enabled():
            return None
        if tuple(type(stage) for stage in stages) != SEED_STAGES:
            return None
        if not all(type(m) is AngularError or type(m) in RANGE_MODELS for m in ctx.noise):
            return None
        if ctx.scenario.normals not in NORMAL_GENERATORS:  # the kernels draw these two
            return None
        if (ctx.sub_rays is not None or ctx.link is not None or ctx.spurious
                or ctx.keep_undetected or ctx.keep_normals):
            return None
        return cls(ctx)

    # ---- the halves, for the pipeline and the benchmark ------------------------------------
    def _parameters(self, contexts: list[NoiseContext]) -> tuple[tuple[np.ndarray, ...],
                                                                 tuple[np.ndarray, ...]]:
        """:meth:`_keys` of the angular errors and :meth:`_range_models` for the frame of
        ``contexts``, made once a frame: its pieces share them (their streams' keys and the
        models' parameters), and a piece's Python steps hold the GIL that the other threads'
        pieces wait for."""
        frame = tuple((c.seed, c.frame, c.stream) for c in contexts)
        cached = self._cached
        if cached is None or cached[0] != frame:
            cached = (frame, (self._keys(self.angular, contexts),
                              self._range_models(contexts)))
            self._cached = cached  # one assignment: a thread reads the old or the new pair
        return cached[1]

    def _keys(self, models: list[int], contexts: list[NoiseContext]
              ) -> tuple[np.ndarray, np.ndarray]:
        """Philox keys and σ (rad) of the chain's angular errors that turn rays."""
        keys, sigmas = [], []
        for i in models:
            model, nctx = self.ctx.noise[i], contexts[i]
            sigma = model.sigma_rad(nctx)
            if sigma != 0.0:  # a zero σ leaves the ray alone, as the model does
                keys.append(stream_key(nctx.seed, nctx.frame, nctx.stream))
                sigmas.append(sigma)
        return (np.array(keys, dtype=np.uint64).reshape(-1, 2),
                np.array(sigmas, dtype=np.float64))

    def _range_models(self, contexts: list[NoiseContext]
                      ) -> tuple[np.ndarray, np.ndarray, np.ndarray]:
        """Kinds, Philox keys and parameters of the chain's range models that change ranges
        (:func:`lidarsim_core.kernels.fused.measure`), in chain order."""
        from ..kernels.fused import RANGE_GAUSSIAN, RANGE_QUANTISED, RANGE_SYSTEMATIC

        kinds, keys, params = [], [], []
        for i in self.ranges:
            model, nctx = self.ctx.noise[i], contexts[i]
            key = stream_key(nctx.seed, nctx.frame, nctx.stream)
            if type(model) is RangeError:
                sigma = model.sigma_m(nctx)
                if sigma != 0.0:  # a zero σ leaves ranges alone, as the model does
                    kinds.append(RANGE_GAUSSIAN)
                    keys.append(key)
                    params.append((sigma, 0.0))
            elif type(model) is RangeBias:
                o = model.options
                if not (o.bias_m == 0.0 and o.scale == 0.0):
                    kinds.append(RANGE_SYSTEMATIC)
                    keys.append(key)
                    params.append((1.0 + o.scale, o.bias_m))
            elif model.options.step_m != 0.0:
                kinds.append(RANGE_QUANTISED)
                keys.append(key)
                params.append((model.options.step_m, model.options.offset_m))
        return (np.array(kinds, dtype=np.int64), np.array(keys, dtype=np.uint64).reshape(-1, 2),
                np.array(params, dtype=np.float64).reshape(-1, 2))

    def before_cast(self, batch: RayBatch, contexts: list[NoiseContext], t_frame: float
                    ) -> CastRays:
        """The angular error and the frame changes of a piece: the arrays the cast reads."""
        from ..kernels.fused import body_rays, ray_stage

        n = len(batch)
        keys, sigmas = self._parameters(contexts)[0]
        posed = piece_poses(self.ctx, batch, t_frame)
        flown, scene = np.empty((n, 3)), np.empty((n, 3))
        direction = np.ascontiguousarray(batch.direction, dtype=np.float64)
        index = np.ascontiguousarray(batch.index, dtype=np.int64)
        if self.ziggurat:  # the Ziggurat's normals first (its rare rejections stay out of it)
            from ..kernels.fused import ray_stage_drawn

            ray_stage_drawn(direction, self._drawn(keys, index, 2), sigmas,
                            _c(posed.sensor.matrix), flown, scene)
        else:
            ray_stage(direction, index, keys, sigmas, _c(posed.sensor.matrix), flown, scene)
        if self.compiled is not None:  # the compiled loop makes the body rays per packet
            return CastRays(batch, flown, [], scene, posed)
        bodies = []
        sensor_position = _c(posed.sensor.position)
        for poses in posed.targets:
            origin, direction = np.empty((n, 3)), np.empty((n, 3))
            body_rays(scene, sensor_position, _c(poses.position), _c(poses.matrix), origin,
                      direction)
            bodies.append((origin, direction))
        return CastRays(batch, flown, bodies, scene, posed)

    def cast(self, rays: CastRays) -> list:
        """The backend's hits on every target (none for an empty piece)."""
        if len(rays.batch) == 0:
            return []
        return [self.ctx.backend.cast(target.mesh, origin, direction)
                for target, (origin, direction) in zip(self.ctx.targets, rays.bodies)]

    def cast_closest(self, rays: CastRays) -> ClosestHits:
        """The closest target of every pulse, with its face, part and incidence cosine: the
        cast and :meth:`closest`, or with compiled casts both in one compiled loop per
        target."""
        if self.compiled is None:
            return self.closest(rays, self.cast(rays))
        from ..kernels.fused_cast import cast_closest

        out = _no_hits(len(rays.batch))
        if len(rays.batch) == 0:
            return out
        sensor_position = _c(rays.posed.sensor.position)
        for j, (target, poses, handle) in enumerate(zip(self.ctx.targets, rays.posed.targets,
                                                        self.compiled)):
            cast_closest(handle.intersect, handle.scene, handle.width, handle.fields,
                         rays.scene, sensor_position, _c(poses.position), _c(poses.matrix),
                         handle.centre, handle.radius, handle.epsilon, handle.first_vertex,
                         handle.normals, np.ascontiguousarray(target.mesh.face_part),
                         target.part_offset, j, out.distance, out.target, out.face, out.part,
                         out.cos_incidence)
        return out

    def closest(self, rays: CastRays, hits: list) -> ClosestHits:
        """The closest target of every pulse, with its face, part and incidence cosine."""
        from ..kernels.fused import closest_hit

        out = _no_hits(len(rays.batch))
        for j, (target, found, (_, direction)) in enumerate(zip(self.ctx.targets, hits,
                                                                 rays.bodies)):
            closest_hit(j, _c(found.distance), _c(found.face, np.int64), _c(found.normal),
                        direction, np.ascontiguousarray(target.mesh.face_part), target.part_offset,
                        out.distance, out.target, out.face, out.part, out.cos_incidence)
        return out

    def measure(self, rays: CastRays, best: ClosestHits, contexts: list[NoiseContext]
                ) -> Returned:
        """The range gate and the range errors: the pulses that return, with their ranges and
        points."""
        from ..kernels.fused import RANGE_GAUSSIAN, measure

        kinds, keys, params = self._parameters(contexts)[1]
        range_min, range_max = float(self.ctx.sensor.range_min_m), float(self.ctx.range_limit)
        index = np.ascontiguousarray(rays.batch.index, dtype=np.int64)
        drawn = np.empty((len(kinds), 0))
        if self.ziggurat and (kinds == RANGE_GAUSSIAN).any():
            # the gate of the kernel, so that the normals are drawn for the returns only
            r = best.distance
            gate = (best.target >= 0) & (r >= range_min) & (r <= range_max)
            drawn = np.ascontiguousarray(self._drawn(keys, index[gate], 1)[:, :, 0])
        return Returned(*measure(best.distance, best.target, rays.flown, index, range_min,
                                 range_max, kinds, keys, params, drawn))

    @staticmethod
    def _drawn(keys: np.ndarray, index: np.ndarray, draws: int) -> np.ndarray:
        """(K, N, draws) Ziggurat normals of each stream key for rays ``index``."""
        from ..kernels.ziggurat import ray_normals

        out = np.empty((len(keys), len(index), draws))
        for a in range(len(keys)):
            key = keys[a].copy()
            key.flags.writeable = False  # as the stream keys the kernel is compiled for
            out[a] = ray_normals(key, index, draws, ziggurat.X_TABLE, ziggurat.F_TABLE)
        return out

    def columns(self, rays: CastRays, best: ClosestHits, returned: Returned, t_frame: float
                ) -> dict[str, np.ndarray]:
        """The point-record columns (:func:`lidarsim_core.pipeline.stages.record_columns`'s,
        in its order); those made of NumPy's transcendental functions (azimuth, elevation,
        incidence angle, intensity) are computed here, on the returned pulses only."""
        ctx, batch, rows = self.ctx, rays.batch, returned.rows
        azimuth, elevation = ctx.pattern.nominal_az_el(batch, rows)
        cos_incidence = best.cos_incidence[rows]
        part = best.part[rows]
        ones = np.ones(len(rows), dtype=np.uint8)
        point, truth = returned.point, returned.truth
        columns = {
            "x": point[0], "y": point[1], "z": point[2],
            "x_true": truth[0], "y_true": truth[1], "z_true": truth[2],
            "range": returned.range_measured, "range_true": returned.range_true,
            "azimuth": azimuth, "elevation": elevation, "timestamp": batch.t[rows],
            "return_number": ones, "number_of_returns": ones.copy(),
            "channel": batch.channel[rows], "ray_index": batch.index[rows],
            "face_index": best.face[rows], "target": best.target[rows], "part": part,
            "incidence_angle": np.arccos(np.clip(cos_incidence, 0.0, 1.0)),
            "intensity": ctx.materials.effective(part, cos_incidence).astype(np.float32),
            "detected": ones.copy(),
        }
        if ctx.scenario.scan.body_frame_truth:
            columns.update(body_frame_columns(ctx, columns, t_frame))
        return columns

    def process(self, batch: RayBatch, contexts: list[NoiseContext], t_frame: float
                ) -> dict[str, np.ndarray]:
        """Point-record columns of a piece of pulses (what ``process_piece`` returns)."""
        rays = self.before_cast(batch, contexts, t_frame)
        best = self.cast_closest(rays)
        return self.columns(rays, best, self.measure(rays, best, contexts), t_frame)


def _no_hits(n: int) -> ClosestHits:
    return ClosestHits(np.full(n, np.inf), np.full(n, -1, dtype=np.int16),
                       np.full(n, -1, dtype=np.int64), np.full(n, -1, dtype=np.int16),
                       np.zeros(n))


def _c(array: np.ndarray, dtype: type = np.float64) -> np.ndarray:
    return np.ascontiguousarray(array, dtype=dtype)
