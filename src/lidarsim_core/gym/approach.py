"""``lidarsim/Approach-v0``: steer a chaser to a hold point in front of a tumbling target from
its LiDAR's point clouds.

Each step is one scan interval of a :class:`~lidarsim_core.loop.LoopSession`: the action is
the commanded impulse (``action_mode="delta_v"``, m/s) or constant acceleration
(``"acceleration"``, m/s²) in the target's LVLH frame, the chaser moves by the HCW equations,
and the observation is that interval's point cloud:

``points``
    (``max_points``, 3) float32 measured points, sensor frame (m); clouds with more points
    keep ``max_points`` of them, evenly spaced in emission order; unused rows are zero.
``mask``
    (``max_points``,) int8: 1 for the rows that hold a point.
``range_image`` (with ``range_image=(rows, cols)``)
    float32 range (m, 0 where no return) on a grid of azimuth × elevation over the
    datasheet's field of view, the nearest return per cell.

Reward and termination are functions ``f(info) -> float`` / ``f(info) -> bool`` of the step's
``info`` dictionary (true relative position, velocity, hold point, action, step); the
defaults reward closing on the hold point and terminate there (within ``hold_tolerance_m``
and ``hold_speed_m_s``) or on a collision course (closer than ``keep_out_m``). ``reset(seed=)``
draws the start dispersion and the noise seed from the environment's generator: one seed,
one episode.
"""

from __future__ import annotations

from typing import Any, Callable, Mapping

import gymnasium
import numpy as np
from gymnasium import spaces

from ..loop.session import LoopSession, StepResult
from ..pipeline.simulation import Simulation
from ..scenario.load import as_scenario
from ..loop.scenarios import vbar_approach

Info = dict[str, Any]


def default_reward(info: Info) -> float:
    """Progress toward the hold point (m closed this step) minus the Δv spent (m/s, ×10)."""
    return float(info["distance_before_m"] - info["distance_m"]
                 - 10.0 * np.linalg.norm(info["delta_v_m_s"]))


def default_termination(info: Info) -> bool:
    """At the hold point and slow, or inside the keep-out sphere."""
    return bool((info["distance_m"] < info["hold_tolerance_m"]
                 and info["speed_m_s"] < info["hold_speed_m_s"])
                or info["range_m"] < info["keep_out_m"])


