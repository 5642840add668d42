"""Pose-error metrics of one frame: translation and rotation errors and ESA's SPEED score.

For an estimated pose ``(q_est, t_est)`` and the true pose ``(q_gt, t_gt)`` of the target body
in the sensor frame:

================================  =================================================================
``translation_error_m``           ``‖t_est − t_gt‖`` (m)
``rotation_error_deg``            the angle of the rotation ``R_gtᵀ R_est`` (deg)
``e_t``                           ``‖t_est − t_gt‖ / ‖t_gt‖`` (SPEED's normalised translation
                                  error; ``t_gt`` is the range vector to the body origin)
``e_q_rad``                       ``2 · arccos |⟨q_est, q_gt⟩|`` (rad), the same angle
``speed_score``                   ``e_t + e_q_rad`` (SPEED's per-image pose score)
================================  =================================================================

The angle is computed from the relative rotation's quaternion with ``atan2`` rather than with
``arccos``, which loses half the digits near zero: a perfect estimate scores exactly 0. With
declared symmetries the true pose is first replaced by its closest equivalent
(:func:`~lidarsim_core.evaluate.symmetry.closest_equivalent`).
"""

from __future__ import annotations

import math
from typing import TYPE_CHECKING, Any

import numpy as np
from scipy.spatial.transform import Rotation

from .symmetry import SymmetryGroup, closest_equivalent

if TYPE_CHECKING:
    from .scores import TargetScorer

#: Metric columns, in file order.
METRICS: tuple[str, ...] = ("translation_error_m", "rotation_error_deg", "e_t", "e_q_rad",
                            "speed_score")


def pose_matrix(quaternion_xyzw: Any, translation_m: Any) -> np.ndarray:
    """4×4 transform from a scalar-last quaternion and a translation."""
    out = np.eye(4)
    out[:3, :3] = Rotation.from_quat(np.asarray(quaternion_xyzw, dtype=np.float64)).as_matrix()
    out[:3, 3] = np.asarray(translation_m, dtype=np.float64)
    return out


def rotation_angle_rad(q_a: Any, q_b: Any) -> float:
    """Angle of the rotation between two attitudes, ``2·arccos|⟨q_a, q_b⟩|`` (rad), computed
    stably (exactly 0 for equal quaternions)."""
    relative = Rotation.from_quat(np.asarray(q_b, dtype=np.float64)).inv() * \
        Rotation.from_quat(np.asarray(q_a, dtype=np.float64))
    return float(relative.magnitude())


def pose_errors(q_est: Any, t_est: Any, q_gt: Any, t_gt: Any,
                group: SymmetryGroup | None = None,
                scorer: "TargetScorer | None" = None) -> dict[str, float]:
    """The metrics of :data:`METRICS` for one frame (see the module docstring), and with a
    ``scorer`` the scores of :data:`~lidarsim_core.evaluate.scores.SCORES`.

    Parameters
    ----------
    q_est, t_est
        Estimated attitude (scalar-last quaternion) and position (m) of the body in the sensor
        frame.
    q_gt, t_gt
        The true ones.
    group
        The target's symmetries (``None``: none).
    scorer
        The target's vertices and symmetries for ADD, ADD-S, MSSD and SPEED+
        (:class:`~lidarsim_core.evaluate.scores.TargetScorer`); ``None``: those are not
        computed.
    """
    t_est = np.asarray(t_est, dtype=np.float64)
    q_gt = np.asarray(q_gt, dtype=np.float64)
    t_gt = np.asarray(t_gt, dtype=np.float64)
    given = pose_matrix(q_gt, t_gt)  # ADD is against the given truth, whatever the symmetry
    if group is not None and (group.continuous is not None or len(group.finite) > 1):
        truth = closest_equivalent(pose_matrix(q_gt, t_gt), pose_matrix(q_est, t_est), group)
        q_gt = Rotation.from_matrix(truth[:3, :3]).as_quat()
        t_gt = truth[:3, 3]
    angle = rotation_angle_rad(q_est, q_gt)
    shift = float(np.linalg.norm(t_est - t_gt))
    distance = float(np.linalg.norm(t_gt))
    e_t = shift / distance if distance > 0 else math.inf
    out = {"translation_error_m": shift, "rotation_error_deg": math.degrees(angle),
           "e_t": e_t, "e_q_rad": angle, "speed_score": e_t + angle}
    if scorer is not None:
        out.update(scorer.scores(pose_matrix(q_est, t_est), given, e_t, angle))
    return out
