"""Built-in plugins: torque-free tumbling rigid bodies (``kind: tumbling`` and
``kind: torque_free``).

Both describe a body whose centre of mass stays at ``position_m`` (scene frame) while it turns
freely in inertial space. ``centre_of_mass_m`` is that point in body coordinates (the rotation
is about it), so the body→scene pose is ``x_scene = R(t) · (x_body - centre_of_mass_m) +
position_m``. ``euler_deg`` / ``quaternion_xyzw`` give ``R`` at ``t_ref_s``.

``tumbling`` — closed-form axisymmetric motion (spin plus nutation)
    ``R(t) = Rot(h, φ̇ τ) · R0 · Rot(s, ψ̇ τ)`` with ``τ = t - t_ref_s``: the body spins at
    ``spin_rate_deg_s`` (ψ̇) about its symmetry axis ``s`` (``symmetry_axis``, body frame),
    and that axis cones about the fixed angular-momentum direction ``h``
    (``angular_momentum_axis``, scene frame at ``t_ref_s``) at ``precession_rate_deg_s`` (φ̇).
    The nutation angle θ (the cone's half-angle) is the angle between ``h`` and ``R0 · s``: set
    it through the initial rotation. This is the exact torque-free motion of an axisymmetric
    body with axial/transverse inertia ratio ``k = φ̇ cos θ / (φ̇ cos θ + ψ̇)``, which must lie
    in (0, 2] for a real body (checked when θ > 0).
``torque_free`` — Euler's equations for any inertia tensor
    ``I ω̇ = -ω × (I ω)`` and ``q̇ = ½ q ⊗ ω`` integrated with SciPy ``solve_ivp`` (DOP853,
    rtol 1e-11, dense output), from ``angular_velocity_deg_s`` at ``t_ref_s``. The solution is
    integrated on demand in fixed 120 s pieces, cached (thread-safe), and evaluated vectorised
    at the ray times. Triaxial bodies show
    the full polhode motion (and the intermediate-axis instability).

Rotating scene frame: with ``orbit`` given (``altitude_km``, ``mean_motion_rad_s`` or
``period_s``) the scene is the target's LVLH frame (see :mod:`.orbit`), which turns at the mean
motion ``n`` about +z (H-bar) relative to inertial space; the rates above are then inertial
(as measured, e.g. Envisat's 2.67 °/s) and the pose is ``Rot(z, -n τ) · R_inertial(t)``. The
frames coincide at ``t_ref_s``.

YAML (Envisat in 2013, flat spin about the orbit anti-normal; the body +Y axis as spin axis is
an estimate)::

    trajectory:
      kind: tumbling
      euler_deg: [-90, 0, 0]           # body +Y → scene -z (anti-normal)
      symmetry_axis: [0, 1, 0]
      angular_momentum_axis: [0, 0, -1]
      spin_rate_deg_s: 2.67
      orbit: {altitude_km: 780}

    trajectory:
      kind: torque_free
      inertia_kg_m2: [17000, 124000, 129000]   # principal moments, body axes (illustrative)
      angular_velocity_deg_s: [0.5, 0.0, 3.0]  # body frame at t_ref_s
"""

from __future__ import annotations

import math
import threading
from abc import abstractmethod
from typing import Any, Literal

import numpy as np
from pydantic import ConfigDict, Field, field_validator, model_validator
from scipy.spatial.transform import Rotation

from ..base.limits import check, size_text
from ..geometry.poses import Poses
from ..geometry.posing import PoseMatrices, RotationChain, quat_matrices, quat_multiply
from ..hookspecs import hookimpl
from ..scenario.pose import PoseConfig
from .base import Trajectory
from .orbit import OrbitConfig, lvlh_from_inertial

Vec3 = tuple[float, float, float]


def _unit(v: Any, name: str) -> np.ndarray:
    v = np.asarray(v, dtype=np.float64)
    norm = np.linalg.norm(v)
    if norm < 1e-12:
        raise ValueError(f"{name} must be a non-zero vector")
    return v / norm


