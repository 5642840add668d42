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

from . import _compat
from ._version import __version__

if TYPE_CHECKING:  # pragma: no cover - for type checkers and IDEs only
    from .base.errors import (
        BackendError,
        ConfigError,
        LidarsimError,
        MeshError,
        PluginError,
        UserInputError,
    )
    from .dataset.reader import open_dataset
    from .io.reader import read
    from .pipeline.simulation import Simulation, simulate
    from .plugins.manager import get_registry
    from .plugins.resolve import get_sensor
    from .records.pointcloud import FrameInfo, PointCloud
    from .scenario.datasheet import SensorDatasheet, load_datasheet
    from .scenario.demo import demo_scenario
    from .scenario.load import load_scenario
    from .scenario.model import Scenario
    from .scene.mesh import Mesh, load_mesh_file

#: Each public name and the module that defines it.
_LAZY: dict[str, str] = {
    "get_sensor": "plugins.resolve",
    "SensorDatasheet": "scenario.datasheet", "load_datasheet": "scenario.datasheet",
    "demo_scenario": "scenario.demo",
    "LidarsimError": "base.errors", "UserInputError": "base.errors",
    "ConfigError": "base.errors", "MeshError": "base.errors", "PluginError": "base.errors",
    "BackendError": "base.errors",
    "Mesh": "scene.mesh", "load_mesh_file": "scene.mesh",
    "get_registry": "plugins.manager",
    "PointCloud": "records.pointcloud", "FrameInfo": "records.pointcloud",
    "Scenario": "scenario.model", "load_scenario": "scenario.load",
    "Simulation": "pipeline.simulation", "simulate": "pipeline.simulation",
    "read": "io.reader",
    "open_dataset": "dataset.reader",
}
#: Names whose objects carry or return point clouds: the plugins layer attaches
#: ``PointCloud.save`` and ``PointCloud.range_image`` (:mod:`.plugins.shortcuts`) first.
_CLOUDS = {"PointCloud", "FrameInfo", "read", "Simulation", "simulate"}

__all__ = ["__version__", *sorted(_LAZY)]

_compat.install()


def __getattr__(name: str) -> Any:
    if name in _LAZY:
        if name in _CLOUDS:
            import_module(".plugins", __name__)
        value = getattr(import_module(f".{_LAZY[name]}", __name__), name)
        globals()[name] = value
        return value
    raise AttributeError(f"module 'lidarsim_core' has no attribute {name!r}")


def __dir__() -> list[str]:
    # the public names only: not the helpers this module imports for itself
    return sorted(__all__)
