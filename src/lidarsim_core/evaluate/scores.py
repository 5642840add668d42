"""Pose scores of the literature: BOP's ADD, ADD-S, ADD(-S) accuracy and MSSD on the target
mesh's vertices, and the SPEED+ challenge's thresholded scores.

For an estimate ``(R_e, t_e)`` and the truth ``(R_g, t_g)`` of the body in the sensor frame,
over the vertices ``x`` of the mesh the simulation traced (``V`` of them, diameter ``d``, the
largest distance between two vertices):

==================  ===============================================================================
``add_m``           ADD, ``mean_x ‖(R_e x + t_e) − (R_g x + t_g)‖`` (Hinterstoisser et al., ACCV
                    2012), against the given truth (no symmetry)
``adds_m``          ADD-S (ADI), ``mean_x1 min_x2 ‖(R_e x1 + t_e) − (R_g x2 + t_g)‖`` (Hodaň et al.,
                    ECCVW 2016): the closest point instead of the same one, so poses that
                    differ by a symmetry score 0
``add_s_correct``   1 when ADD(-S) < 0.1 d, else 0: ADD-S for a target with declared symmetries,
                    ADD otherwise (the accuracy of BOP and of Hinterstoisser et al. at
                    k_m = 0.1); its mean over frames is that accuracy
``mssd_m``          MSSD, ``min_S max_x ‖(R_e x + t_e) − (R_g S x + t_g)‖`` over the declared
                    symmetry transforms S (Hodaň et al., ECCV 2020, BOP Challenge 2019/2020);
                    an axisymmetric symmetry is sampled so that a step moves no vertex more than
                    1 % of d, as the BOP toolkit does
``mssd_recall``     the share of BOP's thresholds τ = 0.05, 0.10, …, 0.50 · d with MSSD < τ; its
                    mean over frames is BOP's average recall AR_MSSD
``speedplus_t``     SPEED+ position score: ``e_t = ‖t_e − t_g‖ / ‖t_g‖``, zeroed below 2.173 mm
                    per metre of range (0.002173)
``speedplus_q_rad`` SPEED+ orientation score: ``e_q = 2 arccos |⟨q_e, q_g⟩|`` (rad), zeroed below
                    0.169°
``speedplus_score`` their sum; the mean over frames is the challenge's score
==================  ===============================================================================

The SPEED+ thresholds are those of ESA's Satellite Pose Estimation Competition 2021 on SPEED+
(kelvins.esa.int/pose-estimation-2021/scoring): errors below the accuracy of the robotic
testbed's ground truth count as zero. With declared symmetries, ``e_t`` and ``e_q`` are
computed against the equivalent true pose closest to the estimate
(:mod:`~lidarsim_core.evaluate.symmetry`), as the other metrics are.
"""

from __future__ import annotations

import math
from dataclasses import dataclass, field
from typing import Any

import numpy as np

from .symmetry import SymmetryGroup, axis_rotation, turn_about

#: SPEED+ (SPEC2021) position threshold: 2.173 mm per metre of range.
SPEEDPLUS_POSITION_THRESHOLD = 2.173e-3
#: SPEED+ (SPEC2021) orientation threshold (deg).
SPEEDPLUS_ORIENTATION_THRESHOLD_DEG = 0.169
#: ADD(-S) accuracy threshold as a fraction of the diameter (k_m = 0.1).
ADD_FRACTION = 0.1
#: MSSD thresholds of BOP's average recall, fractions of the diameter (0.05 to 0.5).
MSSD_FRACTIONS: tuple[float, ...] = tuple(round(0.05 * k, 2) for k in range(1, 11))
#: Largest vertex displacement of one step of a sampled axisymmetry, fraction of the
#: diameter (the BOP toolkit's ``max_sym_disc_step``).
SYMMETRY_STEP_FRACTION = 0.01
#: Score columns, in file order.
SCORES: tuple[str, ...] = ("add_m", "adds_m", "add_s_correct", "mssd_m", "mssd_recall",
                           "speedplus_t", "speedplus_q_rad", "speedplus_score")


def diameter(vertices: np.ndarray) -> float:
    """Largest distance between two vertices (m): over the convex hull's vertices."""
    points = np.unique(np.asarray(vertices, dtype=np.float64), axis=0)
    if len(points) > 4:
        from scipy.spatial import ConvexHull, QhullError

        try:
            points = points[ConvexHull(points).vertices]
        except QhullError:  # flat or degenerate: every point
            pass
    best = 0.0
    for start in range(0, len(points), 512):  # bounded (512, H) blocks
        block = points[start:start + 512]
        gap = np.linalg.norm(block[:, None, :] - points[None, :, :], axis=-1)
        best = max(best, float(gap.max()))
    return best


