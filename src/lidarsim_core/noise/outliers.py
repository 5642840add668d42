"""Built-in plugins: gross errors and false alarms.

``outliers``
    Each reported return is, with probability p, an outlier: its range is replaced by a
    uniform draw on [min, max] (default: the sensor's range gate) or shifted by a Gaussian
    of σ ``sigma_m``. Space-LiDAR studies report 5-7 % outliers (Opromolla et al., Sensors
    2015).
``false_alarms``
    Background (sunlight, detector dark counts) crossing the threshold: each pulse, with
    probability ``p = rate_hz / point_rate_hz`` (or ``probability``), yields an echo at a range
    uniform over the listening window, along the pulse's direction, whether or not the pulse
    hits anything. It competes with the real returns in the return mode (a ``first`` sensor
    reports it when it comes before the real echo) and is written with part
    ``<scene>/false_alarm``, target -1 and NaN ground truth. Its signal is the threshold
    (intensity = the reflectivity detected at 50 % at that range) with the detection model
    on, and 0 otherwise.

Draws are keyed by ray index, so both models are reproducible and chunk-independent.
"""

from __future__ import annotations

from typing import Any, Literal

import numpy as np
from pydantic import Field, model_validator

from ..base.components import ComponentOptions
from ..hookspecs import hookimpl
from .base import NoiseContext, NoiseModel, Returns


class OutliersOptions(ComponentOptions):
    """Options of the outlier model."""

    probability: float = Field(0.0, ge=0, le=1, description="Probability that a return is an "
                                                            "outlier.")
    distribution: Literal["uniform", "gaussian"] = Field(
        "uniform", description="'uniform': range drawn on [min_m, max_m]; 'gaussian': true "
                               "range plus N(0, sigma_m²).")
    min_m: float | None = Field(None, ge=0, description="Lower end of uniform outliers (m); "
                                                        "default: the datasheet's range_min_m.")
    max_m: float | None = Field(None, gt=0, description="Upper end of uniform outliers (m); "
                                                        "default: the datasheet's range_max_m.")
    sigma_m: float = Field(1.0, gt=0, description="σ of Gaussian outliers (m).")


class Outliers(NoiseModel):
    """Gross range errors: with probability p a return's range is redrawn."""

    name = "outliers"
    Options = OutliersOptions
    options: OutliersOptions

    def perturb_returns(self, returns: Returns, ctx: NoiseContext) -> Returns:
        o = self.options
        if o.probability == 0.0 or len(returns) == 0:
            return returns
        u = ctx.uniforms(returns.ray_index, 2)
        hit = u[:, 0] < o.probability
        if not hit.any():
            return returns
        measured = returns.range_measured.copy()
        if o.distribution == "uniform":
            lo = o.min_m if o.min_m is not None else ctx.sensor.range_min_m
            hi = o.max_m if o.max_m is not None else ctx.sensor.range_max_m
            measured[hit] = lo + u[hit, 1] * (hi - lo)
        else:
            from scipy.special import ndtri

            measured[hit] += ndtri(u[hit, 1]) * o.sigma_m
        returns.range_measured = measured
        return returns


class SpuriousReturnModel(NoiseModel):
    """A noise model that adds echoes to pulses (the pipeline asks every such model)."""

    def spurious_ranges(self, ray_index: np.ndarray, ctx: NoiseContext, range_min_m: float,
                        range_max_m: float) -> np.ndarray:
        """(N,) range of a spurious echo for each pulse, NaN where there is none."""
        return np.full(len(ray_index), np.nan)


class FalseAlarmsOptions(ComponentOptions):
    """Options of the false-alarm model (give one of rate_hz and probability)."""

    rate_hz: float | None = Field(None, ge=0, description="False alarms per second over the "
                                                          "whole field of view.")
    probability: float | None = Field(None, ge=0, le=1, description="False-alarm probability "
                                                                    "per pulse.")

    @model_validator(mode="after")
    def _one_rate(self) -> "FalseAlarmsOptions":
        if (self.rate_hz is None) == (self.probability is None):
            raise ValueError("give exactly one of 'rate_hz' and 'probability'")
        return self


class FalseAlarms(SpuriousReturnModel):
    """Background false alarms: echoes at random ranges, at a given rate, in the FOV."""

    name = "false_alarms"
    Options = FalseAlarmsOptions
    options: FalseAlarmsOptions

    def probability(self, ctx: NoiseContext) -> float:
        """False-alarm probability per pulse."""
        if self.options.probability is not None:
            return self.options.probability
        return min(1.0, self.options.rate_hz / ctx.sensor.point_rate_hz)

    def spurious_ranges(self, ray_index: np.ndarray, ctx: NoiseContext, range_min_m: float,
                        range_max_m: float) -> np.ndarray:
        p = self.probability(ctx)
        out = np.full(len(ray_index), np.nan)
        if p == 0.0 or len(ray_index) == 0:
            return out
        u = ctx.uniforms(ray_index, 2)
        alarm = u[:, 0] < p
        out[alarm] = range_min_m + u[alarm, 1] * (range_max_m - range_min_m)
        return out


@hookimpl
def lidarsim_register_noise_models(register: Any) -> None:
    """Register the outlier and false-alarm models."""
    register(Outliers)
    register(FalseAlarms)
