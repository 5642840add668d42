"""Built-in plugins: range errors beyond the paper's constant Gaussian (``range``).

``range_growing``
    Gaussian range error whose σ grows with range, ``σ(R) = max(σ_floor, σ_ref (R/R_ref)^p)``.
    A linear-mode receiver's timing jitter is inversely proportional to the signal, and the
    signal of an extended target falls as 1/R², hence p = 2 by default; vendors quote σ at
    one range (Livox: 1σ at 20 m), which is ``σ_ref`` at ``R_ref``.
``range_systematic``
    Systematic error: ``R' = R (1 + scale) + bias`` (calibration offset and scale factor).
``range_quantisation``
    The reported range is rounded to the time-to-digital converter's step,
    ``R' = offset + q · round((R − offset)/q)``: a uniform error on [−q/2, q/2], σ = q/√12.

Every model leaves the returns untouched when its parameters are zero.
"""

from __future__ import annotations

from typing import Any

import numpy as np
from pydantic import Field

from ..base.components import ComponentOptions
from ..hookspecs import hookimpl
from .base import NoiseContext, NoiseModel, Returns


class RangeGrowingOptions(ComponentOptions):
    """Options of the range-dependent range error."""

    sigma_m: float | None = Field(None, ge=0, description="1σ at reference_range_m (m); "
                                                          "default: the datasheet's "
                                                          "range_precision_m.")
    reference_range_m: float = Field(20.0, gt=0, description="Range at which σ = sigma_m (m) "
                                                             "(Livox quotes 20 m).")
    exponent: float = Field(2.0, ge=0, description="p in σ ∝ R^p (2: σ ∝ 1/signal ∝ R²; "
                                                   "0: constant).")
    floor_m: float = Field(0.0, ge=0, description="Smallest σ (m), e.g. the TDC jitter.")


class RangeGrowingError(NoiseModel):
    """Gaussian range error with σ(R) = max(σ_floor, σ_ref (R/R_ref)^p)."""

    name = "range_growing"
    Options = RangeGrowingOptions
    options: RangeGrowingOptions

    def sigma_at(self, range_m: np.ndarray, ctx: NoiseContext) -> np.ndarray:
        """σ (m) at the given ranges."""
        o = self.options
        sigma = o.sigma_m if o.sigma_m is not None else ctx.sensor.range_precision_m
        return np.maximum(o.floor_m, sigma * (np.asarray(range_m) / o.reference_range_m)
                          ** o.exponent)

    def perturb_returns(self, returns: Returns, ctx: NoiseContext) -> Returns:
        o = self.options
        sigma = o.sigma_m if o.sigma_m is not None else ctx.sensor.range_precision_m
        if (sigma == 0.0 and o.floor_m == 0.0) or len(returns) == 0:
            return returns
        # σ from the echo's own range (false alarms have no true range)
        error = ctx.normals(returns.ray_index, 1)[:, 0] * self.sigma_at(returns.range_measured,
                                                                        ctx)
        returns.range_measured = returns.range_measured + error
        return returns


class RangeBiasOptions(ComponentOptions):
    """Options of the range bias."""

    bias_m: float = Field(0.0, description="Constant offset added to every range (m).")
    scale: float = Field(0.0, gt=-1, description="Scale-factor error: R' = R (1 + scale) + "
                                                 "bias (e.g. 1e-4 = 100 ppm).")


class RangeBias(NoiseModel):
    """Systematic range error, R' = R (1 + scale) + bias."""

    name = "range_systematic"
    Options = RangeBiasOptions
    options: RangeBiasOptions

    def perturb_returns(self, returns: Returns, ctx: NoiseContext) -> Returns:
        o = self.options
        if o.bias_m == 0.0 and o.scale == 0.0:
            return returns
        returns.range_measured = returns.range_measured * (1.0 + o.scale) + o.bias_m
        return returns


class RangeQuantisationOptions(ComponentOptions):
    """Options of the range quantisation."""

    step_m: float = Field(0.0, ge=0, description="Range step q (m) (c/2 times the TDC "
                                                 "period); 0: off.")
    offset_m: float = Field(0.0, description="Range of the zero of the grid (m).")


class RangeQuantisation(NoiseModel):
    """The reported range rounded to a grid: R' = offset + q round((R - offset)/q)."""

    name = "range_quantisation"
    Options = RangeQuantisationOptions
    options: RangeQuantisationOptions

    def perturb_returns(self, returns: Returns, ctx: NoiseContext) -> Returns:
        q, offset = self.options.step_m, self.options.offset_m
        if q == 0.0:
            return returns
        returns.range_measured = offset + q * np.round((returns.range_measured - offset) / q)
        return returns


@hookimpl
def lidarsim_register_noise_models(register: Any) -> None:
    """Register the range-dependent, systematic and quantised range errors."""
    register(RangeGrowingError)
    register(RangeBias)
    register(RangeQuantisation)
