"""One sequence of a dataset run: its plan, folder and normalised scenario and, once built, its
simulation, identity and poses."""

from __future__ import annotations

from dataclasses import dataclass
from pathlib import Path
from typing import Any

from ..scenario.model import Scenario
from .config import SequencePlan
from .layout import SCENARIO_COPY
from .poses import PosesFile


@dataclass
class SequenceRun:
    """A sequence of a dataset run (filled in as the run prepares it)."""

    plan: SequencePlan
    root: Path
    data: dict[str, Any]  # normalised scenario dump
    scenario: Scenario | None = None
    frames: int = 0
    identity: dict[str, Any] | None = None
    poses: PosesFile | None = None
    group: str = ""
    sim: Any = None

    @property
    def copy_path(self) -> Path:
        return self.root / SCENARIO_COPY
