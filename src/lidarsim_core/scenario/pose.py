"""Pose settings: a position and an orientation as scenario files give them.
"""

from __future__ import annotations

from typing import Any

import numpy as np
from pydantic import BaseModel, ConfigDict, Field, field_validator, model_validator
from scipy.spatial.transform import Rotation

from ..geometry.poses import Poses

_VALID_SEQ = set("xyz")


class PoseConfig(BaseModel):
    """A pose in a scenario: a position and at most one rotation description."""

    model_config = ConfigDict(extra="forbid", frozen=True)

    position_m: tuple[float, float, float] = Field(
        (0.0, 0.0, 0.0), description="Body origin in the scene frame (m).")
    euler_deg: tuple[float, float, float] | None = Field(
        None, description="Three rotation angles (deg) applied in `euler_sequence` order.")
    euler_sequence: str = Field(
        "xyz", description="SciPy Euler sequence: lower case = extrinsic (fixed axes, the seed "
                           "paper's X, Y, Z), upper case = intrinsic.")
    quaternion_xyzw: tuple[float, float, float, float] | None = Field(
        None, description="Rotation as a scalar-last unit quaternion [x, y, z, w].")

    @field_validator("position_m", "euler_deg", "quaternion_xyzw")
    @classmethod
    def _finite(cls, value: Any) -> Any:
        if value is not None and not np.all(np.isfinite(value)):
            raise ValueError("values must be finite numbers")
        return value

    @field_validator("euler_sequence")
    @classmethod
    def _sequence(cls, value: str) -> str:
        return check_euler_sequence(value)

    @model_validator(mode="after")
    def _one_rotation(self) -> "PoseConfig":
        if self.euler_deg is not None and self.quaternion_xyzw is not None:
            raise ValueError("give either euler_deg or quaternion_xyzw, not both")
        if self.quaternion_xyzw is not None and np.linalg.norm(self.quaternion_xyzw) < 1e-12:
            raise ValueError("quaternion_xyzw has zero norm")
        return self

    def rotation(self) -> Rotation:
        """The configured rotation as a SciPy ``Rotation``."""
        if self.quaternion_xyzw is not None:
            return Rotation.from_quat(self.quaternion_xyzw)
        if self.euler_deg is not None:
            return Rotation.from_euler(self.euler_sequence, self.euler_deg, degrees=True)
        return Rotation.identity()

    def to_pose(self) -> "Poses":
        """The configured pose as a single-element :class:`Poses`."""
        return Poses(np.asarray(self.position_m, dtype=np.float64)[None, :],
                     Rotation.concatenate([self.rotation()]))


def check_euler_sequence(value: str) -> str:
    """``value`` if SciPy accepts it as an Euler sequence, else a ValueError saying why."""
    if len(value) != 3 or not (value.islower() or value.isupper()) or \
            not set(value.lower()) <= _VALID_SEQ:
        raise ValueError("euler_sequence must be three of x/y/z, all lower case (extrinsic) "
                         "or all upper case (intrinsic), e.g. 'xyz'")
    low = value.lower()
    if low[0] == low[1] or low[1] == low[2]:
        raise ValueError(f"euler_sequence '{value}' repeats an axis in consecutive rotations "
                         "(they would merge into one); e.g. 'xyz' or 'zxz'")
    return value
