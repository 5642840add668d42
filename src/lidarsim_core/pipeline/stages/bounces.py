r"""Multipath: specular bounces and the ghost returns they make (docs/realism.md, "Multipath").

A pulse whose surface has a specular component (``specular_reflectance`` F > 0) continues
along the mirror direction ``d' = d − 2 (d·n) n`` and is cast again through the same backend
against every target, up to ``max_bounces`` times. A LiDAR is monostatic, so the light that
comes back to the sensor retraces the path: after b bounces the surface finally met is seen
at the *total* path length ``L = d_1 + ... + d_{b+1}`` (half the round trip), along the
original ray, i.e. at its mirror image. Its apparent reflectivity is

.. math::  ρ_\mathrm{ghost} = ρ_\mathrm{eff}(θ_{b+1}) \prod_{i=1}^{b} κ_i^2,
           \qquad κ(θ) = F \left[1 - \exp\!\left(-\frac{\tan^2(γ/2)}{m^2 \cos θ}\right)\right]

κ is the one-way coupling of a Beckmann mirror (RMS slope m, Fresnel reflectance F) at
incidence θ: the share of the reflected lobe that stays within the receiver's acceptance
half-angle γ (``acceptance_deg``) of the mirror direction. Facet tilts θ_h are Beckmann
distributed (P(tan θ_h < x) = 1 − exp(−x²/m²)), and a cone of half-angle γ of reflected
directions holds the half-vectors within a solid angle 4 cos θ times smaller
(dω_o = 4 cos θ dω_h), hence the closed form. A flat mirror (m ≪ γ) gives κ = F; a rough one
scatters most of the light out of the receiver's view. The light crosses each mirror twice
(out and back), hence κ². The signal follows the link budget, ``S = C ρ_ghost / L^n``, and the
ghost competes with the direct returns in the detection and the return mode.

Reads ``piece.hits`` (with normals), ``piece.scene`` and ``piece.cand``; writes ``piece.cand``
(ghosts added, every candidate with its ``bounces`` count and, for ghosts, the true surface
point in the sensor frame).
"""

from __future__ import annotations

import math
from dataclasses import replace

import numpy as np

from ...geometry.frames import rotate, to_body
from ...geometry.vec3 import rowdot
from ...instrument.returns import Candidates, SubRayHits, group_sub_rays
from ...scenario.sensor import DEFAULT_ACCEPTANCE_DEG, MultipathConfig
from ..context import RunContext
from .base import Piece

#: A bounce ray starts this far (m, plus the same relative to the path) along its new
#: direction, so the backend cannot find the mirror itself again; the offset is added to the
#: path, so ranges stay exact.
BOUNCE_OFFSET_M = 1e-6


def acceptance_deg(config: MultipathConfig, divergence_deg: tuple[float, float] | None) -> float:
    """γ: the configured value, else half the datasheet's mean full divergence, else the
    default."""
    if config.acceptance_deg is not None:
        return config.acceptance_deg
    if divergence_deg is not None and sum(divergence_deg) > 0:
        return 0.25 * (divergence_deg[0] + divergence_deg[1])
    return DEFAULT_ACCEPTANCE_DEG


def mirror_coupling(reflectance: np.ndarray, slope2: np.ndarray, cos_incidence: np.ndarray,
                    acceptance_rad: float) -> np.ndarray:
    """κ(θ) = F [1 − exp(−tan²(γ/2) / (m² cos θ))] (see the module docstring)."""
    c = np.maximum(np.asarray(cos_incidence, dtype=np.float64), 1e-12)
    t2 = math.tan(0.5 * acceptance_rad) ** 2
    return np.asarray(reflectance) * -np.expm1(-t2 / (np.asarray(slope2) * c))


