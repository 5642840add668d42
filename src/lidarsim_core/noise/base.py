"""Base class of noise-model plugins and the data they act on.

A noise model acts at one or both of two stages of the pipeline:

``perturb_rays``
    before ray casting, on the directions actually flown by the pulses (the seed paper's
    angular error: the pulse really goes elsewhere and hits another point of the surface);
``perturb_returns``
    after ray casting, on what the sensor reports (the seed paper's range error, Eq. 4).

All random numbers come from :func:`lidarsim_core.noise.rng.ray_normals` / ``ray_uniforms`` keyed by
the model's stream name and the ray index, so noise is reproducible and chunk-independent.
"""

from __future__ import annotations

from dataclasses import dataclass
from typing import TYPE_CHECKING

import numpy as np

from ..base.components import Component
from ..scenario.datasheet import SensorDatasheet
from .rng import INVERSE_CDF, MAX_ABS_NORMAL, max_abs_normal, ray_normals, ray_uniforms

if TYPE_CHECKING:
    from ..instrument.linkbudget import LinkBudget


@dataclass(frozen=True)
class NoiseContext:
    """What a noise model may depend on besides the rays: the sensor, the seed and the frame,
    the calibrated link budget (``None`` without ``sensor.detection``) and the normal
    generator of the run (the scenario's ``normals``: ``inverse_cdf``, the seed paper's
    stream, or ``ziggurat``; :func:`lidarsim_core.noise.rng.ray_normals`)."""

    sensor: SensorDatasheet
    seed: int
    frame: int
    stream: str
    link: "LinkBudget | None" = None
    normal_generator: str = INVERSE_CDF

    def normals(self, ray_index: np.ndarray, draws: int) -> np.ndarray:
        """(N, draws) standard normals for these rays from this model's own stream, by the
        run's normal generator."""
        return ray_normals(self.seed, self.frame, self.stream, ray_index, draws,
                           self.normal_generator)

    def max_abs_normal(self) -> float:
        """The largest ``|z|`` that :meth:`normals` can return (8.21 for ``inverse_cdf``,
        12.23 for ``ziggurat``)."""
        return max_abs_normal(self.normal_generator)

    def uniforms(self, ray_index: np.ndarray, draws: int) -> np.ndarray:
        """(N, draws) uniforms in (0, 1) for these rays from this model's own stream."""
        return ray_uniforms(self.seed, self.frame, self.stream, ray_index, draws)


@dataclass
class Returns:
    """Detected returns of one chunk, in the sensor frame at each ray's emission time.

    Noise models change ``range_measured`` and ``direction_measured`` in place (new arrays).

    Attributes
    ----------
    ray_index
        (N,) int64 global ray index.
    direction_flown
        (N, 3) unit direction the pulse actually travelled (after ray-stage noise).
    range_true
        (N,) float64 distance to the true surface point along ``direction_flown`` (m).
    range_measured
        (N,) float64 range the sensor reports (m).
    direction_measured
        (N, 3) unit direction along which the reported point is placed.
    signal
        (N,) received signal of each return from the link budget (threshold units of
        ``NoiseContext.link``; without it ``ρ_eff / R²``, the same up to the constant), or
        None when the caller has none. False alarms carry the threshold (1), or 0.
    noise_scale
        (N,) receiver noise over its own σ_n, √(1 + B), where background light B (the Sun,
        the Earth) raises it; None: no background.
    """

    ray_index: np.ndarray
    direction_flown: np.ndarray
    range_true: np.ndarray
    range_measured: np.ndarray
    direction_measured: np.ndarray
    signal: np.ndarray | None = None
    noise_scale: np.ndarray | None = None

    def __len__(self) -> int:
        return len(self.ray_index)


@dataclass(frozen=True)
class GaussianRayRotation:
    """What a ray stage does, told to the pipeline so it can skip pulses early.

    ``sigma_rad == 0``: the model leaves rays alone. Otherwise it turns each ray by two
    angles ``z1·σ`` and ``z2·σ``, where ``z1, z2`` are ``ctx.normals(ray_index, 2)``: the seed
    paper's angular error. With the default generator they are ``ndtri(u1)``, ``ndtri(u2)``
    of the first two uniforms of ``ctx.uniforms(ray_index, 2)``. Every such draw is within
    ``max_abs_normal`` σ (:data:`lidarsim_core.noise.rng.MAX_ABS_NORMAL` for the inverse CDF),
    so the pipeline knows how far a pulse can turn and skips those that cannot reach a
    target (:mod:`lidarsim_core.pipeline.cull`).
    """

    sigma_rad: float
    max_abs_normal: float = MAX_ABS_NORMAL
    #: The normal generator of the draws (``ctx.normal_generator``).
    normal_generator: str = INVERSE_CDF


class NoiseModel(Component):
    """A measurement-noise model. Override one or both stages; the defaults do nothing."""

    def perturb_rays(self, directions: np.ndarray, ray_index: np.ndarray,
                     ctx: NoiseContext) -> np.ndarray:
        """Return the directions the pulses actually fly ((N, 3) unit vectors)."""
        return directions

    def ray_rotation(self, ctx: NoiseContext) -> GaussianRayRotation | None:
        """Describe :meth:`perturb_rays` for culling (:class:`GaussianRayRotation`), or None
        when it does something else. The default says "leaves rays alone" if the subclass
        does not override :meth:`perturb_rays`, else None (no culling: always correct).
        """
        if type(self).perturb_rays is NoiseModel.perturb_rays:
            return GaussianRayRotation(0.0)
        return None

    def perturb_returns(self, returns: Returns, ctx: NoiseContext) -> Returns:
        """Return the returns with the measurement perturbed."""
        return returns


def perpendicular_basis(directions: np.ndarray) -> tuple[np.ndarray, np.ndarray]:
    """Two unit vectors ``u``, ``v`` perpendicular to each (N, 3) unit direction and to each
    other, chosen deterministically (``u`` horizontal where possible)."""
    x, y, z = directions[:, 0], directions[:, 1], directions[:, 2]
    near_vertical = np.abs(z) > 0.9
    # u = helper × d with helper +Z (+Y near the vertical), written out per component
    ux = np.where(near_vertical, z, -y)
    uy = np.where(near_vertical, 0.0, x)
    uz = np.where(near_vertical, -x, 0.0)
    norm = np.sqrt(ux * ux + uy * uy + uz * uz)
    ux /= norm
    uy /= norm
    uz /= norm
    u = np.stack([ux, uy, uz], axis=-1)
    v = np.stack([y * uz - z * uy, z * ux - x * uz, x * uy - y * ux], axis=-1)
    return u, v
