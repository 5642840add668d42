"""The injected errors, recovered from a cloud's ground truth, and their normal fits.

Angular error
    The pulse was emitted toward the nominal direction ``d0`` (the cloud's ``azimuth`` and
    ``elevation``) but flew along ``d1 = (x_true, y_true, z_true) / range_true``. The deviation
    is split along two axes perpendicular to ``d0``: the local azimuth axis
    ``e_az = (-sin az, cos az, 0)`` and elevation axis
    ``e_el = (-sin el cos az, -sin el sin az, cos el)``, giving the angles
    ``atan2(d1·e_az, d1·d0)`` and ``atan2(d1·e_el, d1·d0)``. For the paper's model (two
    independent N(0, σ²) rotations about axes perpendicular to the ray) each is N(0, σ²),
    whatever the perpendicular axes, so the pooled sample estimates σ.
Range error
    ``range - range_true`` (m): the N(0, σ²) error added along the ray (paper Eq. 4).
"""

from __future__ import annotations

import math
from dataclasses import dataclass

import numpy as np

from ..patterns.geometry import directions_from_az_el
from ..records.pointcloud import PointCloud


@dataclass(frozen=True)
class NormalFit:
    """Maximum-likelihood normal fit of a sample.

    Attributes
    ----------
    n
        Sample size.
    mean, sigma
        Fitted mean and standard deviation (units of the sample).
    sigma_ci95
        Approximate 95 % confidence interval of ``sigma`` (``σ̂ (1 ± 1.96 / √(2n))``).
    """

    n: int
    mean: float
    sigma: float

    @property
    def sigma_ci95(self) -> tuple[float, float]:
        """Approximate 95 % interval of sigma (large-sample normal approximation)."""
        half = 1.96 / math.sqrt(2 * max(self.n, 1))
        return self.sigma * (1 - half), self.sigma * (1 + half)

    def pdf(self, x: np.ndarray) -> np.ndarray:
        """The fitted normal density at ``x``."""
        s = self.sigma if self.sigma > 0 else 1.0
        return np.exp(-0.5 * ((x - self.mean) / s) ** 2) / (s * math.sqrt(2 * math.pi))


def fit_normal(sample: np.ndarray) -> NormalFit:
    """Fit a normal distribution (mean, population standard deviation) to ``sample``."""
    sample = np.asarray(sample, dtype=np.float64)
    if sample.size == 0:
        return NormalFit(0, float("nan"), float("nan"))
    return NormalFit(int(sample.size), float(sample.mean()), float(sample.std()))


def angular_error_components(cloud: PointCloud) -> np.ndarray:
    """(N, 2) angular deviation of each flown pulse from its nominal direction (rad).

    Columns: about the local azimuth axis and about the local elevation axis (module docstring).
    """
    if len(cloud) == 0:
        return np.empty((0, 2))
    az, el = cloud["azimuth"], cloud["elevation"]
    d0 = directions_from_az_el(az, el)
    d1 = cloud.xyz_true / cloud["range_true"][:, None]
    e_az = np.stack([-np.sin(az), np.cos(az), np.zeros_like(az)], axis=-1)
    e_el = np.stack([-np.sin(el) * np.cos(az), -np.sin(el) * np.sin(az), np.cos(el)], axis=-1)
    along = np.einsum("ij,ij->i", d1, d0)
    return np.column_stack([np.arctan2(np.einsum("ij,ij->i", d1, e_az), along),
                            np.arctan2(np.einsum("ij,ij->i", d1, e_el), along)])


def range_errors(cloud: PointCloud) -> np.ndarray:
    """(N,) reported minus true range of each point (m)."""
    return cloud["range"] - cloud["range_true"]
