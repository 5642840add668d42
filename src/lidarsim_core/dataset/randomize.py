"""Randomised sequences: distributions in a dataset file, drawn from the dataset's seed.

A ``sequences`` entry may hold ``randomize:``, a mapping of dotted scenario paths (as in
``set:``) to distributions, and ``count:``, the number of sequences drawn from it (``lidarsim
dataset --sequences N`` overrides the count of every randomised entry)::

    sequences:
      - scenario: envisat_training_scene.yaml
        name: tumble                     # sequences tumble_r0000, tumble_r0001, ...
        count: 50
        randomize:
          targets.0.trajectory.quaternion_xyzw: {so3: uniform}
          targets.0.trajectory.position_m:
            vector: [{uniform: [10, 100]}, 0, 0]
          targets.0.trajectory.angular_velocity_deg_s:
            vector: [{normal: [0, 1]}, {normal: [0, 1]}, {normal: [2.67, 0.5], bounds: [0, 6]}]
          sensor.datasheet: {choice: [ouster-os1-64, velodyne-vlp16]}
    seed: 7                              # the dataset's seed: every draw comes from it

========================================  ==================================================
distribution                              value
========================================  ==================================================
``{uniform: [lo, hi]}``                   float, uniform on [lo, hi)
``{normal: [mean, std]}``                 float, Gaussian
``{log_uniform: [lo, hi]}``               float, ``exp`` of uniform on [ln lo, ln hi), lo > 0
``{choice: [a, b, ...], weights: [...]}`` one of the listed values (any YAML value)
``{so3: uniform}``                        ``[x, y, z, w]``: a rotation uniform on SO(3) (the
                                          Haar measure), :meth:`Rotation.random
                                          <scipy.spatial.transform.Rotation.random>`
``{sphere: uniform}``                     ``[x, y, z]``: a unit vector uniform on the sphere
``{vector: [d0, d1, ...]}``               a list whose items are distributions or constants
``{sphere: uniform, radius: d}``          the unit vector times a drawn (or fixed) radius
========================================  ==================================================

``uniform``, ``normal`` and ``log_uniform`` accept ``bounds: [lo, hi]``: values outside are
drawn again (a truncated distribution; at most :data:`MAX_REDRAWS` times, then an error), and
``integer: true`` rounds the value to the nearest integer.

Sequence ``k`` of entry ``i`` draws from its own stream, NumPy's Philox keyed by
``(dataset seed, i, k)``, in the order the paths are written, so a sequence's values do not
depend on how many sequences are drawn, on the other entries, or on the run (rerun, resume,
workers). Unless the entry gives ``seed``/``seeds``, the scenario's noise seed is drawn too.
The drawn values are recorded per sequence in the manifest (``"drawn"``) and become part of the
scenario the sequence simulates, hence of the dataset's identity.
"""

from __future__ import annotations

from typing import Any, Literal, Union

import numpy as np
from pydantic import BaseModel, ConfigDict, Field, model_validator
from scipy.spatial.transform import Rotation


#: Draws of a truncated distribution before giving up.
MAX_REDRAWS = 10_000
#: Largest drawn noise seed (fits a signed 64-bit integer).
DRAWN_SEED_MAX = 2 ** 63 - 1


class _Strict(BaseModel):
    model_config = ConfigDict(extra="forbid", allow_inf_nan=False)


class _Scalar(_Strict):
    bounds: tuple[float, float] | None = Field(None, description="Redraw values outside.")
    integer: bool = Field(False, description="Round to the nearest integer.")

    @model_validator(mode="after")
    def _ordered_bounds(self) -> "_Scalar":
        if self.bounds is not None and not self.bounds[0] <= self.bounds[1]:
            raise ValueError("bounds must be [low, high] with low <= high")
        return self

    def _one(self, rng: np.random.Generator) -> float:
        raise NotImplementedError

    def draw(self, rng: np.random.Generator) -> float | int:
        """One value (redrawn while outside ``bounds``)."""
        for _ in range(MAX_REDRAWS):
            value = self._one(rng)
            if self.integer:
                value = float(np.rint(value))
            if self.bounds is None or self.bounds[0] <= value <= self.bounds[1]:
                return int(value) if self.integer else value
        raise ValueError(f"no value inside bounds {list(self.bounds or ())} after "
                         f"{MAX_REDRAWS} draws")


