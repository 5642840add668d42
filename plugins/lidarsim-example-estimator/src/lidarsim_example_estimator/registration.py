"""The user's code, written without lidarsim in mind: point-to-point ICP (Besl & McKay) of a
scan onto model points with SciPy, and a principal-axes first guess."""

from __future__ import annotations

import numpy as np
from scipy.spatial import cKDTree


def best_rigid(source: np.ndarray, target: np.ndarray) -> np.ndarray:
    """4×4 transform minimising Σ‖T·source − target‖² over paired points (Kabsch)."""
    cs, ct = source.mean(axis=0), target.mean(axis=0)
    u, _, vt = np.linalg.svd((source - cs).T @ (target - ct))
    d = np.sign(np.linalg.det(vt.T @ u.T))
    rot = vt.T @ np.diag([1.0, 1.0, d]) @ u.T
    out = np.eye(4)
    out[:3, :3] = rot
    out[:3, 3] = ct - rot @ cs
    return out


def icp(scan: np.ndarray, model: np.ndarray, model_in_scan: np.ndarray, *,
        iterations: int = 40, max_distance: float = 1.0) -> tuple[np.ndarray, float]:
    """Refine the model → scan transform; returns it and the fraction of scan points paired."""
    tree = cKDTree(model)
    scan_to_model = np.linalg.inv(model_in_scan)
    fraction = 0.0
    for _ in range(iterations):
        moved = scan @ scan_to_model[:3, :3].T + scan_to_model[:3, 3]
        distance, index = tree.query(moved, distance_upper_bound=max_distance)
        paired = np.isfinite(distance)
        fraction = float(paired.mean())
        if paired.sum() < 3:
            break
        step = best_rigid(moved[paired], model[index[paired]])
        scan_to_model = step @ scan_to_model
        if np.allclose(step, np.eye(4), atol=1e-9):
            break
    return np.linalg.inv(scan_to_model), fraction


def principal_axes_guess(scan: np.ndarray, model: np.ndarray) -> np.ndarray:
    """Model → scan transform lining up centroids and principal axes (a coarse first guess)."""
    def frame(points: np.ndarray) -> np.ndarray:
        _, vectors = np.linalg.eigh(np.cov((points - points.mean(axis=0)).T))
        if np.linalg.det(vectors) < 0:
            vectors[:, 0] *= -1
        return vectors

    rot = frame(scan) @ frame(model).T
    out = np.eye(4)
    out[:3, :3] = rot
    out[:3, 3] = scan.mean(axis=0) - rot @ model.mean(axis=0)
    return out