class RigidBodyOptions(PoseConfig):
    """Options shared by the tumbling trajectories."""

    model_config = ConfigDict(allow_inf_nan=False)

    centre_of_mass_m: Vec3 = Field(
        (0.0, 0.0, 0.0), description="Centre of mass in body coordinates (m); the body turns "
                                     "about it and it stays at position_m.")
    t_ref_s: float = Field(0.0, description="Time at which the rotation equals euler_deg / "
                                            "quaternion_xyzw (s from the epoch).")
    orbit: OrbitConfig | None = Field(
        None, description="If given, the scene is the target's rotating LVLH frame and the "
                          "rates are inertial.")


class _RigidBodyTrajectory(Trajectory):
    """Common pose assembly: inertial rotation → scene rotation → pose about the CoM."""

    options: RigidBodyOptions

    def __init__(self, options: RigidBodyOptions | None = None) -> None:
        super().__init__(options)
        self._r0 = self.options.rotation()
        self._p = np.asarray(self.options.position_m, dtype=np.float64)
        self._com = np.asarray(self.options.centre_of_mass_m, dtype=np.float64)

    @abstractmethod
    def inertial_rotations(self, tau: np.ndarray) -> Rotation:
        """Body→inertial rotations at ``tau`` seconds after ``t_ref_s``."""

    def poses_at(self, t: np.ndarray) -> Poses:
        tau = np.atleast_1d(np.asarray(t, dtype=np.float64)) - self.options.t_ref_s
        rotation = self.inertial_rotations(tau)
        if self.options.orbit is not None:
            rotation = lvlh_from_inertial(self.options.orbit.mean_motion, tau) * rotation
        return Poses(self._p - rotation.apply(self._com), rotation)

    @abstractmethod
    def scene_matrices(self, tau: np.ndarray) -> np.ndarray:
        """(N, 3, 3) body→scene rotation matrices at ``tau`` seconds after ``t_ref_s`` (the
        rotations of :meth:`poses_at`, without SciPy)."""

    def pose_matrices(self, t: np.ndarray) -> PoseMatrices:
        tau = np.atleast_1d(np.asarray(t, dtype=np.float64)) - self.options.t_ref_s
        matrix = self.scene_matrices(tau)
        if not self._com.any():  # p - R·0 is p, bit for bit: one position for all
            return PoseMatrices(self._p[None, :], matrix)
        c = self._com
        turned = matrix[:, :, 0] * c[0] + matrix[:, :, 1] * c[1] + matrix[:, :, 2] * c[2]
        return PoseMatrices(self._p - turned, matrix)

    def _lvlh_link(self) -> list[tuple[np.ndarray, float]]:
        """The LVLH frame's turn relative to inertial space, as a chain link (or none)."""
        orbit = self.options.orbit
        return [] if orbit is None else [(np.array([0.0, 0.0, 1.0]), -orbit.mean_motion)]


