"""Trajectories: how a sensor's or a target's pose evolves with time (built-in plugins)."""

#: Modules registered as built-in plugins (see ``lidarsim_core.plugins.manager``).
BUILTIN_MODULES: tuple[str, ...] = ("static", "kinematic", "keyframes", "tumbling", "hcw")
