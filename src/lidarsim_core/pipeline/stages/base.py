"""The contract of a measurement stage, and the piece of pulses that flows through them.

After the cast, a piece of pulses is a :class:`Piece`: its rays, the directions flown, the
closest hit of every (sub-)ray and the scene-frame geometry of the cast. The
:class:`~lidarsim_core.pipeline.simulation.Simulation` runs its measurement stages in order on it; each
stage reads some fields of the piece and writes others (its docstring says which), and a stage
that is switched off is not in the list at all, so the seed paper's model runs exactly the code
it always ran. Finally :func:`lidarsim_core.pipeline.stages.record.record_columns` turns the piece into
point-record columns.
"""

from __future__ import annotations

from dataclasses import dataclass, field
from typing import Protocol

import numpy as np

from ...geometry.posing import PoseMatrices
from ...instrument.returns import Candidates, SubRayHits
from ...noise.base import NoiseContext
from ...patterns.base import RayBatch


@dataclass
class SceneRays:
    """Scene-frame geometry of a piece's cast, for stages that cast secondary rays.

    Attributes
    ----------
    origin
        (1, 3) or (N, 3) sensor position in the scene frame at each pulse's time.
    vectors
        Directions flown and, with divergence, the beam's cross axes (u, v), rotated into the
        scene frame ((N, 3) each).
    sensor_poses
        The sensor's pose(s) (one, or one per pulse).
    target_poses
        Each target's pose(s) (one, or one per pulse).
    """

    origin: np.ndarray
    vectors: list[np.ndarray]
    sensor_poses: PoseMatrices
    target_poses: list[PoseMatrices]


@dataclass
class Piece:
    """A piece of pulses between the cast and the record.

    Attributes
    ----------
    batch
        The pulses (after culling).
    frame
        Frame number (selects random streams).
    contexts
        The noise chain's contexts, in chain order.
    flown
        (N, 3) directions flown, sensor frame.
    axes
        The beam's cross axes (u, v) in the sensor frame; empty without divergence.
    hits
        Closest hit of every (sub-)ray, pulse-major.
    scene
        Scene-frame geometry of the cast.
    cand
        Candidate returns, sorted by (pulse, range) (written by the candidate stage, extended by
        the bounce and Sun stages).
    detected
        (M,) which candidates the sensor detects (detection stage).
    rows, flag, number, count
        Candidates written to the record, whether each was detected, return number and returns
        per pulse (return selection stage).
    range_measured, direction_measured
        Reported range and direction of every written row (noise stage).
    """

    batch: RayBatch
    frame: int
    contexts: list[NoiseContext]
    flown: np.ndarray
    axes: list[np.ndarray]
    hits: SubRayHits
    scene: SceneRays
    cand: Candidates | None = None
    detected: np.ndarray | None = None
    rows: np.ndarray | None = None
    flag: np.ndarray | None = None
    number: np.ndarray | None = None
    count: np.ndarray | None = None
    range_measured: np.ndarray | None = None
    direction_measured: np.ndarray | None = None
    #: (N,) receiver noise σ / σ_n of each pulse when background light raises it (the Sun
    #: stage); None: the link budget's own noise.
    noise_scale: np.ndarray | None = None
    #: Extra point-record columns written by optional stages (name → (M_written,) array).
    extra: dict[str, np.ndarray] = field(default_factory=dict)


class Stage(Protocol):
    """One measurement stage: built once per simulation, run on every piece."""

    #: Short name (metadata, error messages).
    name: str

    def run(self, piece: Piece) -> None:
        """Read some fields of ``piece`` and write others (see each stage's docstring)."""
