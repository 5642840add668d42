"""Per-ray poses at the cost of a few arithmetic operations, computed once per piece of a scan.

A moving sensor or target has a pose for every ray's emission time. The trajectory plugin
contract gives them as :class:`~lidarsim_core.geometry.poses.Poses` (a SciPy ``Rotation`` per ray,
:meth:`~lidarsim_core.trajectories.base.Trajectory.poses_at`), which is general but costs
about a microsecond per ray in SciPy's composition and conversion. The hot path needs only
each ray's rotation matrix and position, so:

* the built-in trajectories also implement
  :meth:`~lidarsim_core.trajectories.base.Trajectory.pose_matrices` in closed form, as
  vectorised quaternion arithmetic (tumbling, torque-free, constant velocity, HCW, keyframe
  SLERP) or, for the chains of rotations at constant rates, a compiled kernel
  (:mod:`lidarsim_core.kernels.poses`);
* :func:`pose_matrices` uses that path only when the class that implements it also
  implements ``poses_at`` (a subclass overriding ``poses_at`` alone, and every third-party
  trajectory, goes through ``poses_at``: the plugin contract is unchanged);
* :func:`with_piece_poses` attaches the poses of a piece's rays to its
  :class:`~lidarsim_core.patterns.base.RayBatch`, so culling and casting share them
  (``RayBatch.take`` keeps the rows of the rays it keeps).

The closed forms agree with the SciPy path to a few ulp of the rotation matrices (within
1e-12 m on the points; ``tests/test_posing.py``), and each ray's pose depends only on its own
time, so outputs stay byte-identical across chunk sizes and threads.
"""

from __future__ import annotations

from dataclasses import dataclass
from typing import TYPE_CHECKING, Any

import numpy as np
from scipy.spatial.transform import Rotation

from .. import kernels
from ..base.arrays import take_rows

if TYPE_CHECKING:
    from .poses import Poses


@dataclass(frozen=True)
class PoseMatrices:
    """N body→scene poses as arrays; either array may hold one row, shared by all N (a body
    turning about a fixed centre, a sensor holding its station).

    Attributes
    ----------
    position
        (N or 1, 3) float64 body origins in the scene frame (m).
    matrix
        (N or 1, 3, 3) float64 body→scene rotation matrices.
    """

    position: np.ndarray
    matrix: np.ndarray

    def __len__(self) -> int:
        return max(len(self.position), len(self.matrix))

    def full(self, n: int | None = None) -> "PoseMatrices":
        """Both arrays with one row per pose (``n`` rows if given; contiguous)."""
        n = len(self) if n is None else n
        return PoseMatrices(np.ascontiguousarray(np.broadcast_to(self.position, (n, 3))),
                            np.ascontiguousarray(np.broadcast_to(self.matrix, (n, 3, 3))))

    @classmethod
    def from_poses(cls, poses: "Poses") -> "PoseMatrices":
        """The matrices of a :class:`~lidarsim_core.geometry.poses.Poses`."""
        return cls(np.asarray(poses.position, dtype=np.float64).reshape(-1, 3),
                   poses.rotation.as_matrix().reshape(-1, 3, 3))

    def take(self, rows: np.ndarray) -> "PoseMatrices":
        """The poses at ``rows`` (a single shared pose stays as it is)."""
        if len(self) > 1 and len(rows) == 0:  # no ray left: no pose, shared or not
            return PoseMatrices(self.position[:0], self.matrix[:0])
        return PoseMatrices(
            self.position if len(self.position) == 1 else take_rows(self.position, rows),
            self.matrix if len(self.matrix) == 1 else take_rows(self.matrix, rows))

    def to_poses(self) -> "Poses":
        """As a :class:`~lidarsim_core.geometry.poses.Poses` (SciPy rotations)."""
        from .poses import Poses

        full = self.full()
        return Poses(full.position, Rotation.from_matrix(full.matrix))


