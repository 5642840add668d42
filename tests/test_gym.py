"""The Gymnasium environments (lidarsim_core.gym): Gymnasium's own checker, seeded episodes,
registration, and that lidarsim never needs gymnasium."""

from __future__ import annotations

import os
import subprocess
import sys

import numpy as np
import pytest

gymnasium = pytest.importorskip("gymnasium")

from gymnasium.utils.env_checker import check_env  # noqa: E402

import lidarsim_core.gym  # noqa: E402,F401  (registers lidarsim/...)

ENV = {**os.environ, "LIDARSIM_DISABLE_PLUGIN_AUTOLOAD": "1"}


def lidarsim_ids() -> list[str]:
    return sorted(i for i in gymnasium.registry if i.startswith("lidarsim/"))


def test_every_environment_is_registered_under_the_namespace():
    assert lidarsim_ids() == sorted(lidarsim_core.gym.ENVIRONMENTS)
    assert len(lidarsim_ids()) >= 2


@pytest.mark.parametrize("env_id", sorted(lidarsim_core.gym.ENVIRONMENTS))
def test_gymnasium_check_env_passes(env_id):
    env = gymnasium.make(env_id, max_points=512, range_image=(8, 12))
    check_env(env.unwrapped, skip_render_check=True)
    obs, _ = env.reset(seed=1)
    assert obs["mask"].sum() > 0 and obs["range_image"].max() > 0
    env.close()


def episode(env, seed: int, steps: int = 4) -> list:
    obs, info = env.reset(seed=seed)
    out = [obs, info["position_m"]]
    for k in range(steps):
        obs, reward, terminated, truncated, info = env.step(
            np.array([0.0, -0.02 * (k % 2), 0.001], dtype=np.float32))
        out += [obs, reward, terminated, truncated, info["position_m"]]
    return out


def same(a, b) -> bool:
    if isinstance(a, dict):
        return a.keys() == b.keys() and all(same(a[k], b[k]) for k in a)
    if isinstance(a, np.ndarray):
        return a.dtype == b.dtype and a.tobytes() == b.tobytes()
    return a == b


def test_two_resets_with_one_seed_give_one_episode():
    env = gymnasium.make("lidarsim/Approach-v0", max_points=1024)
    first, second, other = episode(env, 7), episode(env, 7), episode(env, 8)
    assert all(same(a, b) for a, b in zip(first, second))
    assert not same(first[1], other[1])  # another seed: another start
    env.close()


def test_the_hold_terminates_and_the_reward_is_pluggable():
    """A custom termination and reward receive the step's truth; the default termination
    ends an episode at the hold point."""
    seen = []

    def reward(info):
        seen.append(info["distance_m"])
        return -info["distance_m"]

    env = gymnasium.make("lidarsim/Approach-v0", max_points=256, start_dispersion_m=0.0,
                         hold_m=(0.0, 50.0, 0.0), reward_fn=reward)
    env.reset(seed=0)
    _, r, terminated, _, info = env.step(np.zeros(3, dtype=np.float32))
    assert r == -seen[-1] and info["distance_m"] < 1e-3 and terminated
    env = gymnasium.make("lidarsim/Approach-v0", max_points=256,
                         termination_fn=lambda info: info["step"] >= 2)
    env.reset(seed=0)
    assert not env.step(np.zeros(3, dtype=np.float32))[2]
    assert env.step(np.zeros(3, dtype=np.float32))[2]


def test_make_with_the_module_prefix_needs_no_import():
    """Gymnasium 1.x loads no plugins: 'lidarsim_core.gym:lidarsim/...' imports the module."""
    code = ("import gymnasium; env = gymnasium.make('lidarsim_core.gym:lidarsim/Approach-v0',"
            " max_points=64); print(env.spec.id)")
    out = subprocess.run([sys.executable, "-c", code], env=ENV, capture_output=True, text=True,
                         timeout=300)
    assert out.returncode == 0, out.stderr
    assert out.stdout.strip() == "lidarsim/Approach-v0"


def test_lidarsim_and_the_loop_never_import_gymnasium():
    code = ("import sys, lidarsim_core, lidarsim_core.loop, lidarsim_core as ls; "
            "ls.Simulation; print(sorted(m for m in sys.modules if m.startswith('gym')))")
    out = subprocess.run([sys.executable, "-c", code], env=ENV, capture_output=True, text=True,
                         timeout=300)
    assert out.returncode == 0, out.stderr
    assert out.stdout.strip() == "[]"