class TumblingOptions(RigidBodyOptions):
    """Closed-form axisymmetric torque-free motion: spin plus precession (nutation cone)."""

    symmetry_axis: Vec3 = Field((0.0, 0.0, 1.0),
                                description="Body axis of symmetry, the spin axis (body frame).")
    angular_momentum_axis: Vec3 = Field(
        (0.0, 0.0, 1.0), description="Direction of the angular momentum, fixed in inertial "
                                     "space (scene frame at t_ref_s).")
    spin_rate_deg_s: float = Field(0.0, description="Spin rate ψ̇ about the symmetry axis "
                                                    "(deg/s, right-handed).")
    precession_rate_deg_s: float = Field(
        0.0, description="Precession rate φ̇ of the symmetry axis about the angular momentum "
                         "(deg/s).")

    @field_validator("symmetry_axis", "angular_momentum_axis")
    @classmethod
    def _nonzero(cls, value: Vec3, info: Any) -> Vec3:
        _unit(value, info.field_name)
        return value

    @model_validator(mode="after")
    def _physical(self) -> "TumblingOptions":
        theta = self.nutation_rad
        if theta < 1e-9 or abs(math.pi - theta) < 1e-9 or \
                self.spin_rate_deg_s == self.precession_rate_deg_s == 0.0:
            return self
        k = self.inertia_ratio
        if k is None and abs(math.cos(theta)) < 1e-9:
            return self  # rotation about a transverse axis (θ = 90°, no spin): any body
        if k is None or not 0.0 < k <= 2.0 + 1e-9:
            raise ValueError(
                f"with a {math.degrees(theta):.3g}° nutation these spin and precession rates are "
                "not the torque-free motion of any rigid axisymmetric body (they imply "
                f"I_axial/I_transverse = {'undefined' if k is None else f'{k:.3g}'}, which "
                "must lie in (0, 2]); set precession_rate_deg_s, or align the symmetry axis "
                "with angular_momentum_axis for a flat spin")
        return self

    @property
    def nutation_rad(self) -> float:
        """Nutation angle θ between the angular momentum and the symmetry axis (rad)."""
        s = self.rotation().apply(_unit(self.symmetry_axis, "symmetry_axis"))
        h = _unit(self.angular_momentum_axis, "angular_momentum_axis")
        return float(np.arccos(np.clip(np.dot(s, h), -1.0, 1.0)))

    @property
    def inertia_ratio(self) -> float | None:
        """Axial/transverse inertia ratio implied by the rates and nutation (None if undefined)."""
        axial_rate = self.precession_rate_deg_s * math.cos(self.nutation_rad) + \
            self.spin_rate_deg_s
        if abs(axial_rate) < 1e-12:
            return None
        return self.precession_rate_deg_s * math.cos(self.nutation_rad) / axial_rate


class TumblingTrajectory(_RigidBodyTrajectory):
    """Torque-free axisymmetric body: spin about its axis, precession about the momentum."""

    name = "tumbling"
    Options = TumblingOptions
    options: TumblingOptions

    def __init__(self, options: TumblingOptions | None = None) -> None:
        super().__init__(options)
        opts = self.options
        self._h = _unit(opts.angular_momentum_axis, "angular_momentum_axis")
        self._s = _unit(opts.symmetry_axis, "symmetry_axis")
        self._phi_dot = math.radians(opts.precession_rate_deg_s)
        self._psi_dot = math.radians(opts.spin_rate_deg_s)

        self._chain = RotationChain.build(*self._lvlh_link(), (self._h, self._phi_dot),
                                          self._r0, (self._s, self._psi_dot))

    def scene_matrices(self, tau: np.ndarray) -> np.ndarray:
        return self._chain.matrices(tau)

    def motion_rates(self, t0: float, t1: float) -> tuple[float, float]:
        """The chain's angular speed bound; the origin ``p - R·c`` moves at most that times
        ``|c|`` (``c`` the centre of mass in the body frame)."""
        rate = self._chain.rate_bound
        return rate, rate * float(np.linalg.norm(self._com))

    def angular_velocity_inertial(self, t: np.ndarray) -> np.ndarray:
        """(N, 3) inertial angular velocity ``φ̇ h + ψ̇ R(t) s`` (rad/s)."""
        tau = np.atleast_1d(np.asarray(t, dtype=np.float64)) - self.options.t_ref_s
        return self._phi_dot * self._h + self._psi_dot * self.inertial_rotations(tau).apply(
            self._s)

    def inertial_rotations(self, tau: np.ndarray) -> Rotation:
        precession = Rotation.from_rotvec(np.outer(self._phi_dot * tau, self._h))
        spin = Rotation.from_rotvec(np.outer(self._psi_dot * tau, self._s))
        return precession * self._r0 * spin


