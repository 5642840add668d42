"""Scoring pose estimators on simulated datasets (``lidarsim evaluate``, docs/evaluate.md).

:func:`evaluate_dataset` runs a registered :class:`PoseEstimator` on every frame of a dataset
made by ``lidarsim dataset`` and writes estimates, per-frame metrics, a summary, plots and an
HTML report. The baselines ``icp`` and ``fpfh_ransac_icp`` need Open3D (extra ``eval``);
nothing heavy is imported here.
"""

from .base import (
                   EstimationFailed,
                   FrameInput,
                   PoseEstimate,
                   PoseEstimator,
                   TargetModelData,
                   function_estimator,
)
from .metrics import pose_errors
from .run import EvaluationResult, evaluate_dataset
from .symmetry import Symmetry, SymmetryGroup, parse_symmetry

#: Modules registered as built-in plugins (see ``lidarsim_core.plugins.manager``).
BUILTIN_MODULES: tuple[str, ...] = ("baselines",)

__all__ = ["EstimationFailed", "EvaluationResult", "FrameInput", "PoseEstimate", "PoseEstimator",
           "Symmetry", "SymmetryGroup", "TargetModelData", "evaluate_dataset", "function_estimator",
           "parse_symmetry", "pose_errors"]
