"""What a dataset is made of: one scenario, or a dataset file listing several sequences.

A **sequence** is one scenario run frame after frame along its trajectories. A plain scenario
file gives a dataset of one sequence. A **dataset file** (YAML/TOML/JSON with a top-level
``sequences:`` list) gives several, for instance the same scene with other seeds or varied
trajectories, and the train/val/test split is then made by trajectory::

    sequences:
      - scenario: scenarios/envisat_tumbling_hold.yaml   # relative to this file
        name: hold                                        # default: the scenario's file stem
        seeds: [1, 2, 3]        # one sequence per seed: hold_s1, hold_s2, hold_s3
        frames: 50              # override scan.frames
      - scenario: scenarios/envisat_tumbling_hold.yaml
        name: hold_fast
        set:                    # dotted-path overrides of the scenario: trajectory variations
          targets.0.trajectory.spin_rate_deg_s: 5.0
        split: test             # pin a split (optional)
    splits: {train: 0.8, val: 0.1, test: 0.1}   # fractions of trajectory groups
    split_seed: 0
    format: laz                 # default exporter (the command's --format wins)
    exporter_options: {scale_m: 0.001}
"""

from __future__ import annotations

import copy
import re
from dataclasses import dataclass
from pathlib import Path
from typing import Annotated, Any, Literal

from pydantic import BaseModel, ConfigDict, Field, model_validator

from ..base.config_io import read_config_file
from ..base.errors import ConfigError
from ..base.limits import MAX_SEED
from ..base.validation import validate_model
from ..scenario.load import scenario_from_dict
from ..scenario.model import Scenario
from .randomize import Distribution, draw_values, sequence_rng
from .samples import SampleSettings

SPLIT_NAMES = ("train", "val", "test")
_NAME_RE = re.compile(r"^[A-Za-z0-9][A-Za-z0-9_.-]*$")


class _Strict(BaseModel):
    model_config = ConfigDict(extra="forbid", allow_inf_nan=False)


class SequenceSpec(_Strict):
    """One entry of a dataset file's ``sequences`` list."""

    scenario: Path = Field(description="Scenario file, relative to the dataset file.")
    name: str | None = Field(None, description="Sequence name (default: the scenario's stem).")
    seed: int | None = Field(None, ge=0, le=MAX_SEED,
                             description="Override the scenario's seed.")
    seeds: list[Annotated[int, Field(ge=0, le=MAX_SEED)]] | None = Field(None, min_length=1,
                                    description="One sequence per seed (name gets _s<seed>).")
    frames: int | None = Field(None, ge=1, description="Override scan.frames.")
    set: dict[str, Any] = Field(default_factory=dict,
                                description="Dotted path → value overrides of the scenario.")
    split: Literal["train", "val", "test"] | None = Field(None, description="Pin a split.")
    group: str | None = Field(None, description="Trajectory group (default: sequences with "
                                                "the same trajectories form a group).")
    randomize: dict[str, Distribution] = Field(
        default_factory=dict, description="Dotted path → distribution, drawn per sequence "
                                          "from the dataset's seed (dataset.randomize).")
    count: int | None = Field(None, ge=1, le=10_000_000,
                              description="Sequences drawn from this randomised entry.")

    @model_validator(mode="after")
    def _seed_or_seeds(self) -> "SequenceSpec":
        if self.seed is not None and self.seeds is not None:
            raise ValueError("give either 'seed' or 'seeds', not both")
        if self.count is not None and not self.randomize:
            raise ValueError("'count' needs 'randomize'")
        if self.randomize and self.seeds is not None:
            raise ValueError("give either 'randomize' or 'seeds', not both")
        if self.name is not None and not _NAME_RE.match(self.name):
            raise ValueError("name may hold letters, digits, '_', '-' and '.' only")
        return self


