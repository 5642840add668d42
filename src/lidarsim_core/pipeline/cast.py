"""Casting one piece of pulses: noise on the rays flown, frame changes, the cast on every
target, and the measurement stages.

These are the steps between culling and the record for one piece (a few tens of thousands of
pulses); :meth:`Simulation.iter_chunks <lidarsim_core.pipeline.simulation.Simulation.iter_chunks>`
runs them on its threads, and ``lidarsim bench`` times them one by one.
"""

from __future__ import annotations

from collections.abc import Sequence

import numpy as np

from ..geometry.frames import rotate, to_body
from ..geometry.vec3 import rowdot
from ..instrument.returns import SubRayHits
from ..noise.base import NoiseContext, perpendicular_basis
from ..patterns.base import RayBatch
from .context import RunContext
from .posing import piece_poses
from .stages import Piece, SceneRays, Stage, record_columns


def pulse_frames(ctx: RunContext, batch: RayBatch, contexts: list[NoiseContext],
                 t_frame: float) -> tuple[np.ndarray, list[np.ndarray],
                                          list[tuple[np.ndarray, list[np.ndarray]]], SceneRays]:
    """The rays of a piece in every frame the cast needs.

    Returns
    -------
    flown
        (N, 3) directions flown (sensor frame), after the ray-stage noise models.
    axes
        The beam's cross axes (u, v; sensor frame); empty without divergence.
    bodies
        Per target: the sensor origin and those vectors in its body frame.
    scene
        The scene-frame geometry, for stages that cast secondary rays.
    """
    flown = batch.direction
    for model, nctx in zip(ctx.noise, contexts):
        flown = model.perturb_rays(flown, batch.index, nctx)
    axes = list(perpendicular_basis(flown)) if ctx.sub_rays is not None else []
    posed = piece_poses(ctx, batch, t_frame)
    origin_scene = posed.sensor.position
    scene = [rotate(posed.sensor, vec) for vec in (flown, *axes)]
    bodies = []
    for poses in posed.targets:
        bodies.append((to_body(poses, origin_scene),
                       [rotate(poses, vec, inverse=True) for vec in scene]))
    return flown, axes, bodies, SceneRays(origin_scene, scene, posed.sensor,
                                          list(posed.targets))


def body_rays(ctx: RunContext, batch: RayBatch, contexts: list[NoiseContext], t_frame: float
              ) -> tuple[np.ndarray, list[tuple[np.ndarray, np.ndarray]]]:
    """Directions flown (sensor frame) and, per target, the rays in its body frame (one ray
    per pulse: the pulses' central rays)."""
    flown, _, bodies, _ = pulse_frames(ctx, batch, contexts, t_frame)
    return flown, [(np.broadcast_to(origin, vecs[0].shape), vecs[0]) for origin, vecs in bodies]


def cast_piece(ctx: RunContext, batch: RayBatch, contexts: list[NoiseContext], t_frame: float,
               frame: int = 0) -> Piece:
    """Cast every (sub-)ray of the pulses on every target; the closest target wins."""
    flown, axes, bodies, scene = pulse_frames(ctx, batch, contexts, t_frame)
    k = ctx.rays_per_pulse
    n = len(batch) * k
    best = np.full(n, np.inf)
    target_id = np.full(n, -1, dtype=np.int16)
    face = np.full(n, -1, dtype=np.int64)
    part = np.full(n, -1, dtype=np.int16)
    cos_inc = np.zeros(n)
    normal = np.zeros((n, 3)) if ctx.keep_normals else None
    for j, (target, (origin, vecs)) in enumerate(zip(ctx.targets, bodies)):
        if ctx.sub_rays is None:
            d_body = vecs[0]
        else:  # K sub-rays per pulse, formed from the rotated axes: one batch of N·K rays
            d_body = ctx.sub_rays.directions(*vecs)
            if len(origin) > 1:
                origin = np.repeat(origin, k, axis=0)
        hits = ctx.backend.cast(target.mesh, np.broadcast_to(origin, d_body.shape), d_body)
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


def process_piece(ctx: RunContext, stages: Sequence[Stage], batch: RayBatch,
                  contexts: list[NoiseContext], t_frame: float, frame: int = 0
                  ) -> dict[str, np.ndarray]:
    """Cast a piece of pulses, run the measurement stages in order, record the points."""
    piece = cast_piece(ctx, batch, contexts, t_frame, frame)
    for stage in stages:
        stage.run(piece)
    return record_columns(ctx, piece)
