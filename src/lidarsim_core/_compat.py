"""Old import paths keep working: every module that the package-layout change (issue 21) moved
is still importable under its old name, with a :class:`DeprecationWarning` naming the new one.

A whole-module move is an alias (the old name gives the very same module object); a module
that was split into several gives a thin module whose attributes are looked up in the new
homes. Nothing is imported until an old path is used. New code and the docs use the new
paths (docs/architecture.md lists them).
"""

from __future__ import annotations

import importlib
import importlib.abc
import importlib.machinery
import sys
import types
import warnings
from typing import Any

PACKAGE = "lidarsim_core"

#: Old module path → the module that now holds it (whole-module moves and the main part
#: of split modules), relative to ``lidarsim_core``.
MOVED: dict[str, str] = {
    "beam": "instrument.beam",
    "bench_suite": "bench.suite",
    "bodyframe": "pipeline.bodyframe",
    "builtin_sensors": "instrument.catalogue",
    "chunks": "base.threads",
    "cli_bag": "cli.bag",
    "cli_bench": "cli.bench",
    "cli_dataset": "cli.dataset",
    "cli_evaluate": "cli.evaluate",
    "cli_mesh": "cli.mesh",
    "cli_motion": "cli.poses",
    "cli_output": "cli.output",
    "cli_patterns": "cli.patterns",
    "cli_report": "cli.report",
    "cli_view": "cli.view",
    "components": "base.components",
    "config_io": "base.config_io",
    "cull": "pipeline.cull",
    "datasheet": "scenario.datasheet",
    "demo": "scenario.demo",
    "errors": "base.errors",
    "frameinfo": "pipeline.frameinfo",
    "groundtruth": "records.groundtruth",
    "guard": "base.signals",
    "limits": "base.limits",
    "materials": "scene.materials",
    "mesh": "scene.mesh",
    "outputs": "base.outputs",
    "patterns.coverage": "patterns.fov",
    "pointcloud": "records.pointcloud",
    "poses": "geometry.poses",
    "posing": "geometry.posing",
    "radiometry": "instrument.linkbudget",
    "rangeimage": "io.rangeimage",
    "registry": "plugins.registry",
    "returns": "instrument.returns",
    "rng": "noise.rng",
    "stages": "pipeline.stages",
    "stages.base": "pipeline.stages.base",
    "stages.bounces": "pipeline.stages.bounces",
    "stages.candidates": "pipeline.stages.candidates",
    "stages.detection": "pipeline.stages.detection",
    "stages.noise": "pipeline.stages.noise",
    "stages.receiver": "pipeline.stages.receiver",
    "stages.record": "pipeline.stages.record",
    "stages.selection": "pipeline.stages.selection",
    "stages.sun": "pipeline.stages.sun",
    "targets": "scene.targets",
    "units": "pipeline.units",
    "vec3": "geometry.vec3",
}
#: Names of split modules that went elsewhere than :data:`MOVED` says.
SPLIT: dict[str, dict[str, str]] = {
    "beam": {
        "BeamConfig": "scenario.sensor",
    },
    "builtin_sensors": {
        "get_sensor": "plugins.resolve",
        "register_sensor_source": "plugins.manager",
    },
    "chunks": {
        "rotate": "geometry.frames",
        "to_body": "geometry.frames",
    },
    "components": {
        "first_validation_error": "base.validation",
    },
    "config_io": {
        "validate_model": "base.validation",
    },
    "groundtruth": {
        "read_ground_truth": "io.groundtruth",
        "sequence_frame_infos": "pipeline.simulation",
        "write_ground_truth": "io.groundtruth",
    },
    "guard": {
        "GUARDED_METHODS": "plugins.guards",
        "check_sensor_outside": "pipeline.inside",
        "describe_os_error": "base.oserrors",
        "guard_component": "plugins.guards",
        "guard_components": "plugins.guards",
        "guard_exporter": "plugins.guards",
        "os_error_line": "base.oserrors",
        "quiet_numerics": "base.numerics",
    },
    "limits": {
        "check_simulation": "pipeline.budget",
        "coverage_cells": "patterns.fov",
    },
    "patterns.coverage": {
        "pattern_for": "plugins.resolve",
    },
    "poses": {
        "PoseConfig": "scenario.pose",
        "check_euler_sequence": "scenario.pose",
    },
    "posing": {
        "PiecePoses": "pipeline.posing",
        "has_fast_path": "trajectories.matrices",
        "piece_poses": "pipeline.posing",
        "pose_matrices": "trajectories.matrices",
        "with_piece_poses": "pipeline.posing",
    },
    "radiometry": {
        "DetectionConfig": "scenario.sensor",
    },
    "rangeimage": {
        "pattern_for_cloud": "plugins.resolve",
    },
    "returns": {
        "ReturnsConfig": "scenario.sensor",
    },
    "stages.bounces": {
        "DEFAULT_ACCEPTANCE_DEG": "scenario.sensor",
        "MultipathConfig": "scenario.sensor",
    },
    "stages.receiver": {
        "ReceiverConfig": "scenario.sensor",
    },
    "stages.sun": {
        "DEFAULT_FILTER_WIDTH_NM": "scenario.sun",
        "SunConfig": "scenario.sun",
        "SunOrbit": "scenario.sun",
    },
}