def symmetry_transforms(group: SymmetryGroup | None, vertices: np.ndarray,
                        size: float) -> np.ndarray:
    """(G, 4, 4) body transforms of the declared symmetries, an axisymmetry sampled in steps
    that move no vertex more than :data:`SYMMETRY_STEP_FRACTION` of ``size``."""
    if group is None:
        return np.eye(4)[None]
    finite = group.finite
    if group.continuous is None:
        return finite
    axis = np.asarray(group.continuous.axis, dtype=np.float64)
    centre = np.asarray(group.continuous.centre_m, dtype=np.float64)
    offset = vertices - centre
    radius = float(np.linalg.norm(offset - np.outer(offset @ axis, axis), axis=1).max())
    # a turn by θ moves a point at distance r from the axis by 2 r sin(θ/2) <= r θ
    steps = max(1, math.ceil(2 * math.pi * radius / (SYMMETRY_STEP_FRACTION * size)))
    turns = [turn_about(axis_rotation(axis, 2 * math.pi * k / steps), centre)
             for k in range(steps)]
    return np.stack([turn @ g for g in finite for turn in turns])


@dataclass
class TargetScorer:
    """The target's vertices, diameter, symmetry transforms and nearest-vertex tree, prepared
    once per sequence.

    Parameters
    ----------
    vertices
        (V, 3) mesh vertices in the body frame (m).
    group
        The declared symmetries (``None`` or trivial: none).
    """

    vertices: np.ndarray
    group: SymmetryGroup | None = None
    diameter_m: float = field(init=False)
    transforms: np.ndarray = field(init=False)
    _tree: Any = field(init=False, default=None, repr=False)

    def __post_init__(self) -> None:
        self.vertices = np.unique(np.asarray(self.vertices, dtype=np.float64), axis=0)
        self.diameter_m = diameter(self.vertices)
        self.transforms = symmetry_transforms(self.group, self.vertices, self.diameter_m)

    @property
    def symmetric(self) -> bool:
        """Whether the target has declared symmetries (ADD-S decides its accuracy then)."""
        return self.group is not None and (self.group.continuous is not None or
                                           len(self.group.finite) > 1)

    def add(self, est: np.ndarray, truth: np.ndarray) -> float:
        """ADD (m) between two 4×4 body → sensor poses."""
        delta = self.vertices @ (est[:3, :3] - truth[:3, :3]).T + (est[:3, 3] - truth[:3, 3])
        return float(np.linalg.norm(delta, axis=1).mean())

    def adds(self, est: np.ndarray, truth: np.ndarray) -> float:
        """ADD-S (m): each estimated vertex to the closest true one."""
        from scipy.spatial import cKDTree

        if self._tree is None:
            self._tree = cKDTree(self.vertices)
        # the estimated vertices brought into the true body frame: one tree for every frame
        moved = (self.vertices @ est[:3, :3].T + est[:3, 3] - truth[:3, 3]) @ truth[:3, :3]
        distance, _ = self._tree.query(moved, k=1)
        return float(np.mean(distance))

    def mssd(self, est: np.ndarray, truth: np.ndarray) -> float:
        """MSSD (m): the smallest, over the symmetry transforms, of the largest vertex gap."""
        placed = self.vertices @ est[:3, :3].T + est[:3, 3]
        best = math.inf
        for s in self.transforms:
            pose = truth @ s
            gap = placed - (self.vertices @ pose[:3, :3].T + pose[:3, 3])
            best = min(best, float(np.sqrt(np.einsum("ij,ij->i", gap, gap).max())))
        return best

    def scores(self, est: np.ndarray, truth: np.ndarray, e_t: float,
               e_q_rad: float) -> dict[str, float]:
        """Every column of :data:`SCORES` for one frame (``e_t``, ``e_q_rad``: SPEED's terms,
        symmetry-aware)."""
        add = self.add(est, truth)
        adds = self.adds(est, truth)
        mssd = self.mssd(est, truth)
        limit = ADD_FRACTION * self.diameter_m
        correct = (adds if self.symmetric else add) < limit
        recall = float(np.mean([mssd < f * self.diameter_m for f in MSSD_FRACTIONS]))
        return {"add_m": add, "adds_m": adds, "add_s_correct": float(correct),
                "mssd_m": mssd, "mssd_recall": recall, **speedplus_scores(e_t, e_q_rad)}


def speedplus_scores(e_t: float, e_q_rad: float) -> dict[str, float]:
    """SPEED+ position and orientation scores (zero below the thresholds) and their sum."""
    t = 0.0 if e_t < SPEEDPLUS_POSITION_THRESHOLD else e_t
    q = 0.0 if e_q_rad < math.radians(SPEEDPLUS_ORIENTATION_THRESHOLD_DEG) else e_q_rad
    return {"speedplus_t": t, "speedplus_q_rad": q, "speedplus_score": t + q}
