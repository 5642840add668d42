"""Built-in plugin: poses interpolated between keyframes (``kind: keyframes``).

Positions are interpolated with a cubic spline (``position_interpolation: cubic``, C² smooth,
SciPy ``CubicSpline`` with not-a-knot ends) or piecewise linearly (``linear``); rotations with
SLERP (``rotation_interpolation: slerp``, constant angular velocity between keyframes, SciPy
``Slerp``) or a C² rotation spline (``spline``, SciPy ``RotationSpline``). Both reproduce the
keyframes exactly. Outside the keyframes' time span the first/last pose is held
(``extrapolate: hold``) or the simulation stops with an error (``extrapolate: error``).

Keyframes come inline or from a file (relative paths are resolved against the scenario file)::

    trajectory:
      kind: keyframes
      keyframes:
        - {t_s: 0.0, position_m: [60, 0, 0], euler_deg: [0, 0, 0]}
        - {t_s: 5.0, position_m: [50, 2, 0], quaternion_xyzw: [0, 0, 0.2588190, 0.9659258]}
        - {t_s: 10.0, position_m: [40, 0, 0], euler_deg: [0, 0, 60]}

    trajectory: {kind: keyframes, file: approach.csv, rotation_interpolation: spline}

A keyframe file is YAML/JSON/TOML with the same ``keyframes:`` list, or CSV with a header:
``t_s,x_m,y_m,z_m`` and optionally ``qx,qy,qz,qw`` (scalar-last quaternion) or
``euler_x_deg,euler_y_deg,euler_z_deg`` (extrinsic x, then y, then z, as ``euler_deg``).
Keyframes without rotations may take their rotation from an ``attitude`` law instead (e.g.
``attitude: {mode: look_at, point_m: [0, 0, 0]}``).
"""

from __future__ import annotations

import csv
import io
from pathlib import Path
from typing import Any, Literal, Mapping

import numpy as np
from pydantic import ConfigDict, Field, model_validator
from scipy.spatial.transform import Rotation

from ..base.components import ComponentOptions
from ..base.config_io import read_config_file, read_text_file
from ..base.errors import ConfigError
from ..base.limits import check
from ..base.validation import validate_model
from ..geometry.poses import Poses
from ..geometry.posing import PoseMatrices, quat_matrices, quat_multiply
from ..hookspecs import hookimpl
from ..scenario.pose import PoseConfig
from .attitude import AttitudeConfig
from .base import Trajectory

_CSV_POSITION = ("t_s", "x_m", "y_m", "z_m")
_CSV_QUATERNION = ("qx", "qy", "qz", "qw")
_CSV_EULER = ("euler_x_deg", "euler_y_deg", "euler_z_deg")


class Keyframe(PoseConfig):
    """A pose at a time: ``t_s`` (s from the epoch) plus the pose fields."""

    t_s: float = Field(description="Time of the keyframe (s from the scenario epoch).")

    @property
    def has_rotation(self) -> bool:
        """Whether the keyframe gives a rotation."""
        return self.euler_deg is not None or self.quaternion_xyzw is not None


class _KeyframeFile(ComponentOptions):
    keyframes: list[Keyframe] = Field(min_length=1)


class KeyframeOptions(ComponentOptions):
    """Keyframes (inline or from a file) and how to interpolate between them."""

    model_config = ConfigDict(allow_inf_nan=False)

    keyframes: list[Keyframe] | None = Field(None, min_length=1,
                                             description="Inline keyframes, in time order.")
    file: Path | None = Field(None, description="Keyframe file (CSV, YAML, JSON, TOML).")
    position_interpolation: Literal["cubic", "linear"] = Field(
        "cubic", description="'cubic' (C² spline) or 'linear'.")
    rotation_interpolation: Literal["slerp", "spline"] = Field(
        "slerp", description="'slerp' (piecewise constant rate) or 'spline' (C² rotation "
                             "spline).")
    extrapolate: Literal["hold", "error"] = Field(
        "hold", description="Outside the keyframes: hold the end pose, or fail.")
    attitude: AttitudeConfig | None = Field(
        None, description="Rotation law for keyframes that give positions only.")

    @model_validator(mode="after")
    def _one_source(self) -> "KeyframeOptions":
        if (self.keyframes is None) == (self.file is None):
            raise ValueError("give exactly one of 'keyframes' (a list) or 'file'")
        return self


