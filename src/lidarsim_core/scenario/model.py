"""Scenario files: what to simulate, validated by pydantic and loaded from YAML/TOML/JSON.

A minimal scenario (YAML)::

    seed: 7
    sensor:
      datasheet: livox-mid70-rose          # catalogue name, a datasheet file, or an inline mapping
      pose: {position_m: [0, 0, 0]}
      # beam: {sub_rays: 16}, detection: {}, returns: {mode: dual}: sensor realism, off
      # unless given (docs/realism.md)
    targets:
      - name: envisat
        mesh: {model: envisat, options: {detail: medium}}   # or {path: envisat.stl, scale: 1.0}
        pose: {position_m: [40, 0, 0], euler_deg: [0, 0, 30]}
    scan: {duration_s: 1.0}
    backend: {name: auto}                  # auto | numpy | embree | any installed backend
    noise: [{name: angular}, {name: range}]   # omit for the datasheet's errors; [] for none
    # normals: ziggurat                    # the noise's normal generator; default inverse_cdf

Relative mesh and datasheet paths are resolved against the scenario file's directory.
"""

from __future__ import annotations

import hashlib
import json
import math
from pathlib import Path
from typing import Any, Literal

from pydantic import (
    BaseModel,
    ConfigDict,
    Field,
    PrivateAttr,
    field_validator,
    model_serializer,
    model_validator,
)

from ..base.limits import LIMITS, MAX_SEED, limit
from ..base.validation import validate_model
from .pose import PoseConfig
from .sensor import (
    BeamConfig,
    DetectionConfig,
    MultipathConfig,
    ReceiverConfig,
    ReturnsConfig,
)
from .earth import EarthConfig
from .sun import SunConfig


class _Strict(BaseModel):
    model_config = ConfigDict(extra="forbid", allow_inf_nan=False)


class NamedComponent(_Strict):
    """A plugin component chosen by name, with its options."""

    name: str = Field(description="Registered name of the component.")
    options: dict[str, Any] = Field(default_factory=dict, description="Component options.")


class TrajectoryConfig(BaseModel):
    """A trajectory plugin by ``kind`` with its options inline (validated by that plugin)."""

    model_config = ConfigDict(extra="allow")

    kind: str = Field(description="Registered trajectory name, e.g. 'static'.")

    def plugin_options(self) -> dict[str, Any]:
        """The options for the trajectory plugin (everything but ``kind``)."""
        return dict(self.model_extra or {})


class _Posed(_Strict):
    pose: PoseConfig | None = Field(None, description="A fixed pose (body → scene).")
    trajectory: TrajectoryConfig | None = Field(None, description="A time-varying pose.")

    @model_validator(mode="after")
    def _one_of_pose_trajectory(self) -> Any:
        if self.pose is not None and self.trajectory is not None:
            raise ValueError("give either 'pose' or 'trajectory', not both")
        return self

    def trajectory_config(self) -> TrajectoryConfig:
        """The trajectory, turning a plain ``pose`` into a static trajectory."""
        if self.trajectory is not None:
            return self.trajectory
        pose = self.pose or PoseConfig()
        return TrajectoryConfig(kind="static", **pose.model_dump(exclude_defaults=True))


class SensorConfig(_Posed):
    """The LiDAR: its datasheet, optional pattern overrides, and its pose or trajectory."""

    datasheet: str | dict[str, Any] = Field(
        description="Catalogue name (see `lidarsim sensors`), path to a datasheet file, or an "
                    "inline datasheet mapping.")
    pattern_options: dict[str, Any] = Field(
        default_factory=dict, description="Overrides of the datasheet's scan_pattern.options.")
    beam: BeamConfig | None = Field(
        None, description="Beam divergence sampled with sub-rays; omitted: one ray per pulse "
                          "(the seed paper's model).")
    detection: DetectionConfig | None = Field(
        None, description="Link-budget detection (reflectivity, incidence, range); omitted: "
                          "every hit inside the range gate is detected (the seed paper's "
                          "model).")
    returns: ReturnsConfig | None = Field(
        None, description="Return formation and mode; omitted: the datasheet's.")
    multipath: MultipathConfig | None = Field(
        None, description="Specular bounces and their ghost returns (needs detection); "
                          "omitted: the light stops at the first surface.")
    receiver: ReceiverConfig | None = Field(
        None, description="Receiver dynamic range: saturation and range walk (needs "
                          "detection); omitted: an unlimited linear receiver.")


