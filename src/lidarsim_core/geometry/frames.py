"""Frame changes of many vectors at once: rotations and body-frame transforms that reuse one
rotation matrix for every row of a piece, with the same bits either way.
"""

from __future__ import annotations

import numpy as np

from .poses import Poses
from .posing import PoseMatrices


def _matvec(matrices: np.ndarray, vectors: np.ndarray) -> np.ndarray:
    """Rows ``M_n v_n`` for (1 or N, 3, 3) ``matrices`` and (1 or N, 3) ``vectors``.

    Computed as ``(M_i0 v_0 + M_i1 v_1) + M_i2 v_2`` with element-wise operations, always in
    this order, so a row gets the same bits whether one matrix serves every row or each row
    has its own: a frame does not change in the last bit with the size of its pieces (a piece
    of one ray of a moving target holds one pose, like a piece of a static one).
    """
    shared = matrices[0] if len(matrices) == 1 else None
    n = len(vectors) if shared is not None else max(len(matrices), len(vectors))
    x, y, z = vectors[:, 0], vectors[:, 1], vectors[:, 2]
    out = np.empty((n, 3))
    for i in range(3):
        a, b, c = (shared[i] if shared is not None else matrices[:, i, :].T)
        column = x * a
        column += y * b
        column += z * c
        out[:, i] = column
    return out


def rotate(poses: "Poses | PoseMatrices", vectors: np.ndarray, *,
           inverse: bool = False) -> np.ndarray:
    """Rotate (N, 3) vectors by ``poses`` (body → scene, or back with ``inverse``).

    ``poses`` holds one pose (applied to every row) or N. Both cases use the same arithmetic,
    so a vector's result depends only on its own pose, not on how many rows share the call.
    """
    matrices = getattr(poses, "matrix", None)  # PoseMatrices: already matrices
    if matrices is None:
        matrices = poses.rotation.as_matrix().reshape(-1, 3, 3)
    if inverse:
        matrices = matrices.transpose(0, 2, 1)
    return _matvec(matrices, np.asarray(vectors, dtype=np.float64).reshape(-1, 3))


def to_body(poses: "Poses | PoseMatrices", points: np.ndarray) -> np.ndarray:
    """Map (N, 3) (or (1, 3)) scene points into the body frame of ``poses``."""
    return rotate(poses, points - poses.position, inverse=True)
