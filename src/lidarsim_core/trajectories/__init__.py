"""Trajectories: how a sensor's or a target's pose evolves with time (built-in plugins)."""
