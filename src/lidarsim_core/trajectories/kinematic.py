"""Built-in plugin: constant linear and angular velocity (``kind: constant_velocity``).

At time ``t`` (s from the scenario epoch), with ``τ = t - t_ref_s``::

    position(t) = position_m + velocity_m_s · τ
    rotation(t) = R0 · exp(τ · ω_body)        (angular_velocity_frame: body, the default)
    rotation(t) = exp(τ · ω_scene) · R0       (angular_velocity_frame: scene)

where ``R0`` is the rotation given by ``euler_deg`` / ``quaternion_xyzw`` (the pose at
``t_ref_s``) and ``ω`` is ``angular_velocity_deg_s`` (deg/s, a rotation vector rate about a
fixed axis). Both frames describe the same motion when ``ω_scene = R0 · ω_body``.

YAML::

    trajectory:
      kind: constant_velocity
      position_m: [40, -2, 0]
      velocity_m_s: [0, 0.5, 0]
      euler_deg: [0, 0, 30]
      angular_velocity_deg_s: [0, 0, 10]
"""

from __future__ import annotations

from typing import Any, Literal

import numpy as np
from pydantic import ConfigDict, Field
from scipy.spatial.transform import Rotation

from ..geometry.poses import Poses
from ..geometry.posing import PoseMatrices, RotationChain
from ..hookspecs import hookimpl
from ..scenario.pose import PoseConfig
from .base import Trajectory


class ConstantVelocityOptions(PoseConfig):
    """Pose at ``t_ref_s`` plus constant linear and angular velocities."""

    model_config = ConfigDict(allow_inf_nan=False)

    velocity_m_s: tuple[float, float, float] = Field(
        (0.0, 0.0, 0.0), description="Linear velocity of the body origin, scene frame (m/s).")
    angular_velocity_deg_s: tuple[float, float, float] = Field(
        (0.0, 0.0, 0.0), description="Angular velocity vector (deg/s).")
    angular_velocity_frame: Literal["body", "scene"] = Field(
        "body", description="Frame of angular_velocity_deg_s: 'body' axes or 'scene' axes.")
    t_ref_s: float = Field(0.0, description="Time at which the pose equals position_m and the "
                                            "given rotation (s from the epoch).")


class ConstantVelocityTrajectory(Trajectory):
    """Constant linear and angular velocity from a reference pose."""

    name = "constant_velocity"
    Options = ConstantVelocityOptions
    options: ConstantVelocityOptions

    def __init__(self, options: ConstantVelocityOptions | None = None) -> None:
        super().__init__(options)
        opts = self.options
        self._p0 = np.asarray(opts.position_m, dtype=np.float64)
        self._v = np.asarray(opts.velocity_m_s, dtype=np.float64)
        self._r0 = opts.rotation()
        self._omega = np.radians(np.asarray(opts.angular_velocity_deg_s, dtype=np.float64))
        self.is_static = not (self._v.any() or self._omega.any())
        rate = float(np.linalg.norm(self._omega))
        spin = (self._omega, rate)
        self._chain = RotationChain.build(self._r0, spin) \
            if opts.angular_velocity_frame == "body" else RotationChain.build(spin, self._r0)

    def pose_matrices(self, t: np.ndarray) -> PoseMatrices:
        tau = np.atleast_1d(np.asarray(t, dtype=np.float64)) - self.options.t_ref_s
        return PoseMatrices(self._p0 + tau[:, None] * self._v, self._chain.matrices(tau))

    def motion_rates(self, t0: float, t1: float) -> tuple[float, float]:
        """``|ω|`` and ``|v|``, constant."""
        return self._chain.rate_bound, float(np.linalg.norm(self._v))

    def poses_at(self, t: np.ndarray) -> Poses:
        tau = np.atleast_1d(np.asarray(t, dtype=np.float64)) - self.options.t_ref_s
        position = self._p0 + tau[:, None] * self._v
        spin = Rotation.from_rotvec(tau[:, None] * self._omega)
        rotation = self._r0 * spin if self.options.angular_velocity_frame == "body" \
            else spin * self._r0
        return Poses(position, rotation)


@hookimpl
def lidarsim_register_trajectories(register: Any) -> None:
    """Register the constant-velocity trajectory."""
    register(ConstantVelocityTrajectory)