class TorqueFreeOptions(RigidBodyOptions):
    """A rigid body with any inertia tensor, integrated with Euler's equations."""

    inertia_kg_m2: tuple[float, float, float] | tuple[Vec3, Vec3, Vec3] = Field(
        description="Principal moments [Ixx, Iyy, Izz] about the body axes, or the full "
                    "symmetric 3×3 tensor (kg·m², about the centre of mass).")
    angular_velocity_deg_s: Vec3 = Field(
        description="Angular velocity at t_ref_s (deg/s).")
    angular_velocity_frame: Literal["body", "scene"] = Field(
        "body", description="Frame of angular_velocity_deg_s at t_ref_s.")

    @field_validator("inertia_kg_m2")
    @classmethod
    def _physical_inertia(cls, value: Any) -> Any:
        tensor = inertia_tensor(value)
        if not np.allclose(tensor, tensor.T, rtol=1e-9, atol=0.0):
            raise ValueError("the inertia tensor must be symmetric")
        moments = np.linalg.eigvalsh(tensor)
        if moments[0] <= 0:
            raise ValueError("the inertia tensor must be positive definite")
        if moments[2] > moments[0] + moments[1] + 1e-9 * moments[2]:
            raise ValueError(f"principal moments {np.round(moments, 6).tolist()} violate the "
                             "triangle inequality (largest ≤ sum of the other two) of a real "
                             "rigid body")
        return value


def inertia_tensor(value: Any) -> np.ndarray:
    """A 3×3 tensor from principal moments (3,) or a full tensor (3, 3)."""
    arr = np.asarray(value, dtype=np.float64)
    return np.diag(arr) if arr.shape == (3,) else arr