def _numbers(cells: dict[str, str], cols: tuple[str, ...], path: Path, line: int) -> list[float]:
    out = []
    for col in cols:
        try:
            out.append(float(cells.get(col, "")))
        except ValueError:
            raise ConfigError(f"'{cells.get(col, '')}' is not a number", source=path,
                              field=f"line {line}.{col}") from None
    return out


def _read_csv(path: Path) -> tuple[list[Keyframe], list[int]]:
    """Keyframes of a CSV file and the line number of each."""
    text = read_text_file(path, "keyframe file")
    check("keyframe_rows", text.count("\n"), what="the file's lines", source=path)
    reader = csv.DictReader(io.StringIO(text, newline=""))
    header = [h.strip() for h in (reader.fieldnames or [])]
    missing = [c for c in _CSV_POSITION if c not in header]
    if missing:
        raise ConfigError(f"CSV header lacks column(s) {', '.join(missing)}; expected "
                          f"{','.join(_CSV_POSITION)} and optionally {','.join(_CSV_QUATERNION)} "
                          f"or {','.join(_CSV_EULER)}", source=path, field="header")
    has_q = all(c in header for c in _CSV_QUATERNION)
    has_e = all(c in header for c in _CSV_EULER)
    if has_q and has_e:
        raise ConfigError("CSV has both quaternion and Euler columns; keep one set",
                          source=path, field="header")
    frames: list[Keyframe] = []
    lines: list[int] = []
    for row in reader:
        line = reader.line_num
        cells = {(k or "").strip(): (v or "").strip() for k, v in row.items()}
        t, x, y, z = _numbers(cells, _CSV_POSITION, path, line)
        data: dict[str, Any] = {"t_s": t, "position_m": [x, y, z]}
        if has_q:
            data["quaternion_xyzw"] = _numbers(cells, _CSV_QUATERNION, path, line)
        elif has_e:
            data["euler_deg"] = _numbers(cells, _CSV_EULER, path, line)
        frames.append(validate_model(Keyframe, data, source=path, prefix=f"line {line}"))
        lines.append(line)
    if not frames:
        raise ConfigError("keyframe file has no rows", source=path)
    return frames, lines


def load_keyframe_file(path: str | Path) -> list[Keyframe]:
    """Read keyframes from a CSV, YAML, JSON or TOML file (see the module docstring).

    Raises
    ------
    ConfigError
        One line naming the file and the line or field that is wrong.
    """
    path = Path(path)
    if path.suffix.lower() == ".csv":
        frames, lines = _read_csv(path)
        fields = [f"line {line}.t_s" for line in lines]
    else:
        frames = validate_model(_KeyframeFile, read_config_file(path), source=path).keyframes
        fields = [f"keyframes.{i}.t_s" for i in range(len(frames))]
    check_times([k.t_s for k in frames], source=path, fields=fields)
    return frames


def check_times(times: list[float], *, source: Any, fields: list[str]) -> None:
    """Raise a one-line :class:`ConfigError` unless ``times`` are finite and strictly increasing."""
    for i, t in enumerate(times):
        if not np.isfinite(t):
            raise ConfigError("keyframe time must be a finite number", source=source,
                              field=fields[i])
        if i and t <= times[i - 1]:
            raise ConfigError(f"keyframe times must increase strictly: t_s = {t:g} does not "
                              f"follow the previous keyframe's t_s = {times[i - 1]:g}",
                              source=source, field=fields[i])


