"""Settings of the sensor in a scenario: pose, datasheet, and the optional measurement models
(beam divergence, detection, return mode, multipath, receiver).
"""

from __future__ import annotations

from typing import Literal

from pydantic import BaseModel, ConfigDict, Field, field_validator

from .datasheet import MAX_DIVERGENCE_DEG, RangeAtReflectivity

#: How a pulse's returns are reported (docs/realism.md#returns).
ReturnMode = Literal["first", "last", "strongest", "dual", "multi"]
#: Which two returns a ``dual`` sensor reports.
DualPair = Literal["strongest_last", "first_strongest", "first_last"]


class BeamConfig(BaseModel):
    """Beam divergence sampled with sub-rays (off, one ray per pulse, unless given)."""

    model_config = ConfigDict(extra="forbid", allow_inf_nan=False)

    sub_rays: int = Field(16, ge=1, le=256, description="Sub-rays per pulse (K).")
    divergence_deg: tuple[float, float] | None = Field(
        None, description="Full divergence (horizontal, vertical) in degrees; default: the "
                          "datasheet's beam_divergence_deg.")
    profile: Literal["gaussian", "uniform"] = Field(
        "gaussian", description="'gaussian': divergence is the full angle at 1/e² intensity; "
                                "'uniform': a top-hat ellipse of that full angle.")

    @field_validator("divergence_deg")
    @classmethod
    def _non_negative(cls, value: tuple[float, float] | None) -> tuple[float, float] | None:
        if value is not None and (value[0] < 0 or value[1] < 0):
            raise ValueError("divergence must be >= 0")
        if value is not None and (value[0] > MAX_DIVERGENCE_DEG or
                                  value[1] > MAX_DIVERGENCE_DEG):
            raise ValueError(f"divergence {list(value)} is wider than {MAX_DIVERGENCE_DEG:g}°: "
                             "not a laser beam (a flash sensor's illumination is its "
                             "pattern, not its divergence)")
        return value


class DetectionConfig(BaseModel):
    """The link-budget detection model (off unless this block is given)."""

    model_config = ConfigDict(extra="forbid", allow_inf_nan=False)

    threshold_to_noise: float = Field(
        4.0, gt=0, description="Detection threshold over the receiver's noise σ (TNR); sets "
                               "how steeply P_d falls around the datasheet ranges. Default: "
                               "an estimate (P_fa ≈ 3e-5 per range cell).")
    range_exponent: float | None = Field(
        None, gt=0, description="n in S ∝ ρ/R^n; default: fitted to the range-at-reflectivity "
                                "figures (2 with a single figure).")
    range_at_reflectivity: list[RangeAtReflectivity] | None = Field(
        None, description="Calibration figures (50 % detection ranges); default: the "
                          "datasheet's.")
    range_max_m: float | None = Field(
        None, gt=0, description="Hard limit on reported ranges (m); default: the larger of "
                                "the datasheet's range_max_m and its longest "
                                "range-at-reflectivity figure (the link budget decides below).")
    keep_undetected: bool = Field(
        False, description="Keep the returns the sensor misses, flagged detected = 0, for "
                           "analysis (they carry no noise).")


class ReturnsConfig(BaseModel):
    """How returns are formed and which ones the sensor reports (default: the datasheet's)."""

    model_config = ConfigDict(extra="forbid", allow_inf_nan=False)

    mode: ReturnMode | None = Field(None, description="Return mode; default: the datasheet's "
                                                      "return_mode.")
    dual: DualPair | None = Field(None, description="Which two returns 'dual' reports; "
                                                    "default: the datasheet's dual_return.")
    max_returns: int | None = Field(None, ge=1, le=15, description="Returns per pulse in "
                                                                   "'multi' mode; default: "
                                                                   "the datasheet's.")
    range_resolution_m: float | None = Field(
        None, gt=0, description="Two surfaces farther apart than this give separate returns "
                                "(m); default: the datasheet's range_resolution_m.")


#: Receiver acceptance half-angle (deg) when neither the scenario nor the datasheet's beam
#: divergence gives one: 0.05° (a 1.7 mrad full field of view, typical of scanning LiDARs).
DEFAULT_ACCEPTANCE_DEG = 0.05


class MultipathConfig(BaseModel):
    """Specular bounces (off unless this block is given; needs ``sensor.detection``)."""

    model_config = ConfigDict(extra="forbid", allow_inf_nan=False)

    max_bounces: int = Field(1, ge=1, le=8, description="Specular bounces followed per pulse "
                                                        "(1: mirror → surface → back).")
    acceptance_deg: float | None = Field(
        None, gt=0, lt=10, description="Receiver acceptance half-angle γ (deg) of the mirror "
                                       "coupling; default: half the datasheet's mean beam "
                                       "divergence (0.05° without one).")
    min_coupling: float = Field(
        1e-6, ge=0, lt=1, description="A bounce is followed only while the mirrors' two-way "
                                      "coupling Π κ² exceeds this (weaker ghosts are "
                                      "undetectable; saves casting them).")


class ReceiverConfig(BaseModel):
    """The receiver's dynamic range (off unless this block is given; needs detection)."""

    model_config = ConfigDict(extra="forbid", allow_inf_nan=False)

    saturation_signal: float | None = Field(
        None, gt=1, description="Signal (in units of the detection threshold) at which the "
                                "receiver saturates: signal and intensity clip there; "
                                "default: the datasheet's saturation_signal.")
    range_walk: bool = Field(False, description="Bias saturated returns early by the "
                                                "uncorrected leading-edge walk ΔR(S).")
    pulse_sigma_m: float | None = Field(
        None, gt=0, description="RMS length σ_R of the pulse in range units (m); default: "
                                "range_resolution_m / 2.3548.")
