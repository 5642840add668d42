"""Beam divergence: one pulse sampled by K sub-rays spread over its elliptical footprint.

The beam is Gaussian (datasheet divergences are full angles at the 1/e² intensity, so the
angular 1σ of the intensity profile is a quarter of the divergence) or a uniform (top-hat)
ellipse. K sub-rays share the pulse energy equally and are placed with the density of the
profile: sub-ray k sits at the radius holding the fraction ``u_k = (k + ½)/K`` of the
energy, at the golden angle ``k · 137.5°`` (a Vogel spiral). For a Gaussian profile
``r_k = σ √(−2 ln(1 − u_k))`` per axis, for a top-hat ``r_k = a √u_k`` with ``a`` the half
divergence. K = 1 is the single central ray of the seed paper.

A sub-ray's direction is ``(d + tan α_h,k · u + tan α_v,k · v) / √(1 + tan² α_h,k +
tan² α_v,k)`` with ``d`` the pulse's flown direction and ``u`` (horizontal: sensor +Y at the
boresight) and ``v = d × u`` (up) the axes of
:func:`~lidarsim_core.noise.base.perpendicular_basis`.
Because the coefficients are the same for every pulse, the K sub-rays of every pulse are
formed from three rotated vectors in one vectorised step and cast in one batch.
"""

from __future__ import annotations

import math
from dataclasses import dataclass

import numpy as np

from ..scenario.sensor import BeamConfig

#: Golden angle (rad): successive sub-rays turn by it, so any K covers the footprint evenly.
GOLDEN_ANGLE = math.pi * (3.0 - math.sqrt(5.0))


@dataclass(frozen=True)
class SubRays:
    """The sub-ray layout of a beam.

    Attributes
    ----------
    angles
        (K, 2) angular offsets (horizontal, vertical) from the pulse direction (rad).
    weights
        (K,) share of the pulse energy carried by each sub-ray (sums to 1).
    coefficients
        (K, 3) sub-ray direction = c0 · d + c1 · u + c2 · v (unit length by construction).
    """

    angles: np.ndarray
    weights: np.ndarray
    coefficients: np.ndarray

    @property
    def count(self) -> int:
        """K."""
        return len(self.weights)

    @classmethod
    def layout(cls, count: int, divergence_rad: tuple[float, float],
               profile: str = "gaussian") -> "SubRays":
        """The layout of ``count`` sub-rays for a full divergence (h, v) in radians."""
        k = np.arange(count, dtype=np.float64)
        if count == 1:
            radius = np.zeros(1)
        else:
            energy = (k + 0.5) / count
            radius = (np.sqrt(-2.0 * np.log1p(-energy)) if profile == "gaussian"
                      else np.sqrt(energy))
        # per-axis scale: Gaussian 1σ = divergence / 4 (1/e² full angle); top-hat half angle
        scale = np.asarray(divergence_rad, dtype=np.float64) / (4.0 if profile == "gaussian"
                                                                 else 2.0)
        phi = k * GOLDEN_ANGLE
        angles = np.stack([radius * np.cos(phi) * scale[0], radius * np.sin(phi) * scale[1]],
                          axis=1)
        tan_h, tan_v = np.tan(angles[:, 0]), np.tan(angles[:, 1])
        norm = np.sqrt(1.0 + tan_h * tan_h + tan_v * tan_v)
        coefficients = np.stack([1.0 / norm, tan_h / norm, tan_v / norm], axis=1)
        return cls(angles, np.full(count, 1.0 / count), coefficients)

    def directions(self, d: np.ndarray, u: np.ndarray, v: np.ndarray) -> np.ndarray:
        """(N·K, 3) sub-ray directions, pulse-major, from (N, 3) pulse axes ``d, u, v``."""
        c = self.coefficients
        out = np.empty((len(d), self.count, 3))
        for axis in range(3):  # (N, K) products per axis: fast inner loops over K
            np.multiply(d[:, axis, None], c[:, 0], out=out[:, :, axis])
            out[:, :, axis] += u[:, axis, None] * c[:, 1]
            out[:, :, axis] += v[:, axis, None] * c[:, 2]
        return out.reshape(-1, 3)

    def direction_of(self, k: np.ndarray, d: np.ndarray, u: np.ndarray,
                     v: np.ndarray) -> np.ndarray:
        """(M, 3) directions of sub-rays ``k`` of M pulses with axes ``d, u, v`` (M, 3)."""
        c = self.coefficients[k]
        return d * c[:, 0, None] + u * c[:, 1, None] + v * c[:, 2, None]


def sub_rays_for(config: BeamConfig, divergence_deg: tuple[float, float]) -> SubRays:
    """The sub-ray layout of ``config`` for a full divergence (h, v) in degrees."""
    return SubRays.layout(config.sub_rays, (math.radians(divergence_deg[0]),
                                            math.radians(divergence_deg[1])), config.profile)