class KeyframeTrajectory(Trajectory):
    """Poses interpolated between keyframes (cubic/linear positions, SLERP/spline rotations).

    Parameters
    ----------
    options
        Validated :class:`KeyframeOptions`.
    base_dir
        Directory a relative ``file`` is resolved against (default: the working directory).
    source, field
        Where the options came from, for error messages.
    """

    name = "keyframes"
    Options = KeyframeOptions
    options: KeyframeOptions

    def __init__(self, options: KeyframeOptions | None = None, *, base_dir: Path | None = None,
                 source: str | None = None, field: str = "options") -> None:
        super().__init__(options)
        opts = self.options
        self._where = (source, field)
        if opts.file is not None:
            path = opts.file if opts.file.is_absolute() else (base_dir or Path.cwd()) / opts.file
            frames = load_keyframe_file(path)
        else:
            frames = list(opts.keyframes or [])
            check_times([k.t_s for k in frames], source=source,
                        fields=[f"{field}.keyframes.{i}.t_s" for i in range(len(frames))])
        rotated = [k.has_rotation for k in frames]
        if opts.attitude is not None and any(rotated):
            raise ConfigError("keyframes give rotations, so 'attitude' must be omitted",
                              source=source, field=f"{field}.attitude")
        self._times = np.array([k.t_s for k in frames], dtype=np.float64)
        self._positions = np.array([k.position_m for k in frames], dtype=np.float64)
        self._rotations = Rotation.concatenate([k.rotation() for k in frames])
        self.is_static = len(frames) == 1
        self._slerp: tuple[np.ndarray, np.ndarray, np.ndarray] | None = None
        self._build_interpolators()

    @classmethod
    def from_config(cls, options: Mapping[str, Any] | None, *, source: str | None = None,
                    field: str = "options") -> "KeyframeTrajectory":
        """Validate ``options`` and build the trajectory; a relative ``file`` is resolved
        against the directory of ``source`` when that is a file."""
        opts = validate_model(cls.Options, dict(options or {}), source=source, prefix=field)
        base = Path(source).parent if source and Path(source).is_file() else None
        return cls(opts, base_dir=base, source=source, field=field)

    def _build_interpolators(self) -> None:
        from scipy.interpolate import CubicSpline
        from scipy.spatial.transform import RotationSpline, Slerp

        opts = self.options
        self._position_fn = None
        self._rotation_fn = None
        if len(self._times) < 2:
            return
        if opts.position_interpolation == "cubic":
            self._position_fn = CubicSpline(self._times, self._positions, axis=0)
        else:
            self._position_fn = lambda t: np.column_stack(
                [np.interp(t, self._times, self._positions[:, i]) for i in range(3)])
        if opts.rotation_interpolation == "spline":
            self._rotation_fn = RotationSpline(self._times, self._rotations)
        else:
            self._rotation_fn = Slerp(self._times, self._rotations)

    @property
    def time_span(self) -> tuple[float, float]:
        """First and last keyframe times (s)."""
        return float(self._times[0]), float(self._times[-1])

    def _check_span(self, t: np.ndarray) -> None:
        t0, t1 = self.time_span
        if self.options.extrapolate == "error" and len(t) and (t.min() < t0 or t.max() > t1):
            source, field = self._where
            raise ConfigError(f"keyframes cover t = {t0:g}..{t1:g} s but the scan needs "
                              f"t = {t.min():g}..{t.max():g} s (use extrapolate: hold or add "
                              "keyframes)", source=source, field=f"{field}.extrapolate")

    def poses_at(self, t: np.ndarray) -> Poses:
        t = np.atleast_1d(np.asarray(t, dtype=np.float64))
        self._check_span(t)
        tc = np.clip(t, *self.time_span)
        if self._position_fn is None:
            position = np.repeat(self._positions, len(t), axis=0)
            rotation = Rotation.from_quat(np.repeat(self._rotations.as_quat(), len(t), axis=0))
        else:
            position = np.asarray(self._position_fn(tc), dtype=np.float64).reshape(-1, 3)
            rotation = self._rotation_fn(tc)
        if self.options.attitude is not None:
            rotation = self.options.attitude.rotations(position)
        return Poses(position, rotation)

    def pose_matrices(self, t: np.ndarray) -> PoseMatrices:
        if self._position_fn is not None and self.options.rotation_interpolation == "spline" \
                and self.options.attitude is None:
            return PoseMatrices.from_poses(self.poses_at(t))  # SciPy's rotation spline
        t = np.atleast_1d(np.asarray(t, dtype=np.float64))
        self._check_span(t)
        tc = np.clip(t, *self.time_span)
        if self._position_fn is None:
            position = np.repeat(self._positions, len(t), axis=0)
        else:
            position = np.asarray(self._position_fn(tc), dtype=np.float64).reshape(-1, 3)
        if self.options.attitude is not None:
            return PoseMatrices(position, self.options.attitude.matrices(position))
        if self._position_fn is None:
            return PoseMatrices(position, np.repeat(self._rotations.as_matrix().reshape(1, 3, 3),
                                                    len(t), axis=0))
        return PoseMatrices(position, self._slerp_matrices(tc))

    def motion_rates(self, t0: float, t1: float) -> tuple[float, float] | None:
        """Over the keyframe intervals that ``[t0, t1]`` meets (the pose holds outside the
        keyframes): the largest speed of the positions (linear: each interval's chord over
        its duration; cubic: ``|c| + 2|b| h + 3|a| h²`` per component of the spline's
        ``a τ³ + b τ² + c τ + d`` on an interval of length ``h``) and the largest SLERP rate
        (each interval's rotation angle over its duration), or the attitude law's bound;
        None with the rotation spline."""
        if self._position_fn is None:
            return 0.0, 0.0
        first, last = self.time_span
        lo, hi = max(t0, first), min(t1, last)
        if lo > hi:  # wholly outside the keyframes: the end pose holds
            return 0.0, 0.0
        k0 = max(int(np.searchsorted(self._times, lo, side="right")) - 1, 0)
        k1 = min(int(np.searchsorted(self._times, hi, side="left")), len(self._times) - 1)
        k1 = max(k1, k0 + 1)
        h = np.diff(self._times)[k0:k1]
        if self.options.position_interpolation == "linear":
            chord = np.linalg.norm(np.diff(self._positions, axis=0)[k0:k1], axis=1)
            speed = float((chord / h).max())
        else:
            a, b, c = (np.abs(self._position_fn.c[i, k0:k1]) for i in range(3))
            bound = c + 2.0 * b * h[:, None] + 3.0 * a * (h * h)[:, None]
            speed = float(np.sqrt((bound * bound).sum(axis=1)).max())
        speed *= 1.0 + 1e-9
        if self.options.attitude is not None:
            middle = 0.5 * (t0 + t1)
            position = self.pose_matrices(np.array([min(max(middle, first), last)])).position
            turn = self.options.attitude.rate_bound(position[0], speed,
                                                    max(middle - t0, t1 - middle))
            return None if turn is None else (turn, speed)
        if self.options.rotation_interpolation == "spline":
            return None
        angles = np.linalg.norm((self._rotations[:-1].inv() * self._rotations[1:]).as_rotvec(),
                                axis=1)[k0:k1]
        return float((angles / h).max()) * (1.0 + 1e-9), speed

    def _slerp_matrices(self, t: np.ndarray) -> np.ndarray:
        """SciPy ``Slerp`` in quaternion arithmetic: ``q_k ⊗ exp(α · log(q_k⁻¹ q_k+1))``."""
        if self._slerp is None:
            rotvecs = (self._rotations[:-1].inv() * self._rotations[1:]).as_rotvec()
            self._slerp = (self._rotations.as_quat(), rotvecs, np.diff(self._times))
        quats, rotvecs, dt = self._slerp
        k = np.searchsorted(self._times, t) - 1  # Slerp's choice of interval
        k[k == -1] = 0
        alpha = (t - self._times[k]) / dt[k]
        step = rotvecs[k] * alpha[:, None]
        angle = np.sqrt((step * step).sum(axis=1))
        small = angle <= 1e-3  # SciPy's series for sin(θ/2)/θ near 0
        a2 = angle * angle
        scale = np.where(small, 0.5 - a2 / 48 + a2 * a2 / 3840,
                         np.sin(0.5 * angle) / np.where(small, 1.0, angle))
        q = quats[k]
        x, y, z, w = quat_multiply((q[:, 0], q[:, 1], q[:, 2], q[:, 3]),
                                   (scale * step[:, 0], scale * step[:, 1], scale * step[:, 2],
                                    np.cos(0.5 * angle)))
        return quat_matrices(x, y, z, w)


@hookimpl
def lidarsim_register_trajectories(register: Any) -> None:
    """Register the keyframe trajectory."""
    register(KeyframeTrajectory)
