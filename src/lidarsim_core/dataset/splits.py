"""Train/val/test splits by trajectory, never by frame.

Consecutive frames of one sequence are nearly the same picture, and two sequences that differ
only in their noise seed fly the same trajectory: putting either across splits leaks the test
set into training. So sequences are first gathered into **trajectory groups**: sequences whose
sensor and targets (names, meshes, poses or trajectories) are configured identically share a
group, whatever their seed, noise, sensor datasheet or frame timing; a sequence's ``group:``
names its group explicitly instead. Whole groups then go to one split each: groups with a
pinned ``split:`` go there, the others are shuffled by a seeded hash of their key and dealt
out by the configured fractions (largest remainder, every split with a non-zero fraction
getting at least one group while there are enough).
"""

from __future__ import annotations

import hashlib
import math
from typing import Any

from ..base.errors import ConfigError
from ..scenario.model import Scenario
from .config import SPLIT_NAMES, SplitFractions
from .identity import canonical_sha256


def trajectory_key(scenario: Scenario) -> str:
    """A short hash of what moves where in ``scenario`` (see the module docstring)."""
    key = {"sensor": scenario.sensor.trajectory_config().model_dump(mode="json"),
           "targets": [{"name": t.name, "mesh": t.mesh.model_dump(mode="json"),
                        "trajectory": t.trajectory_config().model_dump(mode="json")}
                       for t in scenario.targets]}
    return "traj-" + canonical_sha256(key)[:12]


def split_counts(n: int, fractions: SplitFractions) -> dict[str, int]:
    """How many of ``n`` groups each split gets."""
    weights = {name: getattr(fractions, name) for name in SPLIT_NAMES}
    total = sum(weights.values())
    quotas = {name: n * w / total for name, w in weights.items()}
    counts = {name: math.floor(q) for name, q in quotas.items()}
    by_remainder = sorted(SPLIT_NAMES, key=lambda s: (-(quotas[s] - counts[s]),
                                                      SPLIT_NAMES.index(s)))
    for name in by_remainder[:n - sum(counts.values())]:
        counts[name] += 1
    positive = [s for s in SPLIT_NAMES if weights[s] > 0]
    if n >= len(positive):
        for name in positive:
            if counts[name] == 0:
                donor = max(SPLIT_NAMES, key=lambda s: (counts[s], -SPLIT_NAMES.index(s)))
                counts[donor] -= 1
                counts[name] += 1
    return counts


def assign_splits(groups: dict[str, list[str]], pinned: dict[str, str],
                  fractions: SplitFractions, seed: int, *, source: str) -> dict[str, str]:
    """Sequence name → split, whole groups at a time.

    Parameters
    ----------
    groups
        Group key → names of its sequences.
    pinned
        Sequence name → split it must go to.
    fractions
        Split fractions for the groups that are not pinned.
    seed
        Seed of the shuffle of groups.
    source
        The dataset file, for errors.

    Raises
    ------
    ConfigError
        If two sequences of one trajectory group are pinned to different splits.
    """
    group_split: dict[str, str] = {}
    for key, names in groups.items():
        wanted = {pinned[n] for n in names if n in pinned}
        if len(wanted) > 1:
            raise ConfigError(f"sequences {', '.join(names)} share trajectory group '{key}' but "
                              f"are pinned to different splits ({', '.join(sorted(wanted))})",
                              source=source, field="sequences")
        if wanted:
            group_split[key] = wanted.pop()
    free = sorted((k for k in groups if k not in group_split),
                  key=lambda k: hashlib.sha256(f"{seed}:{k}".encode()).hexdigest())
    counts = split_counts(len(free), fractions)
    start = 0
    for name in SPLIT_NAMES:
        for key in free[start:start + counts[name]]:
            group_split[key] = name
        start += counts[name]
    return {seq: group_split[key] for key, names in groups.items() for seq in names}


def splits_record(groups: dict[str, list[str]], assignment: dict[str, str],
                  frames: dict[str, int], fractions: SplitFractions, seed: int
                  ) -> dict[str, Any]:
    """The content of ``splits.json``."""
    return {"format": "lidarsim-splits", "version": 1, "by": "trajectory group",
            "fractions": fractions.model_dump(), "split_seed": seed,
            "groups": {key: {"split": assignment[names[0]], "sequences": names}
                       for key, names in sorted(groups.items())},
            "splits": {s: [n for n in assignment if assignment[n] == s] for s in SPLIT_NAMES},
            "frames": {s: sum(frames[n] for n in assignment if assignment[n] == s)
                       for s in SPLIT_NAMES}}