class Uniform(_Scalar):
    """Uniform on ``[lo, hi)``."""

    uniform: tuple[float, float]

    @model_validator(mode="after")
    def _ordered(self) -> "Uniform":
        if not self.uniform[0] <= self.uniform[1]:
            raise ValueError("uniform must be [low, high] with low <= high")
        return self

    def _one(self, rng: np.random.Generator) -> float:
        return float(rng.uniform(self.uniform[0], self.uniform[1]))


class Normal(_Scalar):
    """Gaussian ``[mean, std]``."""

    normal: tuple[float, float]

    @model_validator(mode="after")
    def _positive_std(self) -> "Normal":
        if self.normal[1] < 0:
            raise ValueError("normal must be [mean, std] with std >= 0")
        return self

    def _one(self, rng: np.random.Generator) -> float:
        return float(rng.normal(self.normal[0], self.normal[1]))


class LogUniform(_Scalar):
    """``exp`` of uniform on ``[ln lo, ln hi)``."""

    log_uniform: tuple[float, float]

    @model_validator(mode="after")
    def _positive(self) -> "LogUniform":
        if not 0 < self.log_uniform[0] <= self.log_uniform[1]:
            raise ValueError("log_uniform must be [low, high] with 0 < low <= high")
        return self

    def _one(self, rng: np.random.Generator) -> float:
        lo, hi = np.log(self.log_uniform[0]), np.log(self.log_uniform[1])
        return float(np.exp(rng.uniform(lo, hi)))


class Choice(_Strict):
    """One of the listed values."""

    choice: list[Any] = Field(min_length=1)
    weights: list[float] | None = None

    @model_validator(mode="after")
    def _weights(self) -> "Choice":
        if self.weights is not None:
            if len(self.weights) != len(self.choice):
                raise ValueError("weights must have one entry per choice")
            if min(self.weights) < 0 or sum(self.weights) <= 0:
                raise ValueError("weights must be >= 0 and not all zero")
        return self

    def draw(self, rng: np.random.Generator) -> Any:
        """One of the values."""
        p = None if self.weights is None else np.asarray(self.weights) / sum(self.weights)
        return self.choice[int(rng.choice(len(self.choice), p=p))]


class SO3(_Strict):
    """A rotation uniform on SO(3), as a scalar-last quaternion."""

    so3: Literal["uniform"]

    def draw(self, rng: np.random.Generator) -> list[float]:
        """``[x, y, z, w]`` with ``w >= 0``."""
        quat = Rotation.random(random_state=rng).as_quat()
        quat = -quat if quat[3] < 0 else quat
        return [float(v) for v in quat]


class Sphere(_Strict):
    """A direction uniform on the unit sphere (times ``radius``)."""

    sphere: Literal["uniform"]
    radius: "Distribution | float" = 1.0

    def draw(self, rng: np.random.Generator) -> list[float]:
        """``[x, y, z]``."""
        while True:
            v = rng.normal(size=3)
            norm = float(np.linalg.norm(v))
            if norm > 1e-12:
                break
        r = self.radius if isinstance(self.radius, (int, float)) else self.radius.draw(rng)
        return [float(c) for c in v / norm * r]


class Vector(_Strict):
    """A list of distributions or constants."""

    vector: list["Distribution | float | int | str | bool | None"] = Field(min_length=1)

    def draw(self, rng: np.random.Generator) -> list[Any]:
        """One value per item, in order."""
        return [item.draw(rng) if isinstance(item, BaseModel) else item  # type: ignore[union-attr]
                for item in self.vector]


Distribution = Union[Uniform, Normal, LogUniform, Choice, SO3, Sphere, Vector]
Sphere.model_rebuild()
Vector.model_rebuild()


def sequence_rng(dataset_seed: int, entry: int, index: int) -> np.random.Generator:
    """The random stream of sequence ``index`` of entry ``entry`` (see the module docstring)."""
    return np.random.Generator(np.random.Philox(key=[dataset_seed, entry * 2 ** 32 + index]))


def draw_values(randomize: dict[str, Distribution], rng: np.random.Generator, *,
                draw_seed: bool) -> dict[str, Any]:
    """Draw every path's value in order (then the noise seed, if ``draw_seed``)."""
    out: dict[str, Any] = {path: dist.draw(rng) for path, dist in randomize.items()}
    if draw_seed:
        out["seed"] = int(rng.integers(0, DRAWN_SEED_MAX, endpoint=True))
    return out
