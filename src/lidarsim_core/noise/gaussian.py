"""Built-in plugins: the seed paper's Gaussian angular error and range error.

``angular``
    Two successive rotations of the flown ray, by independent N(0, σ²) angles, about two axes
    perpendicular to the ray and to each other (paper §2.2). σ defaults to the datasheet's
    ``angular_precision_deg``, read as the 1σ error about each axis.
``range``
    The reported range is the true one plus N(0, σ²); the point moves along the ray,
    P_r = P_t + e·v_dir (paper Eq. 4). σ defaults to the datasheet's ``range_precision_m``.
"""

from __future__ import annotations

import math
from typing import Any

import numpy as np
from pydantic import Field

from .. import kernels
from ..base.components import ComponentOptions
from ..hookspecs import hookimpl
from .base import (
    GaussianRayRotation,
    NoiseContext,
    NoiseModel,
    Returns,
    perpendicular_basis,
)


class AngularOptions(ComponentOptions):
    """Options of the angular error."""

    sigma_deg: float | None = Field(None, ge=0, description="1σ about each perpendicular axis "
                                                            "(deg); default: the datasheet's.")


class AngularError(NoiseModel):
    """Gaussian pointing error: two rotations about axes perpendicular to the ray (paper §2.2)."""

    name = "angular"
    Options = AngularOptions
    options: AngularOptions

    def sigma_rad(self, ctx: NoiseContext) -> float:
        """The 1σ angle in radians for this sensor."""
        sigma = self.options.sigma_deg
        return math.radians(sigma) if sigma is not None else ctx.sensor.angular_precision_rad

    def perturb_rays(self, directions: np.ndarray, ray_index: np.ndarray,
                     ctx: NoiseContext) -> np.ndarray:
        sigma = self.sigma_rad(ctx)
        if sigma == 0.0 or len(directions) == 0:
            return directions
        angles = ctx.normals(ray_index, 2) * sigma
        if kernels.enabled():  # the same arithmetic compiled, without the temporaries
            from ..kernels.rotation import rotate_two_angles

            return rotate_two_angles(np.ascontiguousarray(directions, dtype=np.float64), angles)
        u, v = perpendicular_basis(directions)
        # rotation by a1 about u, then by a2 about v, in closed form (Rodrigues; d, u, v is a
        # right-handed orthonormal basis): 7x faster than composing SciPy rotations per ray
        c1, s1 = np.cos(angles[:, 0]), np.sin(angles[:, 0])
        c2, s2 = np.cos(angles[:, 1]), np.sin(angles[:, 1])
        return (c1 * c2)[:, None] * directions + (c1 * s2)[:, None] * u - s1[:, None] * v

    def ray_rotation(self, ctx: NoiseContext) -> GaussianRayRotation | None:
        if type(self).perturb_rays is not AngularError.perturb_rays:  # a subclass changed it
            return None
        return GaussianRayRotation(self.sigma_rad(ctx), ctx.max_abs_normal(),
                                   ctx.normal_generator)


class RangeOptions(ComponentOptions):
    """Options of the range error."""

    sigma_m: float | None = Field(None, ge=0, description="1σ range error (m); default: the "
                                                          "datasheet's range_precision_m.")


class RangeError(NoiseModel):
    """Gaussian range error along the ray, P_r = P_t + e·v_dir (paper Eq. 4)."""

    name = "range"
    Options = RangeOptions
    options: RangeOptions

    def sigma_m(self, ctx: NoiseContext) -> float:
        """The 1σ range error in metres for this sensor."""
        sigma = self.options.sigma_m
        return sigma if sigma is not None else ctx.sensor.range_precision_m

    def perturb_returns(self, returns: Returns, ctx: NoiseContext) -> Returns:
        sigma = self.sigma_m(ctx)
        if sigma == 0.0 or len(returns) == 0:
            return returns
        returns.range_measured = returns.range_measured + ctx.normals(returns.ray_index, 1)[:, 0] * sigma
        return returns


@hookimpl
def lidarsim_register_noise_models(register: Any) -> None:
    """Register the paper's angular and range errors."""
    register(AngularError)
    register(RangeError)
