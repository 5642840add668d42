"""Gymnasium environments on the closed loop (optional extra ``gym``: ``pip install
lidarsim-core[gym]``; docs/closed_loop.md).

Importing this package registers every environment under the ``lidarsim/`` namespace:

>>> import gymnasium                                   # doctest: +SKIP
>>> import lidarsim_core.gym                           # registers lidarsim/...
>>> env = gymnasium.make("lidarsim/Approach-v0")

Gymnasium 1.x has no plugin entry points (they were removed in 1.0), so an installed package
cannot register itself before it is imported; ``gymnasium.make`` imports it when the id names
the module: ``gymnasium.make("lidarsim_core.gym:lidarsim/Approach-v0")`` needs no import.
``import lidarsim_core`` never imports gymnasium.
"""

from __future__ import annotations

from gymnasium.envs.registration import register, registry

#: Every environment this package registers: id → (entry point, default keyword arguments).
ENVIRONMENTS: dict[str, tuple[str, dict]] = {
    "lidarsim/Approach-v0": ("lidarsim_core.gym.approach:ApproachEnv", {}),
    "lidarsim/ApproachAccel-v0": ("lidarsim_core.gym.approach:ApproachEnv",
                                  {"action_mode": "acceleration", "max_action": 0.01}),
}

for _id, (_entry, _kwargs) in ENVIRONMENTS.items():
    if _id not in registry:
        register(id=_id, entry_point=_entry, kwargs=_kwargs, max_episode_steps=400)

__all__ = ["ENVIRONMENTS"]
