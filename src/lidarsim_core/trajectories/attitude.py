"""Attitude laws for trajectories that define a position only (HCW, position keyframes).

Two laws, chosen with ``mode``:

``look_at`` (default)
    The body's +X axis (the sensor boresight) points at ``point_m`` (scene frame); the body's
    +Z axis is the component of ``up`` (scene frame) perpendicular to the boresight. When the
    boresight is parallel to ``up`` the scene axis least aligned with the boresight is used as
    "up" instead, and when the body sits on ``point_m`` the boresight is scene +X.
``fixed``
    A constant rotation, given like a pose's rotation (``euler_deg`` + ``euler_sequence`` or
    ``quaternion_xyzw``, scalar-last).
"""

from __future__ import annotations

import math
from typing import Annotated, Any, Literal, Union

import numpy as np
from pydantic import ConfigDict, Discriminator, Field, Tag, model_validator
from scipy.spatial.transform import Rotation

from .. import kernels
from ..base.components import ComponentOptions
from ..scenario.pose import PoseConfig

Vec3 = tuple[float, float, float]


class LookAtAttitude(ComponentOptions):
    """Point the body's +X axis at a scene point, +Z toward ``up``."""

    model_config = ConfigDict(allow_inf_nan=False)

    mode: Literal["look_at"] = "look_at"
    point_m: Vec3 = Field((0.0, 0.0, 0.0), description="Scene point the +X axis aims at (m).")
    up: Vec3 = Field((0.0, 0.0, 1.0), description="Scene direction the body's +Z leans "
                                                  "toward (default +z, H-bar in LVLH).")

    @model_validator(mode="after")
    def _nonzero_up(self) -> "LookAtAttitude":
        if np.linalg.norm(self.up) < 1e-12:
            raise ValueError("'up' must be a non-zero vector")
        return self

    def rotations(self, positions: np.ndarray) -> Rotation:
        """Body→scene rotations for bodies at ``positions`` ((N, 3), m)."""
        return look_at(positions, np.asarray(self.point_m, float), np.asarray(self.up, float))

    def matrices(self, positions: np.ndarray) -> np.ndarray:
        """(N, 3, 3) body→scene rotation matrices for bodies at ``positions`` (compiled when
        the kernels are in use: the same construction, within a few ulp)."""
        point, up = np.asarray(self.point_m, float), np.asarray(self.up, float)
        positions = np.atleast_2d(np.asarray(positions, dtype=np.float64))
        if kernels.enabled():  # for any number of rows: a ray's pose never depends on it
            from ..kernels.poses import look_at_matrices as compiled

            return compiled(np.ascontiguousarray(positions), point, up / np.linalg.norm(up))
        return look_at_matrices(positions, point, up)


    def rate_bound(self, position: np.ndarray, speed: float, span: float) -> float | None:
        """An upper bound on the body's angular speed (rad/s) while it stays within
        ``speed · span`` of ``position`` (m) moving at most at ``speed`` (m/s); None near the
        point or where the boresight comes near ``up`` (the law switches axes there).

        The boresight ``x`` turns at most at ``speed / r`` (``r`` the distance to the point).
        The frame's angular velocity ``ω`` has ``x × ẋ`` across the boresight (norm ``|ẋ|``)
        and the roll ``ω·x = −y·ż`` about it; with ``z = w / |w|``, ``w = up − (up·x) x``,
        ``y·ż = y·ẇ / |w| = −(up·x)(y·ẋ) / |w|``, so ``|ω|² <= |ẋ|² (1 + (up·x)² / |w|²) =
        |ẋ|² / |w|²`` (``|w|² = 1 − (up·x)²``): ``|ω| <= |ẋ| / |w|``.
        """
        ux, uy, uz = self.up
        norm = math.sqrt(ux * ux + uy * uy + uz * uz)
        ux, uy, uz = ux / norm, uy / norm, uz / norm
        px, py, pz = np.asarray(position, dtype=np.float64).reshape(3).tolist()
        ox, oy, oz = self.point_m[0] - px, self.point_m[1] - py, self.point_m[2] - pz
        distance = math.sqrt(ox * ox + oy * oy + oz * oz)
        r_min = distance - speed * span
        if not r_min > 1e-3 * max(1.0, distance):
            return None
        # |x(t) - x(mid)| <= speed·span / r_min, and |up × x| is 1-Lipschitz in x
        cx, cy, cz = uy * oz - uz * oy, uz * ox - ux * oz, ux * oy - uy * ox
        w_min = math.sqrt(cx * cx + cy * cy + cz * cz) / distance - speed * span / r_min
        if not w_min > 1e-3:
            return None
        return speed / r_min / w_min