class TorqueFreeTrajectory(_RigidBodyTrajectory):
    """Torque-free rigid body with any inertia tensor (Euler's equations, solve_ivp)."""

    name = "torque_free"
    Options = TorqueFreeOptions
    options: TorqueFreeOptions

    def check_span(self, t0: float, t1: float, *, source: Any, field: str) -> None:
        """Refuse a span over which the integration would not end: the body rate never
        exceeds ``sqrt(ωᵀ I ω / I_min)`` (kinetic energy is conserved), and the integrator
        works in pieces from ``t_ref_s``; the angle turned through those pieces bounds its
        work (limit ``integration_rad``)."""
        opts = self.options
        inertia = np.asarray(self._inertia, dtype=np.float64)
        omega = np.radians(np.asarray(opts.angular_velocity_deg_s, dtype=np.float64))
        energy2 = float(omega @ inertia @ omega)
        omega_max = math.sqrt(max(energy2, 0.0) / float(np.linalg.eigvalsh(inertia)[0]))
        piece = self.PIECE_S
        reach = max(abs(t0 - opts.t_ref_s), abs(t1 - opts.t_ref_s))
        pieces = math.floor(reach / piece) + 1 if math.isfinite(reach) else math.inf
        check("integration_rad", omega_max * piece * pieces, source=source,
              field=f"{field}.angular_velocity_deg_s",
              what=f"a body rate up to {math.degrees(omega_max):g} °/s integrated over "
                   f"{size_text(pieces)} × {piece:g} s")

    #: Length of each cached integration piece (s). Pieces cover ``[k·E, (k+1)·E]`` after
    #: ``t_ref_s`` (and the mirror image before it), whatever order times are asked in, so the
    #: result does not depend on chunking or on which pipeline thread asks first.
    PIECE_S = 120.0
    RTOL = 1e-11
    ATOL = 1e-12

    def __init__(self, options: TorqueFreeOptions | None = None) -> None:
        super().__init__(options)
        opts = self.options
        self._inertia = inertia_tensor(opts.inertia_kg_m2)
        self._inertia_inv = np.linalg.inv(self._inertia)
        omega = np.radians(np.asarray(opts.angular_velocity_deg_s, dtype=np.float64))
        if opts.angular_velocity_frame == "scene":
            omega = self._r0.apply(omega, inverse=True)
        state0 = np.concatenate([self._r0.as_quat(), omega])
        # dense solutions of the pieces after (+1) and before (-1) t_ref_s, in order, and the
        # state at the open end of each chain
        self._pieces: dict[int, list[Any]] = {+1: [], -1: []}
        self._ends = {+1: state0, -1: state0}
        self._lock = threading.Lock()

    def _rhs(self, _t: float, y: np.ndarray) -> np.ndarray:
        q, w = y[:4], y[4:]
        qv, qw = q[:3], q[3]
        omega_dot = self._inertia_inv @ -np.cross(w, self._inertia @ w)
        # q̇ = ½ q ⊗ (ω, 0), Hamilton product, scalar-last: body rates turn the body frame
        q_dot_v = 0.5 * (qw * w + np.cross(qv, w))
        q_dot_w = -0.5 * np.dot(qv, w)
        return np.concatenate([q_dot_v, [q_dot_w], omega_dot])

    def _ensure(self, direction: int, count: int) -> list[Any]:
        """The first ``count`` pieces in ``direction``, integrating the missing ones."""
        from scipy.integrate import solve_ivp

        with self._lock:
            pieces = self._pieces[direction]
            while len(pieces) < count:
                k = len(pieces)
                span = (direction * k * self.PIECE_S, direction * (k + 1) * self.PIECE_S)
                sol = solve_ivp(self._rhs, span, self._ends[direction], method="DOP853",
                                rtol=self.RTOL, atol=self.ATOL, dense_output=True)
                if not sol.success:  # pragma: no cover - the smooth ODE does not fail
                    raise RuntimeError(f"Euler-equation integration failed: {sol.message}")
                pieces.append(sol.sol)
                self._ends[direction] = sol.y[:, -1]
            return pieces[:count]

    def states(self, tau: np.ndarray) -> np.ndarray:
        """(N, 7) states ``[qx, qy, qz, qw, ωx, ωy, ωz]`` (body rates, rad/s) at ``tau``
        seconds after ``t_ref_s``."""
        tau = np.atleast_1d(np.asarray(tau, dtype=np.float64))
        out = np.empty((len(tau), 7))
        direction = np.where(tau >= 0, 1, -1)
        index = np.floor(np.abs(tau) / self.PIECE_S).astype(np.int64)
        for sign in (+1, -1):
            mine = direction == sign
            if not mine.any():
                continue
            pieces = self._ensure(sign, int(index[mine].max()) + 1)
            for k in np.unique(index[mine]):
                sel = mine & (index == k)
                out[sel] = pieces[k](tau[sel]).T
        out[:, :4] /= np.linalg.norm(out[:, :4], axis=1, keepdims=True)
        return out

    def angular_momentum_inertial(self, t: np.ndarray) -> np.ndarray:
        """(N, 3) angular momentum ``R I ω`` in inertial axes (kg·m²/s); constant in theory."""
        tau = np.atleast_1d(np.asarray(t, dtype=np.float64)) - self.options.t_ref_s
        y = self.states(tau)
        return Rotation.from_quat(y[:, :4]).apply(y[:, 4:] @ self._inertia.T)

    def inertial_rotations(self, tau: np.ndarray) -> Rotation:
        return Rotation.from_quat(self.states(tau)[:, :4])

    def scene_matrices(self, tau: np.ndarray) -> np.ndarray:
        tau = np.atleast_1d(np.asarray(tau, dtype=np.float64))
        q = self.states(tau)[:, :4]
        parts = (q[:, 0], q[:, 1], q[:, 2], q[:, 3])
        if self.options.orbit is not None:  # Rot(z, -n τ) ⊗ q
            half = 0.5 * (-self.options.orbit.mean_motion * tau)
            s = np.sin(half)
            zero = np.zeros_like(s)
            parts = quat_multiply((zero, zero, s, np.cos(half)), parts)
        return quat_matrices(*parts)


@hookimpl
def lidarsim_register_trajectories(register: Any) -> None:
    """Register the tumbling (closed form) and torque_free (Euler's equations) trajectories."""
    register(TumblingTrajectory)
    register(TorqueFreeTrajectory)
