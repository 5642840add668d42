"""Target symmetries: which poses look the same, so that the metrics score the closest one.

A symmetric target (a cylinder, a box with two identical faces, a four-fold bus) shows the
same surface in several attitudes, and no estimator can tell them apart from points alone. A
symmetry is a rotation of the body about an axis through a centre that maps the mesh onto
itself: ``x ↦ S (x − c) + c`` with ``S`` a turn of ``360°/order`` about ``axis`` (body frame),
or any angle for ``order: inf`` (an axisymmetric body). The declared symmetries generate a
group ``G`` of body transforms; a true pose ``T`` (body → sensor) is then indistinguishable
from every ``T ∘ g``, ``g ∈ G``, and :func:`closest_equivalent` picks the one closest in
attitude to the estimate (ties, within 1e-9 rad, go to the smaller translation error).
"""

from __future__ import annotations

import math
import re
from dataclasses import dataclass
from typing import Iterable, Literal

import numpy as np
from pydantic import BaseModel, ConfigDict, Field, ValidationError, field_validator

from ..base.errors import ConfigError
from ..base.validation import first_validation_error

#: Most elements a finite symmetry group may have (the icosahedral group has 60).
MAX_GROUP_SIZE = 240
_AXES = {"x": (1.0, 0.0, 0.0), "y": (0.0, 1.0, 0.0), "z": (0.0, 0.0, 1.0)}


class Symmetry(BaseModel):
    """One rotational symmetry of a target, in its body frame."""

    model_config = ConfigDict(extra="forbid", frozen=True, allow_inf_nan=False)

    axis: tuple[float, float, float] = Field(description="Axis direction (body frame).")
    order: int | Literal["inf"] = Field(
        description="n for an n-fold symmetry (turns of 360°/n), 'inf' for an axisymmetric body.")
    centre_m: tuple[float, float, float] = Field(
        (0.0, 0.0, 0.0), description="A point of the axis, body frame (m).")

    @field_validator("axis")
    @classmethod
    def _unit(cls, value: tuple[float, float, float]) -> tuple[float, float, float]:
        norm = math.sqrt(sum(v * v for v in value))
        if norm == 0:
            raise ValueError("the axis must not be zero")
        return tuple(v / norm for v in value)  # type: ignore[return-value]

    @field_validator("order")
    @classmethod
    def _order(cls, value: int | str) -> int | str:
        if value != "inf" and value < 2:
            raise ValueError("order must be at least 2 (or 'inf')")
        return value

    def label(self) -> str:
        """Compact text form, the one :func:`parse_symmetry` reads."""
        axis = ",".join(f"{v:g}" for v in self.axis)
        centre = "" if not any(self.centre_m) else "@" + ",".join(f"{v:g}" for v in self.centre_m)
        return f"{axis}:{self.order}{centre}"


def _vector(text: str, what: str, spec: str) -> tuple[float, float, float]:
    if text.lower() in _AXES:
        return _AXES[text.lower()]
    try:
        values = tuple(float(v) for v in text.split(","))
    except ValueError:
        values = ()
    if len(values) != 3 or not all(math.isfinite(v) for v in values):
        raise ConfigError(f"symmetry '{spec}': {what} must be x, y, z or three numbers 'a,b,c'",
                          field="--symmetry")
    return values  # type: ignore[return-value]


def parse_symmetry(spec: str) -> tuple[str | None, Symmetry]:
    """Parse ``[TARGET=]AXIS:ORDER[@CENTRE]``, e.g. ``z:4``, ``envisat=0,0,1:inf@0,0,1.5``.

    Returns
    -------
    target, symmetry
        ``target`` is ``None`` when the spec names none (it then applies to the evaluated
        target).
    """
    match = re.fullmatch(r"\s*(?:([^=\s]+)=)?([^:@]+):([^@]+)(?:@(.+))?\s*", spec)
    if not match:
        raise ConfigError(f"symmetry '{spec}': expected [TARGET=]AXIS:ORDER[@CX,CY,CZ], e.g. "
                          "'z:4' or 'x:inf'", field="--symmetry")
    target, axis, order, centre = match.groups()
    order_value: int | str = order.strip().lower()
    if order_value != "inf":
        try:
            order_value = int(order_value)
        except ValueError:
            raise ConfigError(f"symmetry '{spec}': order must be an integer ≥ 2 or 'inf'",
                              field="--symmetry") from None
    data = {"axis": _vector(axis.strip(), "the axis", spec), "order": order_value,
            "centre_m": _vector(centre.strip(), "the centre", spec) if centre else (0, 0, 0)}
    try:
        return target, Symmetry(**data)
    except ValidationError as exc:
        _, message = first_validation_error(exc)
        raise ConfigError(f"symmetry '{spec}': {message}", field="--symmetry") from None