class FixedAttitude(ComponentOptions):
    """A constant body→scene rotation."""

    model_config = ConfigDict(allow_inf_nan=False)

    mode: Literal["fixed"] = "fixed"
    euler_deg: Vec3 | None = Field(None, description="Rotation angles (deg), see poses.")
    euler_sequence: str = Field("xyz", description="SciPy Euler sequence (lower = extrinsic).")
    quaternion_xyzw: tuple[float, float, float, float] | None = Field(
        None, description="Scalar-last unit quaternion [x, y, z, w].")

    @model_validator(mode="after")
    def _valid_rotation(self) -> "FixedAttitude":
        self.rotation()  # the pose model's checks (sequence, zero norm, one of two)
        return self

    def rotation(self) -> Rotation:
        """The configured rotation."""
        return PoseConfig(euler_deg=self.euler_deg, euler_sequence=self.euler_sequence,
                          quaternion_xyzw=self.quaternion_xyzw).rotation()

    def rotations(self, positions: np.ndarray) -> Rotation:
        """The fixed rotation, once per position."""
        quat = self.rotation().as_quat()
        return Rotation.from_quat(np.tile(quat, (len(positions), 1)))

    def rate_bound(self, position: np.ndarray, speed: float, span: float) -> float:
        """The body does not turn: 0."""
        return 0.0

    def matrices(self, positions: np.ndarray) -> np.ndarray:
        """The fixed rotation's matrix, once per position."""
        return np.repeat(self.rotation().as_matrix().reshape(1, 3, 3), len(positions), axis=0)


def _mode(value: Any) -> str:
    """The attitude law named by ``mode`` (default ``look_at``)."""
    if isinstance(value, dict):
        return value.get("mode", "look_at")
    return getattr(value, "mode", "look_at")


#: An attitude law as written in a scenario (``mode`` picks the law, default ``look_at``).
AttitudeConfig = Annotated[Union[Annotated[LookAtAttitude, Tag("look_at")],
                                 Annotated[FixedAttitude, Tag("fixed")]],
                           Discriminator(_mode)]


def look_at(positions: np.ndarray, point: np.ndarray, up: np.ndarray) -> Rotation:
    """Rotations whose +X axis points from each position to ``point``, +Z toward ``up``.

    Parameters
    ----------
    positions
        (N, 3) body positions in the scene frame (m).
    point
        (3,) scene point to aim at (m).
    up
        (3,) preferred direction of the body's +Z axis (scene frame).

    Returns
    -------
    Rotation
        N body→scene rotations (columns of the matrix: boresight, left, up).
    """
    return Rotation.from_matrix(look_at_matrices(positions, point, up))


def look_at_matrices(positions: np.ndarray, point: np.ndarray, up: np.ndarray) -> np.ndarray:
    """The (N, 3, 3) matrices of :func:`look_at` (orthonormal by construction)."""
    positions = np.atleast_2d(np.asarray(positions, dtype=np.float64))
    n = len(positions)
    x = point[None, :] - positions
    norm = np.linalg.norm(x, axis=1)
    on_point = norm < 1e-12
    x[on_point] = (1.0, 0.0, 0.0)
    norm[on_point] = 1.0
    x /= norm[:, None]
    ups = np.broadcast_to(up / np.linalg.norm(up), (n, 3)).copy()
    z = ups - np.einsum("ij,ij->i", ups, x)[:, None] * x
    znorm = np.linalg.norm(z, axis=1)
    parallel = znorm < 1e-9
    if parallel.any():
        # the scene axis least aligned with the boresight is never parallel to it
        alt = np.eye(3)[np.argmin(np.abs(x[parallel]), axis=1)]
        z[parallel] = alt - np.einsum("ij,ij->i", alt, x[parallel])[:, None] * x[parallel]
        znorm[parallel] = np.linalg.norm(z[parallel], axis=1)
    z /= znorm[:, None]
    y = np.cross(z, x)
    return np.stack([x, y, z], axis=2)

