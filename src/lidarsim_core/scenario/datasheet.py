"""The sensor datasheet: pydantic models of what a LiDAR vendor's datasheet says.

Fields carry their unit in their name and are converted to SI radians/metres/seconds once, by
the properties at the bottom of :class:`SensorDatasheet`. Every datasheet states its sources;
values that are estimates are listed in ``estimated_fields``.
"""

from __future__ import annotations

import math
from pathlib import Path
from typing import Any, Literal

from pydantic import (BaseModel, ConfigDict, Field, field_validator, model_serializer,
                      model_validator)

from ..base.config_io import read_config_file
from ..base.validation import validate_model

#: Widest beam divergence (full angle, degrees) a datasheet or beam block may give.
MAX_DIVERGENCE_DEG = 90.0


class _Strict(BaseModel):
    model_config = ConfigDict(extra="forbid", frozen=True, allow_inf_nan=False)


class Source(_Strict):
    """Where a datasheet's values come from."""

    title: str = Field(min_length=1, description="Document title, e.g. 'Livox Mid-70 User Manual v1.2'.")
    url: str | None = Field(None, description="Where the document can be found.")
    note: str | None = Field(None, description="What was taken from it, or how it was interpreted.")


class ScanPatternSpec(_Strict):
    """Which registered scan pattern the sensor uses, with that pattern's options."""

    name: str = Field(description="Name of a registered scan pattern, e.g. 'rose'.")
    options: dict[str, Any] = Field(default_factory=dict,
                                    description="Options validated by the pattern's Options model.")


class RangeAtReflectivity(_Strict):
    """A datasheet detection-range figure: range reached on a target of given reflectivity."""

    reflectivity: float = Field(gt=0, le=1, description="Lambertian reflectivity, 0-1.")
    range_m: float = Field(gt=0, description="Detection range at that reflectivity (m).")


class RangePrecisionCondition(_Strict):
    """The condition at which the datasheet states its range precision: a Lambertian target of
    ``reflectivity`` at normal incidence, ``range_m`` away. The signal-driven range error
    (noise model ``range_signal``) scales the precision from there."""

    range_m: float = Field(20.0, gt=0, description="Range of the stated precision (m); Livox: "
                                                   "20 m.")
    reflectivity: float = Field(0.8, gt=0, le=1, description="Lambertian reflectivity of the "
                                                             "target, 0-1; Livox: 0.8 (80 %).")