class MeshConfig(_Strict):
    """Where a target's triangles come from: a file, or a registered procedural model."""

    path: Path | None = Field(None, description="Mesh file (STL, OBJ, PLY, GLB, ...).")
    model: str | None = Field(None, description="Registered target model, e.g. 'envisat'.")
    options: dict[str, Any] = Field(default_factory=dict, description="Model options.")
    scale: float = Field(1.0, gt=0, description="Factor applied to file coordinates.")

    @model_validator(mode="after")
    def _one_source(self) -> "MeshConfig":
        if (self.path is None) == (self.model is None):
            raise ValueError("give exactly one of 'path' or 'model'")
        if self.path is not None and self.options:
            raise ValueError("'options' apply to a 'model', not to a mesh file")
        return self


class TargetConfig(_Posed):
    """One target: a labelled mesh and its pose or trajectory."""

    name: str = Field(min_length=1, description="Label written into the point record.")
    mesh: MeshConfig
    materials: dict[str, str | dict[str, Any]] = Field(
        default_factory=dict,
        description="Part name → material: a material name (built-in or from the scenario's "
                    "'materials') or an inline mapping of material fields; key '*' sets "
                    "every part not named. Unnamed parts keep the mesh's own materials "
                    "(Envisat's defaults, mesh-file colours) or 'default'.")


class ScanConfig(_Strict):
    """Timing of the scan: one frame, or a sequence of frames."""

    duration_s: float = Field(gt=0, description="Integration time of one frame (s).")
    start_s: float = Field(0.0, ge=0, description="Start of frame 0 after the epoch (s).")
    frames: int = Field(1, ge=1, description="Number of frames.")
    frame_period_s: float | None = Field(
        None, gt=0, description="Time between frame starts (s); default: duration_s.")
    frame_rate_hz: float | None = Field(
        None, gt=0, description="Frames per second, instead of frame_period_s (Hz).")
    sequence_duration_s: float | None = Field(
        None, gt=0, description="Instead of frames: simulate every frame that starts within "
                                "this time after start_s (s).")
    motion: Literal["per_ray", "frozen"] = Field(
        "per_ray", description="'per_ray': every ray sees the poses at its own timestamp "
                               "(motion distortion); 'frozen': poses at frame start.")
    body_frame_truth: bool = Field(
        False, description="Add columns x_body, y_body, z_body: each noiseless point in its "
                           "target's body frame at its own timestamp (the mesh's frame).")

    @field_validator("frames")
    @classmethod
    def _frames_within_budget(cls, value: int) -> int:
        _check_frame_count(value, "frames")
        return value

    @model_validator(mode="after")
    def _sequence_timing(self) -> "ScanConfig":
        if self.frame_period_s is not None and self.frame_rate_hz is not None:
            raise ValueError("give either frame_period_s or frame_rate_hz, not both")
        if self.sequence_duration_s is not None:
            # frames whose start lies in [start_s, start_s + sequence_duration_s), counted
            # in floating point first: the ratio of two valid times can be astronomical
            ratio = self.sequence_duration_s / self.period_s
            _check_frame_count(ratio, "sequence_duration_s / frame period")
            count = max(1, math.ceil(ratio - 1e-9))
            if "frames" in self.model_fields_set and self.frames != count:
                raise ValueError(f"frames ({self.frames}) disagrees with sequence_duration_s "
                                 f"({self.sequence_duration_s:g} s = {count} frames); give one")
            self.frames = count
        if self.frames > 1 and self.duration_s > self.period_s * (1 + 1e-9):
            raise ValueError(f"duration_s ({self.duration_s:g} s) exceeds the frame period "
                             f"({self.period_s:g} s): frames would overlap")
        return self

    @property
    def period_s(self) -> float:
        """Time between frame starts (s)."""
        if self.frame_rate_hz is not None:
            return 1.0 / self.frame_rate_hz
        return self.frame_period_s or self.duration_s

    def frame_interval(self, frame: int) -> tuple[float, float]:
        """``(t_start, t_stop)`` of ``frame`` in seconds from the epoch."""
        t0 = self.start_s + frame * self.period_s
        return t0, t0 + self.duration_s


def _check_frame_count(frames: float, what: str) -> None:
    # a ValueError, so pydantic reports it with the field like any other range error
    bound = limit("frames")
    if not frames <= bound:
        raise ValueError(f"{what} gives {frames:.6g} frames, over the limit of {bound:,.0f} "
                         f"(set {LIMITS['frames'].env} to raise it)")


#: Sensor fields of the measurement model that are absent (None) in the seed paper's model.
_REALISM_SENSOR_FIELDS = ("beam", "detection", "returns", "multipath", "receiver")


#: Top-level blocks added later, left out of dumps when unset (see ``Scenario``).
_LATER_BLOCKS = ("earth",)
#: Top-level fields added later, left out of dumps at their default (see ``Scenario``).
_LATER_DEFAULTS = {"normals": "inverse_cdf"}


