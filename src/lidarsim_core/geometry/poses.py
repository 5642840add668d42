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
from scipy.spatial.transform import Rotation


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


def relative_rows(poses: Poses, reference: Poses) -> Poses:
    """Row ``i`` of ``poses`` in the body frame of row ``i`` of ``reference``, with the bits of
    ``poses[i].relative_to(reference[i])``.

    :meth:`Poses.relative_to` of one row turns the offset with SciPy's one-rotation path (its
    matrix, then a matrix product), which rounds differently from SciPy's many-rotation path;
    the stacked matrix product below is the one-rotation arithmetic on every row.
    """
    rotation = reference.rotation.inv() * poses.rotation
    turn = np.swapaxes(reference.rotation.as_matrix().reshape(-1, 3, 3), 1, 2)
    offset = (poses.position - reference.position)[:, :, None]
    return Poses(np.matmul(turn, offset)[:, :, 0], rotation)
