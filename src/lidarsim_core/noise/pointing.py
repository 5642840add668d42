"""Built-in plugin: angular error applied to the measured point instead of the flown ray.

``angular`` (the seed paper's way) turns the pulse before it is cast: the beam really goes
elsewhere and hits another point of the surface, so the point stays on the surface.
``angular_point`` casts the nominal ray and turns the *reported* direction instead: the
encoder of a scanner misreads where the beam went, so the point leaves the surface by
``R · δ``. The rotation is the same (two Gaussian angles about two axes perpendicular to the
ray, σ the datasheet's ``angular_precision_deg``) and is drawn once per pulse: every return
of a pulse is misplaced the same way.
"""

from __future__ import annotations

from typing import Any

import numpy as np

from ..hookspecs import hookimpl
from .base import GaussianRayRotation, NoiseContext, Returns
from .gaussian import AngularError, AngularOptions
from .streams import per_pulse


class AngularPointError(AngularError):
    """Gaussian pointing error of the reported direction (the measured point moves)."""

    name = "angular_point"
    Options = AngularOptions
    options: AngularOptions

    def perturb_rays(self, directions: np.ndarray, ray_index: np.ndarray,
                     ctx: NoiseContext) -> np.ndarray:
        return directions

    def ray_rotation(self, ctx: NoiseContext) -> GaussianRayRotation | None:
        return GaussianRayRotation(0.0)  # the flown ray is the nominal one

    def perturb_returns(self, returns: Returns, ctx: NoiseContext) -> Returns:
        returns.direction_measured = AngularError.perturb_rays(
            self, returns.direction_measured, returns.ray_index, per_pulse(ctx))
        return returns


@hookimpl
def lidarsim_register_noise_models(register: Any) -> None:
    """Register the point-domain angular error."""
    register(AngularPointError)
