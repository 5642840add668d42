"""Plugins: the registry of components, the pluggy manager that fills it, the one place that
resolves names to components, and guards around third-party components.

The hook specifications stay at :mod:`lidarsim_core.hookspecs` (the path plugins import).
"""

from .manager import (
                      BUILTIN_PROVIDER,
                      ENTRY_POINT_GROUP,
                      PluginLoadWarning,
                      build_plugin_manager,
                      build_registry,
                      get_registry,
                      reset_registry,
)
from .resolve import get_sensor, pattern_for

# importing the shortcuts attaches PointCloud.save() and PointCloud.range_image()
from .shortcuts import write_cloud

__all__ = ["BUILTIN_PROVIDER", "ENTRY_POINT_GROUP", "PluginLoadWarning", "build_plugin_manager",
           "build_registry", "get_registry", "get_sensor", "pattern_for", "reset_registry", "write_cloud"]