def axis_rotation(axis: np.ndarray, angle: float) -> np.ndarray:
    """3×3 rotation by ``angle`` (rad) about the unit ``axis`` (Rodrigues)."""
    k = np.array([[0, -axis[2], axis[1]], [axis[2], 0, -axis[0]], [-axis[1], axis[0], 0]])
    return np.cos(angle) * np.eye(3) + np.sin(angle) * k + (1 - np.cos(angle)) * np.outer(axis, axis)


def turn_about(rotation: np.ndarray, centre: np.ndarray) -> np.ndarray:
    """4×4 transform ``x ↦ R (x − c) + c``."""
    out = np.eye(4)
    out[:3, :3] = rotation
    out[:3, 3] = centre - rotation @ centre
    return out


@dataclass(frozen=True)
class SymmetryGroup:
    """The body transforms that leave a target unchanged.

    Attributes
    ----------
    finite
        (G, 4, 4) transforms generated by the finite symmetries (the identity first).
    continuous
        The axisymmetric symmetry, if any (at most one).
    """

    finite: np.ndarray
    continuous: Symmetry | None = None

    @classmethod
    def trivial(cls) -> "SymmetryGroup":
        """No symmetry: the identity only."""
        return cls(np.eye(4)[None])

    @classmethod
    def from_symmetries(cls, symmetries: Iterable[Symmetry]) -> "SymmetryGroup":
        """Close the declared symmetries into a group.

        Raises
        ------
        ConfigError
            More than one axisymmetric symmetry (the body would be a sphere: its attitude is
            not defined), or a finite group larger than :data:`MAX_GROUP_SIZE` (the
            generators are not a symmetry of any rigid body).
        """
        symmetries = list(symmetries)
        continuous = [s for s in symmetries if s.order == "inf"]
        if len(continuous) > 1:
            raise ConfigError("at most one axisymmetric ('inf') symmetry per target",
                              field="--symmetry")
        generators = [turn_about(axis_rotation(np.asarray(s.axis), 2 * np.pi / int(s.order)),
                             np.asarray(s.centre_m, dtype=np.float64))
                      for s in symmetries if s.order != "inf"]
        elements = [np.eye(4)]
        frontier = [np.eye(4)]
        while frontier:
            new = []
            for element in frontier:
                for gen in generators:
                    candidate = gen @ element
                    if not any(np.allclose(candidate, e, atol=1e-9) for e in elements):
                        elements.append(candidate)
                        new.append(candidate)
                        if len(elements) > MAX_GROUP_SIZE:
                            raise ConfigError(
                                f"the declared symmetries generate more than {MAX_GROUP_SIZE} "
                                "poses: they are not the symmetries of a rigid body",
                                field="--symmetry")
            frontier = new
        return cls(np.stack(elements), continuous[0] if continuous else None)

    @property
    def size(self) -> float:
        """Number of equivalent poses (``inf`` with an axisymmetric symmetry)."""
        return math.inf if self.continuous is not None else len(self.finite)


def _rotation_angle(a: np.ndarray, b: np.ndarray) -> float:
    cos = (np.trace(a.T @ b) - 1.0) / 2.0
    return float(np.arccos(np.clip(cos, -1.0, 1.0)))


def closest_equivalent(truth: np.ndarray, estimate: np.ndarray,
                       group: SymmetryGroup) -> np.ndarray:
    """The pose equivalent to ``truth`` under ``group`` that is closest to ``estimate``.

    Parameters
    ----------
    truth, estimate
        4×4 transforms body → sensor.
    group
        The target's symmetries.

    Returns
    -------
    numpy.ndarray
        ``truth @ g`` for the ``g`` of the group with the smallest rotation angle to
        ``estimate`` (ties within 1e-9 rad: the smaller translation error). With an
        axisymmetric symmetry about unit axis ``a``, the best turn ``θ`` about it maximises
        ``trace(M R_a(θ))``, ``M = R_g R_estᵀ R_true``: ``θ = atan2(trace(M [a]ₓ),
        trace(M) − aᵀ M a)``.
    """
    if group.continuous is None and len(group.finite) == 1:
        return truth
    best, best_key = truth, (math.inf, math.inf)
    r_est = estimate[:3, :3]
    for g in group.finite:
        candidate = truth @ g
        if group.continuous is not None:
            axis = np.asarray(group.continuous.axis)
            centre = np.asarray(group.continuous.centre_m, dtype=np.float64)
            m = g[:3, :3] @ r_est.T @ truth[:3, :3]
            k = np.array([[0, -axis[2], axis[1]], [axis[2], 0, -axis[0]],
                          [-axis[1], axis[0], 0]])
            theta = math.atan2(np.trace(m @ k), np.trace(m) - axis @ m @ axis)
            candidate = truth @ turn_about(axis_rotation(axis, theta), centre) @ g
        angle = _rotation_angle(candidate[:3, :3], r_est)
        shift = float(np.linalg.norm(candidate[:3, 3] - estimate[:3, 3]))
        if angle < best_key[0] - 1e-9 or (abs(angle - best_key[0]) <= 1e-9 and
                                          shift < best_key[1]):
            best, best_key = candidate, (angle, shift)
    return best
