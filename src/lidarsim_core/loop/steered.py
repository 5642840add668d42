"""A steered body's path: the poses a session was given at its step boundaries, flown as a
keyframe trajectory (linear positions, SLERP rotations: constant velocity and rotation rate
over each step).

The session's poses become a :class:`~lidarsim_core.trajectories.keyframes.KeyframeTrajectory`
twice: during the loop, as :class:`SteeredTrajectory` over the last few keyframes only (a
step's rays never look further back), and in the recorded keyframe file that ``lidarsim
simulate`` replays over all of them. Both interpolate each step from its own two keyframes
with the same arithmetic (NumPy's ``interp`` and the SLERP of the keyframe trajectory choose
their interval by the same search, which the window of three keyframes keeps), so the
replayed frames carry the loop's bits.
"""

from __future__ import annotations

from dataclasses import dataclass, field

import numpy as np
from scipy.spatial.transform import Rotation, Slerp

from ..geometry.poses import Poses
from ..geometry.posing import PoseMatrices
from ..trajectories.keyframes import Keyframe, KeyframeOptions, KeyframeTrajectory

#: The interpolation the loop flies and its keyframe file asks for.
INTERPOLATION = {"position_interpolation": "linear", "rotation_interpolation": "slerp",
                 "extrapolate": "hold"}
_OPTIONS = KeyframeOptions(keyframes=[Keyframe(t_s=0.0)], **INTERPOLATION)
#: Keyframes a step's trajectory holds: the one before the step's start keeps the
#: interval search of the whole recording on the step's first instant.
WINDOW = 3


class SteeredTrajectory(KeyframeTrajectory):
    """The last :data:`WINDOW` keyframes of a steered body as a keyframe trajectory.

    Built without validating options (the session checked every number): the same class,
    interpolators and arithmetic as the keyframe trajectory that replays the recording.

    Parameters
    ----------
    times
        (K,) increasing keyframe times (s), K >= 2.
    positions
        (K, 3) positions (m).
    unit_quaternions
        (K, 4) the quaternions of the rotations ``Rotation.from_quat`` makes of the recorded
        ones (as the keyframe file's reader makes them), taken as they are.
    """

    def __init__(self, times: np.ndarray, positions: np.ndarray,
                 unit_quaternions: np.ndarray) -> None:  # noqa: D107 - on the class
        self.options = _OPTIONS
        self._where = ("<loop session>", "trajectory")
        self._times = times
        self._positions = positions
        # Rotation.concatenate of the keyframes' rotations, without normalising them again
        self._rotations = Rotation(unit_quaternions, normalize=False, copy=False)
        self.is_static = False
        self._slerp = None
        self._slerp_fn: Slerp | None = None
        # the keyframe trajectory's linear interpolation, the same expression
        self._position_fn = lambda t: np.column_stack(
            [np.interp(t, self._times, self._positions[:, i]) for i in range(3)])
        self._memo: tuple[bytes, np.ndarray, Rotation] | None = None

    @property
    def _rotation_fn(self) -> Slerp:  # type: ignore[override]
        # SciPy's Slerp, built on first use (frame metadata), once per step; the per-ray
        # path (_slerp_matrices) reuses its relative rotations, the same expression
        if self._slerp_fn is None:
            self._slerp_fn = Slerp(self._times, self._rotations)
            if self._slerp is None:
                self._slerp = (self._rotations.as_quat(), np.asarray(self._slerp_fn.rotvecs),
                               np.diff(self._times))
        return self._slerp_fn

    def poses_at(self, t: np.ndarray) -> Poses:
        """The keyframe trajectory's poses; the last answer is kept (a step asks for its
        start and end twice: the inside check and the frame metadata)."""
        t = np.atleast_1d(np.asarray(t, dtype=np.float64))
        key = t.tobytes()
        if self._memo is None or self._memo[0] != key:
            poses = super().poses_at(t)
            self._memo = (key, poses.position, poses.rotation)
        return Poses(self._memo[1].copy(), self._memo[2])

    def pose_matrices(self, t: np.ndarray) -> PoseMatrices:
        """The keyframe trajectory's closed form (defined here too, beside ``poses_at``, so
        that the pipeline keeps using it: :func:`~lidarsim_core.trajectories.matrices.has_fast_path`)."""
        return super().pose_matrices(t)


@dataclass
class SteeredPath:
    """Every keyframe a steered body was given: times (s), positions (m) and scalar-last
    quaternions, with the unit quaternions of the rotations made from them."""

    times: list[float] = field(default_factory=list)
    positions: list[np.ndarray] = field(default_factory=list)
    quaternions: list[np.ndarray] = field(default_factory=list)
    unit_quaternions: list[np.ndarray] = field(default_factory=list)

    def add(self, t: float, position: np.ndarray, quaternion_xyzw: np.ndarray) -> None:
        """Append the pose at ``t`` (the rotation is made as the keyframe reader makes it)."""
        q = np.asarray(quaternion_xyzw, dtype=np.float64).copy()
        self.times.append(float(t))
        self.positions.append(np.asarray(position, dtype=np.float64).copy())
        self.quaternions.append(q)
        self.unit_quaternions.append(Rotation.from_quat(q).as_quat())

    def trajectory(self) -> SteeredTrajectory:
        """The trajectory of the newest step: its last :data:`WINDOW` keyframes."""
        lo = max(0, len(self.times) - WINDOW)
        return SteeredTrajectory(np.array(self.times[lo:]), np.array(self.positions[lo:]),
                                 np.array(self.unit_quaternions[lo:]))

    def drop_last(self) -> None:
        """Forget the newest keyframe (a step that failed)."""
        for seq in (self.times, self.positions, self.quaternions, self.unit_quaternions):
            seq.pop()

    def csv_text(self) -> str:
        """The keyframe file (``t_s,x_m,y_m,z_m,qx,qy,qz,qw``; every number as Python's
        shortest repr, which reads back to the same bits)."""
        lines = ["t_s,x_m,y_m,z_m,qx,qy,qz,qw"]
        for t, p, q in zip(self.times, self.positions, self.quaternions):
            lines.append(",".join(repr(float(v)) for v in (t, *p, *q)))
        return "\n".join(lines) + "\n"