class SplitFractions(_Strict):
    """Fractions of the trajectory groups that go to each split."""

    train: float = Field(0.8, ge=0)
    val: float = Field(0.1, ge=0)
    test: float = Field(0.1, ge=0)

    @model_validator(mode="after")
    def _positive_total(self) -> "SplitFractions":
        if self.train + self.val + self.test <= 0:
            raise ValueError("split fractions must not all be zero")
        return self


class DatasetConfig(_Strict):
    """A dataset file: several sequences and how to split them."""

    sequences: list[SequenceSpec] = Field(min_length=1)
    splits: SplitFractions = Field(default_factory=SplitFractions)
    split_seed: int = Field(0, ge=0, description="Seed of the split's shuffle of groups.")
    format: str | None = Field(None, description="Exporter name (default: ply).")
    exporter_options: dict[str, Any] = Field(default_factory=dict,
                                             description="Options of the exporter.")
    seed: int = Field(0, ge=0, le=2 ** 63 - 1,
                      description="Seed of every randomised draw (dataset.randomize).")
    samples: SampleSettings | None = Field(
        None, description="Training samples of format 'shards' (dataset.samples).")


@dataclass
class SequencePlan:
    """A sequence ready to run: its name, validated scenario and split settings."""

    name: str
    scenario: Scenario
    split: str | None = None
    group: str | None = None
    drawn: dict[str, Any] | None = None


@dataclass
class DatasetPlan:
    """Everything a dataset run needs from its input file."""

    sequences: list[SequencePlan]
    source: str
    config: DatasetConfig | None = None

    @property
    def multi(self) -> bool:
        """Whether this is a dataset file (sequences under ``sequences/``)."""
        return self.config is not None


def set_dotted(data: dict[str, Any], path: str, value: Any, *, source: str, field: str) -> None:
    """Set ``data[a][b][0]...`` from ``"a.b.0"``, creating missing mapping keys."""
    keys = path.split(".")
    node: Any = data
    for i, key in enumerate(keys):
        last = i == len(keys) - 1
        if isinstance(node, list):
            if not key.isdigit() or int(key) >= len(node):
                raise ConfigError(f"'{key}' is not an index of a list of {len(node)} items",
                                  source=source, field=field)
            if last:
                node[int(key)] = value
            else:
                node = node[int(key)]
        elif isinstance(node, dict):
            if last:
                node[key] = value
            else:
                node = node.setdefault(key, {})
        else:
            raise ConfigError(f"cannot set '{key}' inside a {type(node).__name__}",
                              source=source, field=field)


def scenario_variant(raw: dict[str, Any], *, source: str | Path | None, seed: int | None = None,
                     frames: int | None = None, updates: dict[str, Any] | None = None,
                     where: str = "<dataset>", field: str = "set") -> Scenario:
    """Validate a scenario mapping after applying a dataset's overrides.

    ``frames`` replaces ``scan.frames`` (and drops ``scan.sequence_duration_s``); ``updates``
    maps dotted paths to new values.
    """
    data = copy.deepcopy(raw)
    for path, value in (updates or {}).items():
        set_dotted(data, path, value, source=where, field=f"{field}.{path}")
    if seed is not None:
        data["seed"] = seed
    if frames is not None:
        scan = data.setdefault("scan", {})
        if not isinstance(scan, dict):
            raise ConfigError("scan must be a mapping", source=source, field="scan")
        scan["frames"] = frames
        scan.pop("sequence_duration_s", None)
    try:
        return scenario_from_dict(data, source=source)
    except ConfigError as exc:
        # a value the dataset file set is the dataset file's mistake: name it and its field
        entry = field.rsplit(".", 1)[0] if field.endswith(".set") else None
        blamed = {path: f"{field}.{path}" for path in (updates or {})}
        if seed is not None and entry is not None:
            blamed["seed"] = f"{entry}.seed"
        if frames is not None and entry is not None:
            blamed["scan.frames"] = f"{entry}.frames"
        bad = exc.field or ""
        for path, where_field in blamed.items():
            if bad == path or bad.startswith(path + ".") or path.startswith(bad + ".") and bad:
                raise ConfigError(exc.message, source=where, field=where_field) from None
        raise


