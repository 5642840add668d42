"""lidarsim: LiDAR point clouds of satellites for in-orbit close-range operations.

The public API is loaded lazily, so ``import lidarsim_core`` stays cheap and never imports the
optional heavy dependencies (embreex, pyvista, vtk, laspy, dask).

Examples
--------
>>> import lidarsim_core as ls
>>> scenario = ls.demo_scenario(duration_s=0.05)
>>> cloud = ls.simulate(scenario)
>>> cloud.frame.sensor
'livox-mid70-rose'
"""

from __future__ import annotations

from importlib import import_module
from typing import TYPE_CHECKING, Any

from ._version import __version__

if TYPE_CHECKING:  # pragma: no cover - for type checkers and IDEs only
    from .builtin_sensors import get_sensor
    from .datasheet import SensorDatasheet, load_datasheet
    from .demo import demo_scenario
    from .errors import (BackendError, ConfigError, LidarsimError, MeshError, PluginError,
                         UserInputError)
    from .mesh import Mesh, load_mesh_file
    from .plugins import get_registry
    from .pointcloud import FrameInfo, PointCloud
    from .scenario import Scenario, load_scenario
    from .pipeline import Simulation, simulate
    from .io.reader import read

_LAZY: dict[str, str] = {
    "get_sensor": "builtin_sensors",
    "SensorDatasheet": "datasheet", "load_datasheet": "datasheet",
    "demo_scenario": "demo",
    "LidarsimError": "errors", "UserInputError": "errors", "ConfigError": "errors",
    "MeshError": "errors", "PluginError": "errors", "BackendError": "errors",
    "Mesh": "mesh", "load_mesh_file": "mesh",
    "get_registry": "plugins",
    "PointCloud": "pointcloud", "FrameInfo": "pointcloud",
    "Scenario": "scenario", "load_scenario": "scenario",
    "Simulation": "pipeline", "simulate": "pipeline",
    "read": "io.reader",
}

__all__ = ["__version__", *sorted(_LAZY)]


def __getattr__(name: str) -> Any:
    if name in _LAZY:
        value = getattr(import_module(f".{_LAZY[name]}", __name__), name)
        globals()[name] = value
        return value
    raise AttributeError(f"module 'lidarsim_core' has no attribute {name!r}")


def __dir__() -> list[str]:
    # the public names only: not the helpers this module imports for itself
    return sorted(__all__)