class BounceStage:
    """Ghost returns from specular bounces (see the module docstring)."""

    name = "bounces"

    def __init__(self, ctx: RunContext, config: MultipathConfig) -> None:
        self.max_bounces = config.max_bounces
        self.min_coupling = config.min_coupling
        self.acceptance_rad = math.radians(acceptance_deg(config, ctx.sensor.beam_divergence_deg))
        self.backend = ctx.backend
        self.targets = ctx.targets
        self.materials = ctx.materials
        self.link = ctx.link
        self.sub_rays = ctx.sub_rays
        self.range_resolution_m = ctx.range_resolution_m

    def info(self) -> dict:
        """Frame metadata: the bounce settings."""
        return {"max_bounces": self.max_bounces,
                "acceptance_deg": math.degrees(self.acceptance_rad),
                "min_coupling": self.min_coupling}

    def coupling(self, part: np.ndarray, cos_incidence: np.ndarray) -> np.ndarray:
        """κ of hits on ``part`` at incidence cosines ``cos_incidence``."""
        return mirror_coupling(self.materials.specular[part], self.materials.slope2[part],
                               cos_incidence, self.acceptance_rad)

    def run(self, piece: Piece) -> None:
        hits, scene = piece.hits, piece.scene
        k = 1 if self.sub_rays is None else self.sub_rays.count
        ray = np.flatnonzero(hits.target >= 0)  # flat (sub-)ray index of every live path
        pulse = ray // k
        d_all = scene.vectors[0] if self.sub_rays is None else \
            self.sub_rays.directions(*scene.vectors)
        direction = d_all[ray]
        origin = scene.origin if len(scene.origin) == 1 else scene.origin[pulse]
        path = hits.distance[ray]
        point = origin + direction * path[:, None]
        target, face, part = hits.target[ray], hits.face[ray], hits.part[ray]
        cos_inc, normal = hits.cos_incidence[ray], hits.normal[ray]
        gain = np.ones(len(ray))
        ghosts: list[Candidates] = []
        for bounce in range(1, self.max_bounces + 1):
            gain = gain * self.coupling(part, cos_inc) ** 2
            go = np.flatnonzero(gain > self.min_coupling)
            if not len(go):
                break
            ray, pulse, direction, path, point = ray[go], pulse[go], direction[go], path[go], \
                point[go]
            target, face, gain, normal = target[go], face[go], gain[go], normal[go]
            # the mirror's normal in the scene frame, then the mirror direction
            n_scene = np.empty_like(normal)
            for j in np.unique(target):
                sel = np.flatnonzero(target == j)
                n_scene[sel] = rotate(scene.target_poses[j].take(pulse[sel]), normal[sel])
            direction = direction - 2.0 * rowdot(direction, n_scene)[:, None] * n_scene
            direction /= np.linalg.norm(direction, axis=1)[:, None]
            offset = BOUNCE_OFFSET_M * (1.0 + path)
            start = point + direction * offset[:, None]
            t, new_target, new_face, new_part, new_cos, new_normal = self._cast(
                start, direction, pulse, scene.target_poses, target, face)
            hit = np.flatnonzero(new_target >= 0)
            ray, pulse, direction, gain = ray[hit], pulse[hit], direction[hit], gain[hit]
            t = t[hit]
            path = path[hit] + offset[hit] + t
            point = start[hit] + direction * t[:, None]
            target, face, part = new_target[hit], new_face[hit], new_part[hit]
            cos_inc, normal = new_cos[hit], new_normal[hit]
            true_point = to_body(scene.sensor_poses.take(pulse), point)
            ghosts.append(self._candidates(piece, bounce, ray, path, target, face, part,
                                           cos_inc, gain, true_point, len(hits.distance), k))
            if not len(ray):
                break
        ghosts = [g for g in ghosts if len(g)]
        if ghosts:
            piece.cand = Candidates.concatenate([piece.cand, *ghosts])
        else:  # nothing to merge: every candidate is direct, already in (pulse, range) order
            m = len(piece.cand)
            piece.cand = replace(piece.cand, bounces=np.zeros(m, dtype=np.uint8),
                                 true_point=np.full((m, 3), np.nan))

    def _cast(self, origin: np.ndarray, direction: np.ndarray, pulse: np.ndarray,
              target_poses: list, from_target: np.ndarray, from_face: np.ndarray
              ) -> tuple[np.ndarray, ...]:
        """Closest hit of scene-frame rays on every target (not the face they leave)."""
        n = len(origin)
        best = np.full(n, np.inf)
        target_id = np.full(n, -1, dtype=np.int16)
        face = np.full(n, -1, dtype=np.int64)
        part = np.full(n, -1, dtype=np.int16)
        cos_inc = np.zeros(n)
        normal = np.zeros((n, 3))
        for j, target in enumerate(self.targets):
            poses = target_poses[j].take(pulse)
            o_body = to_body(poses, origin)
            d_body = rotate(poses, direction, inverse=True)
            hits = self.backend.cast(target.mesh, o_body, d_body)
            # a flat face cannot see its own reflection: drop a re-hit of the face left
            again = (from_target == j) & (hits.face == from_face)
            closer = np.flatnonzero(hits.hit & ~again & (hits.distance < best))
            best[closer] = hits.distance[closer]
            target_id[closer] = j
            face[closer] = hits.face[closer]
            part[closer] = target.mesh.face_part[hits.face[closer]] + target.part_offset
            cos_inc[closer] = np.abs(rowdot(hits.normal[closer], d_body[closer]))
            normal[closer] = hits.normal[closer]
        return best, target_id, face, part, cos_inc, normal

    def _candidates(self, piece: Piece, bounce: int, ray: np.ndarray, path: np.ndarray,
                    target: np.ndarray, face: np.ndarray, part: np.ndarray,
                    cos_inc: np.ndarray, gain: np.ndarray, true_point: np.ndarray,
                    n_rays: int, k: int) -> Candidates:
        """Ghost candidates of one bounce count (sub-rays grouped by range like direct ones)."""
        link = self.link
        exponent = link.exponent
        m = len(ray)
        if self.sub_rays is None:
            rho = self.materials.effective(part, cos_inc) * gain
            zeros = np.zeros(m, dtype=np.int64)
            return Candidates(ray, zeros, path, path, zeros,
                              link.constant * rho / path ** exponent, rho, target, face, part,
                              cos_inc, np.full(m, bounce, dtype=np.uint8), true_point)
        flat = SubRayHits(np.full(n_rays, np.inf), np.full(n_rays, -1, dtype=np.int16),
                          np.full(n_rays, -1, dtype=np.int64), np.zeros(n_rays, dtype=np.int16),
                          np.zeros(n_rays))
        flat.distance[ray], flat.target[ray], flat.face[ray] = path, target, face
        flat.part[ray], flat.cos_incidence[ray] = part, cos_inc
        gains = np.zeros(n_rays)
        gains[ray] = gain
        points = np.full((n_rays, 3), np.nan)
        points[ray] = true_point
        pulse, rank, rng, strongest, power, rng_true = group_sub_rays(
            flat, k, self.sub_rays.weights, self.materials.effective, exponent,
            self.range_resolution_m, gain=gains)
        return Candidates(pulse, rank, rng, rng_true, strongest % k, link.constant * power,
                          power * rng ** exponent, flat.target[strongest], flat.face[strongest],
                          flat.part[strongest], flat.cos_incidence[strongest],
                          np.full(len(pulse), bounce, dtype=np.uint8), points[strongest])