def is_dataset_file(data: dict[str, Any]) -> bool:
    """Whether a parsed input file is a dataset file (top-level ``sequences``)."""
    return "sequences" in data


def load_plan(path: str | Path, *, frames: int | None = None,
              sequences: int | None = None) -> DatasetPlan:
    """Read a scenario or dataset file into a :class:`DatasetPlan`.

    Parameters
    ----------
    path
        A scenario file (one sequence) or a dataset file (``sequences:`` list).
    frames
        Override the number of frames of every sequence.
    sequences
        Override the ``count`` of every randomised entry (``lidarsim dataset --sequences``).

    Raises
    ------
    ConfigError
        One line naming the file and field that is wrong.
    """
    path = Path(path)
    data = read_config_file(path)
    if not is_dataset_file(data):
        scenario = scenario_variant(data, source=path, frames=frames, where=str(path))
        return DatasetPlan([SequencePlan(path.stem, scenario)], str(path))
    config = validate_model(DatasetConfig, data, source=path)
    if sequences is not None and not any(spec.randomize for spec in config.sequences):
        raise ConfigError("--sequences needs an entry with 'randomize'", source=path,
                          field="sequences")
    # body-frame samples need the body-frame columns
    forced = {"scan.body_frame_truth": True} \
        if config.samples is not None and config.samples.body_frame else {}
    plans: list[SequencePlan] = []
    for i, spec in enumerate(config.sequences):
        spec = spec.model_copy(update={"set": {**forced, **spec.set}})
        file = spec.scenario if spec.scenario.is_absolute() else path.parent / spec.scenario
        field = f"sequences.{i}"
        try:
            raw = read_config_file(file)
        except ConfigError as exc:
            raise ConfigError(exc.message, source=path, field=f"{field}.scenario") from None
        base = spec.name or file.stem
        if spec.randomize:
            plans += _drawn_sequences(spec, raw, file, base, config.seed, i, path,
                                      frames=frames or spec.frames,
                                      count=sequences or spec.count or 1)
            continue
        seeds = spec.seeds if spec.seeds is not None else [spec.seed]
        for seed in seeds:
            name = f"{base}_s{seed}" if spec.seeds is not None else base
            scenario = scenario_variant(raw, source=file, seed=seed,
                                        frames=frames or spec.frames, updates=spec.set,
                                        where=str(path), field=f"{field}.set")
            plans.append(SequencePlan(name, scenario, spec.split, spec.group))
    names = [s.name for s in plans]
    repeated = sorted({n for n in names if names.count(n) > 1})
    if repeated:
        raise ConfigError(f"sequence names must be unique; repeated: {', '.join(repeated)} "
                          "(give each entry a 'name')", source=path, field="sequences")
    return DatasetPlan(plans, str(path), config)


#: Digits of the draw number in the names of randomised sequences (``name_r0007``).
DRAW_DIGITS = 4


def _drawn_sequences(spec: SequenceSpec, raw: dict[str, Any], file: Path, base: str,
                     dataset_seed: int, entry: int, path: Path, *, frames: int | None,
                     count: int) -> list[SequencePlan]:
    """The ``count`` sequences of a randomised entry, each with its drawn values."""
    field = f"sequences.{entry}"
    out = []
    for k in range(count):
        try:
            drawn = draw_values(spec.randomize, sequence_rng(dataset_seed, entry, k),
                                draw_seed=spec.seed is None)
        except ValueError as exc:
            raise ConfigError(str(exc), source=path, field=f"{field}.randomize") from None
        seed = drawn.pop("seed", spec.seed)
        updates = {**spec.set, **drawn}
        scenario = scenario_variant(raw, source=file, seed=seed, frames=frames,
                                    updates=updates, where=str(path), field=f"{field}.set")
        if seed is not None and spec.seed is None:
            drawn["seed"] = seed
        out.append(SequencePlan(f"{base}_r{k:0{DRAW_DIGITS}d}", scenario, spec.split,
                                spec.group, drawn))
    return out