class Scenario(_Strict):
    """A complete simulation set-up."""

    seed: int = Field(0, ge=0, le=MAX_SEED,
                      description="Seed of every random number (noise), 0 to 2^64 - 1.")
    sensor: SensorConfig
    targets: list[TargetConfig] = Field(min_length=1)
    scan: ScanConfig
    backend: NamedComponent = Field(default_factory=lambda: NamedComponent(name="auto"),
                                    description="Ray backend; 'auto' = embree if installed, "
                                                "else numpy.")
    noise: list[NamedComponent] | None = Field(
        None, description="Noise chain in order; default: the datasheet's angular and range "
                          "errors; [] for a noiseless run.")
    normals: Literal["inverse_cdf", "ziggurat"] = Field(
        "inverse_cdf", description="How the noise models' normal numbers are drawn from their "
                                   "random streams: 'inverse_cdf' (the seed paper's stream, "
                                   "the default) or 'ziggurat' (Marsaglia & Tsang's method on "
                                   "the same counters: exact, other numbers, cheaper).")
    sun: SunConfig | None = Field(
        None, description="The Sun: shadows, solar background false alarms and blinding "
                          "(needs sensor.detection); omitted: a dark sky.")
    earth: EarthConfig | None = Field(
        None, description="The Earth as a background source behind the target, from the orbit "
                          "and epoch of sun.orbit; omitted: no Earth.")
    chunk_rays: int = Field(131072, ge=1, description="Rays processed per chunk (memory bound).")
    materials: dict[str, dict[str, Any]] = Field(
        default_factory=dict, description="Your own named materials (name → material fields: "
                                          "diffuse_reflectivity, specular_reflectance, ...), "
                                          "usable in targets[].materials.")

    _source: Path | None = PrivateAttr(None)

    @field_validator("backend", mode="before")
    @classmethod
    def _backend_shorthand(cls, value: Any) -> Any:
        return {"name": value} if isinstance(value, str) else value

    @field_validator("noise", mode="before")
    @classmethod
    def _noise_shorthand(cls, value: Any) -> Any:
        if isinstance(value, list):
            return [{"name": v} if isinstance(v, str) else v for v in value]
        return value

    @model_validator(mode="after")
    def _unique_target_names(self) -> "Scenario":
        names = [t.name for t in self.targets]
        dup = {n for n in names if names.count(n) > 1}
        if dup:
            raise ValueError(f"target names must be unique; repeated: {sorted(dup)}")
        return self

    @model_serializer(mode="wrap")
    def _drop_unset_blocks(self, handler: Any) -> dict[str, Any]:
        # blocks added after scenarios were first written out stay out of every dump when
        # unset, so copies, hashes and dataset identities of older scenarios keep their bytes
        data = handler(self)
        for key in _LATER_BLOCKS:
            if key in data and data[key] is None:
                del data[key]
        for key, default in _LATER_DEFAULTS.items():
            if key in data and data[key] == default:
                del data[key]
        return data

    @property
    def source(self) -> str:
        """The file this scenario came from, or ``"<scenario>"``."""
        return str(self._source) if self._source else "<scenario>"

    @property
    def base_dir(self) -> Path:
        """Directory relative paths are resolved against."""
        return self._source.parent if self._source else Path.cwd()

    def resolve(self, path: Path) -> Path:
        """``path`` made absolute against :attr:`base_dir`."""
        return path if path.is_absolute() else self.base_dir / path

    def config_hash(self) -> str:
        """SHA-256 of the canonical JSON of the validated scenario (first 16 hex digits).

        The sensor-realism fields (``sensor.beam``/``detection``/``returns``, ``materials``)
        enter the JSON only when set, so scenarios written before they existed keep their
        hash (and their datasets can be resumed).
        """
        data = self.model_dump(mode="json")
        for key in _REALISM_SENSOR_FIELDS:
            if data["sensor"].get(key) is None:
                data["sensor"].pop(key, None)
        for target in data["targets"]:
            if not target.get("materials"):
                target.pop("materials", None)
        if not data.get("materials"):
            data.pop("materials", None)
        for key in ("sun", "earth"):
            if data.get(key) is None:
                data.pop(key, None)
        canon = json.dumps(data, sort_keys=True, separators=(",", ":"))
        return hashlib.sha256(canon.encode("utf-8")).hexdigest()[:16]

    def with_updates(self, **changes: Any) -> "Scenario":
        """A validated copy with top-level fields replaced (keeps the source file)."""
        data = self.model_dump()
        data.update(changes)
        new = validate_model(type(self), data, source=self.source)  # one line, not a raw error
        new._source = self._source
        return new