class SensorDatasheet(_Strict):
    """A LiDAR sensor as described by its datasheet (the seed paper's fields, plus identity).

    Angles are in degrees, ranges in metres, rates in hertz, as the field names say.
    """

    name: str = Field(pattern=r"^[a-z0-9][a-z0-9_.-]*$",
                      description="Catalogue name used in scenarios, e.g. 'livox-mid70'.")
    manufacturer: str = Field(min_length=1)
    model: str = Field(min_length=1)
    description: str = ""
    sources: list[Source] = Field(min_length=1, description="Where the values come from.")
    estimated_fields: list[str] = Field(
        default_factory=list, description="Fields whose values are estimates, not datasheet figures.")

    fov_type: Literal["circular", "rectangular", "panoramic"] = Field(
        description="'circular' (solid-state, cone; fov_h_deg = fov_v_deg = full cone angle), "
                    "'rectangular' (solid-state or flash, H x V) or 'panoramic' (mechanical "
                    "spinning, fov_h_deg usually 360).")
    fov_h_deg: float = Field(gt=0, le=360, description="Full horizontal field of view (deg).")
    fov_v_deg: float = Field(gt=0, le=180, description="Full vertical field of view (deg).")
    fov_v_center_deg: float = Field(0.0, ge=-90, le=90,
                                    description="Elevation of the vertical FOV's centre (deg).")
    range_max_m: float = Field(gt=0, description="Maximum detection range (m).")
    range_min_m: float = Field(0.0, ge=0, description="Minimum range / blind zone (m).")
    range_precision_m: float = Field(ge=0, description="Range precision, 1 sigma (m).")
    range_precision_condition: RangePrecisionCondition | None = Field(
        None, description="Range and reflectivity at which range_precision_m is stated; "
                          "default: Livox's, 20 m on an 80 % target.")
    angular_precision_deg: float = Field(ge=0, description="Angular precision, 1 sigma (deg).")
    point_rate_hz: float = Field(gt=0, description="Points emitted per second (all channels).")
    wavelength_nm: float | None = Field(None, gt=0)
    beam_divergence_deg: tuple[float, float] | None = Field(
        None, description="Full beam divergence (horizontal, vertical) in degrees.")
    range_at_reflectivity: list[RangeAtReflectivity] = Field(
        default_factory=list, description="Detection ranges at given target reflectivities "
                                          "(read as 50 % detection probability at normal "
                                          "incidence); calibrate the detection model.")
    range_resolution_m: float | None = Field(
        None, gt=0, description="Smallest separation of two surfaces that gives two returns "
                                "(m), about c·τ/2 for a pulse of width τ.")
    saturation_signal: float | None = Field(
        None, gt=1, description="Signal, in units of the detection threshold, at which the "
                                "receiver saturates (default of sensor.receiver).")
    optical_filter_nm: float | None = Field(
        None, gt=0, description="Width of the receiver's optical band-pass filter (nm; "
                                "default of sun.filter_width_nm).")
    return_mode: Literal["first", "last", "strongest", "dual", "multi"] = Field(
        "strongest", description="Default return mode (see docs/realism.md).")
    dual_return: Literal["strongest_last", "first_strongest", "first_last"] = Field(
        "strongest_last", description="Which two returns the 'dual' mode reports.")
    max_returns: int = Field(1, ge=1, le=15, description="Most returns the sensor reports "
                                                         "per pulse ('multi' mode).")
    scan_pattern: ScanPatternSpec

    @model_serializer(mode="wrap")
    def _drop_unset_later_fields(self, handler: Any) -> dict[str, Any]:
        # fields added after datasheets were first written out stay out of dumps when unset,
        # so dataset identities of older runs keep their bytes
        data = handler(self)
        if data.get("range_precision_condition", 0) is None:
            del data["range_precision_condition"]
        return data

    @field_validator("beam_divergence_deg")
    @classmethod
    def _positive_divergence(cls, value: tuple[float, float] | None) -> tuple[float, float] | None:
        if value is not None and (value[0] < 0 or value[1] < 0):
            raise ValueError("beam divergence must be >= 0")
        if value is not None and (value[0] > MAX_DIVERGENCE_DEG or
                                  value[1] > MAX_DIVERGENCE_DEG):
            raise ValueError(f"divergence {list(value)} is wider than {MAX_DIVERGENCE_DEG:g}°: "
                             "not a laser beam (a flash sensor's illumination is its "
                             "pattern, not its divergence)")
        return value

    @model_validator(mode="after")
    def _consistent(self) -> "SensorDatasheet":
        if self.range_min_m >= self.range_max_m:
            raise ValueError(f"range_min_m ({self.range_min_m}) must be below range_max_m "
                             f"({self.range_max_m})")
        if self.fov_type != "panoramic" and self.fov_h_deg >= 180:
            raise ValueError(f"fov_h_deg {self.fov_h_deg} must be below 180 for a "
                             f"{self.fov_type} field of view (use fov_type: panoramic)")
        if self.fov_type == "circular" and not math.isclose(self.fov_h_deg, self.fov_v_deg):
            raise ValueError("a circular FOV needs fov_h_deg == fov_v_deg (the full cone angle)")
        unknown = set(self.estimated_fields) - set(type(self).model_fields)
        if unknown:
            raise ValueError(f"estimated_fields names unknown fields: {sorted(unknown)}")
        return self

    # ---- SI views, converted once here -------------------------------------------------
    @property
    def angular_precision_rad(self) -> float:
        """Angular precision 1 sigma in radians."""
        return math.radians(self.angular_precision_deg)

    @property
    def half_fov_h_rad(self) -> float:
        """Half the horizontal FOV in radians."""
        return math.radians(self.fov_h_deg) / 2

    @property
    def half_fov_v_rad(self) -> float:
        """Half the vertical FOV in radians."""
        return math.radians(self.fov_v_deg) / 2


def load_datasheet(path: str | Path) -> SensorDatasheet:
    """Read and validate a datasheet file (YAML/TOML/JSON).

    Raises
    ------
    ConfigError
        Naming the file and the field when the file is malformed or a value is invalid.
    """
    return validate_model(SensorDatasheet, read_config_file(path), source=path)


def datasheet_json_schema() -> dict[str, Any]:
    """The JSON schema of :class:`SensorDatasheet` (``lidarsim schema sensor``)."""
    return SensorDatasheet.model_json_schema()
