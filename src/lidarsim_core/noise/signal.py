"""Built-in plugin ``range_signal``: a range error that follows the return's signal.

A linear-mode receiver times an echo where its rising edge crosses the threshold; noise σ_n
on an edge of slope dV/dt moves that instant by σ_t = σ_n / (dV/dt) (the leading-edge timing
relation), and the slope of an echo of given shape is proportional to its amplitude S, so the
timing jitter, hence the range error, is the rise time over the signal-to-noise ratio:
σ_R ∝ (c/2) t_rise σ_n / S. The datasheet states the precision σ_ref at one condition: a Lambertian target of
reflectivity ρ_ref, face-on, at range R_ref (Livox: 2 cm 1σ at 20 m on an 80 % target). Its
signal there, from the same link budget as detection, is ``S_ref = C ρ_ref / R_ref^n``, and a
return of signal S (range, reflectivity, incidence and the beam footprint's share on the
surface, all in S) has

.. math::  σ_R(S) = \\sqrt{σ_f^2 + (σ_\\mathrm{ref}^2 − σ_f^2)\\,(k\\, S_\\mathrm{ref} / S)^2}

where σ_f is the floor of the timing electronics (jitter that does not depend on the echo,
added in quadrature so that σ_R(S_ref) = σ_ref exactly) and k = √(1 + B) the receiver
noise raised by background light (the Sun, the Earth; 1 without). Far from the floor this is
``σ_ref · S_ref / S``: larger on dark, far and grazing surfaces, smaller on bright, near,
face-on ones. Without ``sensor.detection`` the link budget is ``S = ρ_eff / R²`` (n = 2), with
it the calibrated one. False alarms carry the threshold signal (S = 1) with a link budget and
no signal without one: they are left as drawn.
"""

from __future__ import annotations

from typing import Any

import numpy as np
from pydantic import Field

from ..base.components import ComponentOptions
from ..hookspecs import hookimpl
from .base import NoiseContext, NoiseModel, Returns

#: Standard deviation of a TDC7200 time-to-digital converter, 35 ps (Texas Instruments
#: datasheet SNAS647D), as a range: c/2 · 35 ps. The default floor (an estimate: the
#: sensor's own electronics are not published).
TDC_FLOOR_M = 299792458.0 / 2.0 * 35e-12
#: The reference condition when the datasheet states none: Livox's (1σ at 20 m; the HAP
#: manual states it on an 80 % target).
LIVOX_REFERENCE_RANGE_M = 20.0
LIVOX_REFERENCE_REFLECTIVITY = 0.8


class RangeSignalOptions(ComponentOptions):
    """Options of the signal-driven range error."""

    sigma_m: float | None = Field(None, ge=0, description="1σ at the reference condition (m); "
                                                          "default: the datasheet's "
                                                          "range_precision_m.")
    reference_range_m: float | None = Field(
        None, gt=0, description="Range of the reference condition (m); default: the "
                                "datasheet's range_precision_condition, else 20 m (Livox).")
    reference_reflectivity: float | None = Field(
        None, gt=0, le=1, description="Lambertian reflectivity of the reference condition; "
                                      "default: the datasheet's range_precision_condition, "
                                      "else 0.8 (Livox).")
    floor_m: float = Field(TDC_FLOOR_M, ge=0, description="1σ of the timing electronics (m), "
                                                          "added in quadrature; default "
                                                          "c/2 · 35 ps (a TDC7200).")


class RangeSignalError(NoiseModel):
    """Gaussian range error that follows the return's signal S: σ_R = √(σ_f² + (σ_ref² − σ_f²)
    (k S_ref/S)²), k = √(1 + B) with background light."""

    name = "range_signal"
    Options = RangeSignalOptions
    options: RangeSignalOptions

    def reference(self, ctx: NoiseContext) -> tuple[float, float, float]:
        """``(σ_ref, R_ref, ρ_ref)`` for this sensor."""
        o, sheet = self.options, ctx.sensor
        condition = sheet.range_precision_condition
        sigma = o.sigma_m if o.sigma_m is not None else sheet.range_precision_m
        rng = o.reference_range_m or (condition.range_m if condition is not None
                                      else LIVOX_REFERENCE_RANGE_M)
        rho = o.reference_reflectivity or (condition.reflectivity if condition is not None
                                           else LIVOX_REFERENCE_REFLECTIVITY)
        return sigma, rng, rho

    def reference_signal(self, ctx: NoiseContext) -> float:
        """S_ref in the units of the returns' signal (see the module docstring)."""
        _, rng, rho = self.reference(ctx)
        constant, exponent = ((ctx.link.constant, ctx.link.exponent) if ctx.link is not None
                              else (1.0, 2.0))
        return constant * rho / rng ** exponent

    def sigma_at(self, signal: np.ndarray, ctx: NoiseContext,
                 noise_scale: np.ndarray | None = None) -> np.ndarray:
        """σ_R (m) of returns of these signals (0 where the signal is not positive)."""
        sigma_ref, _, _ = self.reference(ctx)
        floor = self.options.floor_m
        signal = np.asarray(signal, dtype=np.float64)
        ratio = np.zeros_like(signal)
        valid = signal > 0
        ratio[valid] = self.reference_signal(ctx) / signal[valid]
        if noise_scale is not None:
            ratio *= noise_scale
        # a floor above σ_ref leaves only the floor
        sigma = np.sqrt(floor * floor + max(sigma_ref * sigma_ref - floor * floor, 0.0)
                        * ratio * ratio)
        return np.where(valid, sigma, 0.0)

    def perturb_returns(self, returns: Returns, ctx: NoiseContext) -> Returns:
        sigma_ref, rng, _ = self.reference(ctx)
        if (sigma_ref == 0.0 and self.options.floor_m == 0.0) or len(returns) == 0:
            return returns
        signal = returns.signal
        if signal is None:  # a caller without the link budget: the reference target's signal
            signal = self.reference_signal(ctx) * (rng / returns.range_true) ** (
                ctx.link.exponent if ctx.link is not None else 2.0)
        sigma = self.sigma_at(signal, ctx, returns.noise_scale)
        error = ctx.normals(returns.ray_index, 1)[:, 0] * sigma
        returns.range_measured = returns.range_measured + error
        return returns


@hookimpl
def lidarsim_register_noise_models(register: Any) -> None:
    """Register the signal-driven range error."""
    register(RangeSignalError)
