"""Settings of the Earth as a background source behind the target (docs/realism.md, "The
Earth"; computed by :mod:`lidarsim_core.pipeline.stages.earth`)."""

from __future__ import annotations

from pydantic import BaseModel, ConfigDict, Field

#: Earth's Bond albedo (NASA Earth Fact Sheet, 0.306; CERES measures about 0.29-0.30).
EARTH_BOND_ALBEDO = 0.306


class EarthConfig(BaseModel):
    """The Earth as a background source (needs ``sun`` with ``orbit``)."""

    model_config = ConfigDict(extra="forbid", allow_inf_nan=False)

    albedo: float = Field(
        EARTH_BOND_ALBEDO, ge=0, le=1,
        description="Lambertian reflectance of the Earth's dayside at the sensor's wavelength; "
                    "default the Bond albedo 0.306 (NASA Earth Fact Sheet). Near infrared: "
                    "clouds ~0.6-0.8, vegetation ~0.4-0.5, ocean ~0.05.")
