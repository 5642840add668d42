"""Settings of the Sun stage: the orbit and epoch that place the Sun, and the receiver's
optical filter.
"""

from __future__ import annotations

import math
from datetime import datetime, timezone

from pydantic import BaseModel, ConfigDict, Field, field_validator, model_validator

#: Noise-equivalent irradiance (W/m²) when the scenario gives none: an estimate that puts a
#: white surface in full sunlight (E_λ Δλ ≈ 9 W/m² at 905 nm through 10 nm) near B = 1,
#: the background-limited regime of linear-mode receivers in daylight.
DEFAULT_NOISE_EQUIVALENT_IRRADIANCE_W_M2 = 10.0

#: Receiver optical filter width (nm) when the scenario gives none: an estimate for the
#: narrow-band interference filters of near-infrared LiDARs (10-30 nm).
DEFAULT_FILTER_WIDTH_NM = 10.0


class SunOrbit(BaseModel):
    """The target's circular orbit and the epoch of the scenario's t = 0, from which the Sun's
    direction in the LVLH scene frame follows."""

    model_config = ConfigDict(extra="forbid", allow_inf_nan=False)

    epoch: datetime = Field(description="UTC date and time of the scenario's t = 0 "
                                        "(ISO 8601, e.g. 2024-03-20T12:00:00Z).")
    altitude_km: float = Field(gt=0, description="Altitude above the Earth's equatorial "
                                                 "radius (km).")
    inclination_deg: float = Field(ge=0, le=180, description="Orbit inclination (deg).")
    raan_deg: float = Field(0.0, description="Right ascension of the ascending node (deg).")
    argument_of_latitude_deg: float = Field(
        0.0, description="Angle from the ascending node to the target at the epoch (deg).")

    @field_validator("epoch")
    @classmethod
    def _utc(cls, value: datetime) -> datetime:
        return value.replace(tzinfo=timezone.utc) if value.tzinfo is None else value


class SunConfig(BaseModel):
    """The Sun (off unless this block is given; needs ``sensor.detection``)."""

    model_config = ConfigDict(extra="forbid", allow_inf_nan=False)

    direction: tuple[float, float, float] | None = Field(
        None, description="Direction toward the Sun in the scene frame (normalised here); or "
                          "give orbit.")
    orbit: SunOrbit | None = Field(
        None, description="The target's orbit and epoch: the Sun's direction in the LVLH "
                          "scene frame at each pulse's time, and the Earth's shadow.")
    spectral_irradiance_w_m2_nm: float | None = Field(
        None, gt=0, description="Solar spectral irradiance at the sensor's wavelength "
                                "(W m⁻² nm⁻¹); default: a 5772 K blackbody scaled to the solar "
                                "constant at the datasheet's wavelength_nm.")
    filter_width_nm: float | None = Field(
        None, gt=0, description="Receiver optical filter width Δλ (nm); default: the "
                                "datasheet's optical_filter_nm, else 10 nm (an estimate).")
    noise_equivalent_irradiance_w_m2: float = Field(
        DEFAULT_NOISE_EQUIVALENT_IRRADIANCE_W_M2, gt=0,
        description="In-band irradiance on a white surface whose background noise equals the "
                    "receiver's own (W/m²); default 10 (an estimate).")
    blinding_angle_deg: float | None = Field(
        None, ge=0, lt=90, description="Pulses this close to the Sun report nothing (deg); "
                                       "default: the Sun's angular radius plus the receiver's "
                                       "acceptance half-angle.")

    @field_validator("direction")
    @classmethod
    def _nonzero(cls, value: tuple[float, float, float] | None
                 ) -> tuple[float, float, float] | None:
        if value is not None and math.hypot(*value) == 0.0:
            raise ValueError("the Sun's direction must not be the zero vector")
        return value

    @model_validator(mode="after")
    def _one_source(self) -> "SunConfig":
        if (self.direction is None) == (self.orbit is None):
            raise ValueError("give exactly one of direction or orbit")
        return self