class ApproachEnv(gymnasium.Env):
    """A closed-loop approach from LiDAR point clouds (see the module docstring).

    Parameters
    ----------
    scenario
        The scene (a scenario, file or mapping; default: :func:`.scenarios.vbar_approach`).
        Its sensor trajectory gives the start state; ``hcw`` gives the orbit.
    dt
        Step length (s): one scan interval.
    max_points
        Rows of the ``points`` observation.
    action_mode
        ``"delta_v"`` or ``"acceleration"``.
    max_action
        Bound of each action component (m/s or m/s²).
    hold_m
        The hold point, LVLH (m).
    hold_tolerance_m, hold_speed_m_s, keep_out_m
        For the default termination.
    max_steps
        Steps before the episode is truncated.
    start_dispersion_m
        Standard deviation of the start position's offset per axis (m), drawn at reset.
    range_image
        ``(rows, cols)`` of the optional range image, or None.
    reward_fn, termination_fn
        Replace :func:`default_reward` / :func:`default_termination`.
    render_mode
        None (no rendering).
    """

    metadata = {"render_modes": []}

    def __init__(self, scenario: Any = None, *, dt: float = 0.1, max_points: int = 2048,
                 action_mode: str = "delta_v", max_action: float = 0.05,
                 hold_m: Any = (0.0, 10.0, 0.0), hold_tolerance_m: float = 0.5,
                 hold_speed_m_s: float = 0.02, keep_out_m: float = 5.0, max_steps: int = 400,
                 start_dispersion_m: float = 0.5,
                 range_image: tuple[int, int] | None = None,
                 reward_fn: Callable[[Info], float] | None = None,
                 termination_fn: Callable[[Info], bool] | None = None,
                 render_mode: str | None = None) -> None:
        if action_mode not in ("delta_v", "acceleration"):
            raise ValueError(f"action_mode must be 'delta_v' or 'acceleration', not "
                             f"{action_mode!r}")
        self.simulation = Simulation(as_scenario(scenario if scenario is not None
                                                 else vbar_approach(dt=dt)))
        self.dt = float(dt)
        self.max_points = int(max_points)
        self.action_mode = action_mode
        self.hold = np.asarray(hold_m, dtype=np.float64)
        self.limits = {"hold_tolerance_m": float(hold_tolerance_m),
                       "hold_speed_m_s": float(hold_speed_m_s), "keep_out_m": float(keep_out_m)}
        self.max_steps = int(max_steps)
        self.start_dispersion_m = float(start_dispersion_m)
        self.range_image_shape = None if range_image is None else \
            (int(range_image[0]), int(range_image[1]))
        self.reward_fn = reward_fn or default_reward
        self.termination_fn = termination_fn or default_termination
        self.render_mode = render_mode
        sheet = self.simulation.context.sensor
        reach = float(sheet.range_max_m)
        self.action_space = spaces.Box(-max_action, max_action, shape=(3,), dtype=np.float32)
        obs: dict[str, spaces.Space] = {
            "points": spaces.Box(-reach, reach, shape=(self.max_points, 3), dtype=np.float32),
            "mask": spaces.Box(0, 1, shape=(self.max_points,), dtype=np.int8)}
        if self.range_image_shape is not None:
            obs["range_image"] = spaces.Box(0.0, reach, shape=self.range_image_shape,
                                            dtype=np.float32)
        self.observation_space = spaces.Dict(obs)
        self._fov = (np.radians(sheet.fov_h_deg) / 2, np.radians(sheet.fov_v_deg) / 2,
                     np.radians(sheet.fov_v_center_deg))
        self.session: LoopSession | None = None
        self._steps = 0

    # ---- observation -----------------------------------------------------------------
    def _observation(self, result: StepResult) -> dict[str, np.ndarray]:
        c = result.cloud.columns
        keep = np.flatnonzero(c["detected"] == 1)
        if len(keep) > self.max_points:  # evenly spaced in emission order: deterministic
            keep = keep[np.linspace(0, len(keep) - 1, self.max_points).round().astype(int)]
        points = np.zeros((self.max_points, 3), dtype=np.float32)
        mask = np.zeros(self.max_points, dtype=np.int8)
        xyz = np.column_stack([c["x"][keep], c["y"][keep], c["z"][keep]])
        points[:len(keep)] = xyz
        mask[:len(keep)] = 1
        obs = {"points": points, "mask": mask}
        if self.range_image_shape is not None:
            obs["range_image"] = self._range_image(c)
        return obs

    def _range_image(self, c: Mapping[str, np.ndarray]) -> np.ndarray:
        rows, cols = self.range_image_shape  # type: ignore[misc]
        half_h, half_v, centre_v = self._fov
        image = np.full(rows * cols, np.inf, dtype=np.float64)
        ok = c["detected"] == 1
        az, el, rng = c["azimuth"][ok], c["elevation"][ok] - centre_v, c["range"][ok]
        col = np.floor((half_h - az) / (2 * half_h) * cols).astype(np.int64)
        row = np.floor((half_v - el) / (2 * half_v) * rows).astype(np.int64)
        inside = (col >= 0) & (col < cols) & (row >= 0) & (row < rows)
        np.minimum.at(image, row[inside] * cols + col[inside], rng[inside])
        image[~np.isfinite(image)] = 0.0
        return image.reshape(rows, cols).astype(np.float32)

    def _info(self, result: StepResult, before: float, action: np.ndarray) -> Info:
        state = result.state
        t_in_s, _ = result.target_in_sensor(0)
        dv = action * self.dt if self.action_mode == "acceleration" else action
        return {"t_s": state.t_s, "step": self._steps,
                "position_m": state.position_m, "velocity_m_s": state.velocity_m_s,
                "target_in_sensor_m": t_in_s, "range_m": float(np.linalg.norm(t_in_s)),
                "hold_m": self.hold.copy(),
                "distance_before_m": before,
                "distance_m": float(np.linalg.norm(state.position_m - self.hold)),
                "speed_m_s": float(np.linalg.norm(state.velocity_m_s)),
                "action": action.copy(), "delta_v_m_s": np.asarray(dv, dtype=np.float64),
                "points": int(len(result.cloud)), **self.limits}

    # ---- the Gymnasium interface -------------------------------------------------------
    def reset(self, *, seed: int | None = None, options: dict[str, Any] | None = None
              ) -> tuple[dict[str, np.ndarray], Info]:
        """Start an episode: the start dispersion and the noise seed come from ``seed``."""
        super().reset(seed=seed)
        ctx = self.simulation.context
        t0 = np.array([ctx.scenario.scan.start_s])
        start = ctx.sensor_trajectory.poses_at(t0).position[0]
        offset = self.np_random.normal(0.0, self.start_dispersion_m, size=3)
        noise_seed = int(self.np_random.integers(0, 2 ** 31 - 1))
        self.session = LoopSession(self.simulation, seed=noise_seed,
                                   position_m=start + offset, velocity_m_s=np.zeros(3))
        self._steps = 0
        before = float(np.linalg.norm(start + offset - self.hold))
        result = self.session.step(self.dt)  # the first scan, natural motion
        zero = np.zeros(3)
        return self._observation(result), self._info(result, before, zero)

    def step(self, action: Any) -> tuple[dict[str, np.ndarray], float, bool, bool, Info]:
        """One scan interval under the commanded ``action`` (LVLH)."""
        if self.session is None:
            raise RuntimeError("call reset() before step()")
        act = np.clip(np.asarray(action, dtype=np.float64).reshape(3),
                      self.action_space.low, self.action_space.high)
        before = float(np.linalg.norm(self.session.state.position_m - self.hold))
        command = {"delta_v_m_s" if self.action_mode == "delta_v" else "acceleration_m_s2": act}
        result = self.session.step(self.dt, **command)
        self._steps += 1
        info = self._info(result, before, act)
        reward = float(self.reward_fn(info))
        terminated = bool(self.termination_fn(info))
        truncated = self._steps >= self.max_steps
        return self._observation(result), reward, terminated, truncated, info