def quat_multiply(a: tuple[Any, ...], b: tuple[Any, ...]) -> tuple[Any, ...]:
    """Hamilton product ``a ⊗ b`` of scalar-last quaternions given as ``(x, y, z, w)``
    components (scalars or arrays), in :mod:`lidarsim_core.kernels.poses`'s order."""
    ax, ay, az, aw = a
    bx, by, bz, bw = b
    return (aw * bx + ax * bw + (ay * bz - az * by),
            aw * by + ay * bw + (az * bx - ax * bz),
            aw * bz + az * bw + (ax * by - ay * bx),
            aw * bw - (ax * bx + ay * by + az * bz))


def quat_matrices(x: np.ndarray, y: np.ndarray, z: np.ndarray, w: np.ndarray) -> np.ndarray:
    """(N, 3, 3) rotation matrices of unit quaternions (SciPy's formula)."""
    x2, y2, z2, w2 = x * x, y * y, z * z, w * w
    xy, zw, xz, yw, yz, xw = x * y, z * w, x * z, y * w, y * z, x * w
    out = np.empty((len(x), 3, 3))
    out[:, 0, 0] = x2 - y2 - z2 + w2
    out[:, 1, 0] = 2.0 * (xy + zw)
    out[:, 2, 0] = 2.0 * (xz - yw)
    out[:, 0, 1] = 2.0 * (xy - zw)
    out[:, 1, 1] = -x2 + y2 - z2 + w2
    out[:, 2, 1] = 2.0 * (yz + xw)
    out[:, 0, 2] = 2.0 * (xz + yw)
    out[:, 1, 2] = 2.0 * (yz - xw)
    out[:, 2, 2] = -x2 - y2 + z2 + w2
    return out


@dataclass(frozen=True)
class RotationChain:
    """``R(τ) = F0 · Rot(a1, w1 τ) · F1 · … · Rot(aK, wK τ) · FK``: fixed rotations and
    rotations at constant rates about fixed unit axes.

    Attributes
    ----------
    fixed
        (K+1, 4) scalar-last quaternions F0..FK.
    axes
        (K, 3) unit axes.
    rates
        (K,) rates (rad/s).
    """

    fixed: np.ndarray
    axes: np.ndarray
    rates: np.ndarray

    @classmethod
    def build(cls, *links: Rotation | tuple[np.ndarray, float]) -> "RotationChain":
        """A chain from ``links`` in order: a ``Rotation`` (fixed) or ``(axis, rate)``;
        consecutive fixed rotations are composed, zero rates dropped."""
        fixed, axes, rates = [Rotation.identity()], [], []
        for link in links:
            if isinstance(link, Rotation):
                fixed[-1] = fixed[-1] * link
                continue
            axis, rate = link
            if rate == 0.0:
                continue
            norm = float(np.linalg.norm(axis))
            axes.append(np.asarray(axis, dtype=np.float64) / norm)
            rates.append(float(rate))
            fixed.append(Rotation.identity())
        return cls(np.ascontiguousarray([f.as_quat() for f in fixed], dtype=np.float64),
                   np.ascontiguousarray(np.reshape(axes, (-1, 3)), dtype=np.float64),
                   np.asarray(rates, dtype=np.float64))

    @property
    def rate_bound(self) -> float:
        """An upper bound on the chain's angular speed (rad/s): its angular velocity is the
        sum of each link's rate about its (turned) axis, so at most ``Σ |wk|``."""
        return float(np.abs(self.rates).sum())

    def matrices(self, tau: np.ndarray) -> np.ndarray:
        """(N, 3, 3) rotation matrices at ``tau`` (N,) seconds."""
        tau = np.ascontiguousarray(tau, dtype=np.float64)
        if kernels.enabled():
            from ..kernels.poses import chain_matrices

            return chain_matrices(tau, self.fixed, self.axes, self.rates)
        return self.matrices_numpy(tau)

    def matrices_numpy(self, tau: np.ndarray) -> np.ndarray:
        """:meth:`matrices` in NumPy (the reference of the compiled kernel)."""
        n = len(tau)
        q = tuple(np.full(n, c) for c in self.fixed[0])
        for j in range(len(self.rates)):
            half = 0.5 * (self.rates[j] * tau)
            s, c = np.sin(half), np.cos(half)
            q = quat_multiply(q, (s * self.axes[j, 0], s * self.axes[j, 1],
                                  s * self.axes[j, 2], c))
            q = quat_multiply(q, tuple(self.fixed[j + 1]))
        return quat_matrices(*q)