class _Moved(types.ModuleType):
    """An old split module: each attribute comes from the module that now holds it."""

    def __init__(self, old: str) -> None:
        super().__init__(f"{PACKAGE}.{old}")
        self._old = old

    def _home(self, name: str) -> str:
        return SPLIT.get(self._old, {}).get(name, MOVED[self._old])

    def __getattr__(self, name: str) -> Any:
        if name.startswith("__"):
            raise AttributeError(name)
        module = importlib.import_module(f"{PACKAGE}.{self._home(name)}")
        try:
            return getattr(module, name)
        except AttributeError:
            raise AttributeError(f"module '{PACKAGE}.{self._old}' has no attribute "
                                 f"{name!r}") from None

    def __dir__(self) -> list[str]:
        main = importlib.import_module(f"{PACKAGE}.{MOVED[self._old]}")
        return sorted({n for n in vars(main) if not n.startswith("_")} |
                      set(SPLIT.get(self._old, {})))


class _Loader(importlib.abc.Loader):
    def __init__(self, old: str) -> None:
        self.old = old
        self.spec: Any = None

    def create_module(self, spec: importlib.machinery.ModuleSpec) -> types.ModuleType:
        new = MOVED[self.old]
        warnings.warn(f"{PACKAGE}.{self.old} moved to {PACKAGE}.{new}; import it from there "
                      "(docs/architecture.md)", DeprecationWarning, stacklevel=2)
        if self.old in SPLIT:
            return _Moved(self.old)
        module = importlib.import_module(f"{PACKAGE}.{new}")
        self.spec = module.__spec__
        return module

    def exec_module(self, module: types.ModuleType) -> None:
        """Nothing to run: the module is the moved one (or looks its names up there)."""
        if self.spec is not None:
            # the import system gave the moved module the old name's spec: give its own back
            # (its relative imports, pickles and spawned workers use it)
            module.__spec__ = self.spec


class _Finder(importlib.abc.MetaPathFinder):
    """Finds the old paths of :data:`MOVED` (and nothing else)."""

    def find_spec(self, fullname: str, path: Any = None,
                  target: Any = None) -> importlib.machinery.ModuleSpec | None:
        if not fullname.startswith(PACKAGE + "."):
            return None
        old = fullname[len(PACKAGE) + 1:]
        if old not in MOVED:
            return None
        return importlib.machinery.ModuleSpec(fullname, _Loader(old))


def install() -> None:
    """Register the finder once, first: an old name inside a moved package (``stages.sun``)
    would otherwise be found again as a second copy of the module."""
    if not any(isinstance(finder, _Finder) for finder in sys.meta_path):
        sys.meta_path.insert(0, _Finder())
