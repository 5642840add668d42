"""Rigid-body poses: configuration models and a vectorised pose container.

Conventions
-----------
* A pose maps **body → scene**: ``x_scene = R @ x_body + p``.
* ``euler_deg`` uses :meth:`scipy.spatial.transform.Rotation.from_euler` semantics: a lower-case
  sequence (default ``"xyz"``, the seed paper's rotations about X, then Y, then Z) means
  rotations about the *fixed* (extrinsic) axes; an upper-case sequence such as ``"ZYX"`` means
  intrinsic rotations about the moving axes.
* Quaternions are scalar-last ``[x, y, z, w]`` (SciPy's order) and are normalised on input.
"""

from __future__ import annotations

from dataclasses import dataclass
from typing import Any

import numpy as np
from pydantic import BaseModel, ConfigDict, Field, field_validator, model_validator
from scipy.spatial.transform import Rotation

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


@dataclass(frozen=True)
class Poses:
    """N body→scene poses (N may be 1, which broadcasts).

    Attributes
    ----------
    position
        (N, 3) float64 body origins in the scene frame (m).
    rotation
        A SciPy ``Rotation`` holding N rotations (body → scene).
    """

    position: np.ndarray
    rotation: Rotation

    def __len__(self) -> int:
        return len(self.position)

    def apply(self, points: np.ndarray) -> np.ndarray:
        """Map (N, 3) body-frame points to the scene frame."""
        return self.rotation.apply(points) + self.position

    def apply_inverse(self, points: np.ndarray) -> np.ndarray:
        """Map (N, 3) scene-frame points to the body frame."""
        return self.rotation.apply(points - self.position, inverse=True)

    def rotate(self, vectors: np.ndarray) -> np.ndarray:
        """Rotate (N, 3) body-frame vectors into the scene frame."""
        return self.rotation.apply(vectors)

    def rotate_inverse(self, vectors: np.ndarray) -> np.ndarray:
        """Rotate (N, 3) scene-frame vectors into the body frame."""
        return self.rotation.apply(vectors, inverse=True)

    def inverse(self) -> "Poses":
        """The scene→body poses."""
        inv = self.rotation.inv()
        return Poses(-inv.apply(self.position), inv)

    def relative_to(self, reference: "Poses") -> "Poses":
        """This pose expressed in ``reference``'s body frame (``reference⁻¹ ∘ self``)."""
        rot = reference.rotation.inv() * self.rotation
        pos = reference.rotation.apply(self.position - reference.position, inverse=True)
        return Poses(pos, rot)

    def __getitem__(self, index: Any) -> "Poses":
        idx = np.atleast_1d(np.arange(len(self))[index])
        return Poses(self.position[idx], self.rotation[idx])

    def as_matrices(self) -> np.ndarray:
        """(N, 4, 4) homogeneous body→scene matrices."""
        mats = np.zeros((len(self), 4, 4))
        mats[:, :3, :3] = self.rotation.as_matrix().reshape(-1, 3, 3)
        mats[:, :3, 3] = self.position
        mats[:, 3, 3] = 1.0
        return mats

    def to_records(self) -> list[dict[str, list[float]]]:
        """JSON-ready ``[{"translation_m": [...], "quaternion_xyzw": [...]}, ...]``."""
        quats = self.rotation.as_quat().reshape(-1, 4)
        return [{"translation_m": p.tolist(), "quaternion_xyzw": q.tolist()}
                for p, q in zip(self.position, quats)]
