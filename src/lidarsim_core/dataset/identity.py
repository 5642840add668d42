"""What makes a dataset what it is, so that a rerun can resume it or must refuse it.

A sequence's scenario is first *normalised* so that it no longer depends on where it runs: a
datasheet given as a file is inlined, and ``backend: auto`` becomes the backend it chose here
(a cluster node without Embree then fails loudly instead of silently tracing with NumPy).
The normalised scenario is what the dataset stores, simulates, and hashes.

The identity of a dataset is the normalised scenario of each sequence, the content of its
inputs (datasheet, mesh geometry, the poses its trajectories give), the providers of every
plugin it uses, the exporter and its options, and the versions of lidarsim and of the numeric
packages. Any difference means frames already on disk may not match new ones, so the run is
refused with the differences listed.
"""

from __future__ import annotations

import functools
import hashlib
import json
from importlib import metadata
from pathlib import Path
from typing import TYPE_CHECKING, Any

from .._version import __version__
from ..base.config_io import CONFIG_SUFFIXES
from ..base.errors import ConfigError
from ..plugins.registry import Registry
from ..plugins.resolve import get_sensor
from ..scenario.load import scenario_from_dict
from ..scenario.model import Scenario

if TYPE_CHECKING:
    from ..io.base import Exporter
    from ..pipeline.simulation import Simulation

#: Packages whose versions can change the bytes of a frame.
NUMERIC_PACKAGES = ("numpy", "scipy", "trimesh", "embreex")


def canonical_sha256(data: Any) -> str:
    """SHA-256 of the canonical (key-sorted, compact) JSON of ``data``."""
    text = json.dumps(data, sort_keys=True, separators=(",", ":"))
    return hashlib.sha256(text.encode("utf-8")).hexdigest()


def scenario_source(scenario: Scenario) -> str | None:
    """The file a scenario came from, or ``None`` for one built in memory."""
    return None if scenario.source == "<scenario>" else scenario.source


def normalize_scenario(scenario: Scenario, registry: Registry) -> Scenario:
    """The scenario with a datasheet file inlined and ``backend: auto`` resolved.

    The result keeps the original source file, so relative mesh paths still resolve.
    """
    from ..plugins.resolve import resolve_backend

    data = scenario.model_dump(mode="json")
    sheet = scenario.sensor.datasheet
    if isinstance(sheet, str) and sheet.endswith(CONFIG_SUFFIXES):
        path = scenario.resolve(Path(sheet))
        if not path.is_file():
            raise ConfigError(f"datasheet file not found: {path}", source=scenario.source,
                              field="sensor.datasheet")
        data["sensor"]["datasheet"] = get_sensor(path).model_dump(mode="json")
    if scenario.backend.name == "auto":
        data["backend"]["name"] = resolve_backend(registry, scenario.backend,
                                                  source=scenario.source).name
    return scenario_from_dict(data, source=scenario_source(scenario))


def _provider(registry: Registry, kind: str, name: str) -> str:
    entry = registry.entries[kind].get(name)
    return entry.provider if entry is not None else "inline"


def plugin_providers(sim: "Simulation", registry: Registry) -> dict[str, str]:
    """``"kind/name"`` → providing distribution, for every plugin a simulation uses."""
    scenario = sim.scenario
    used: list[tuple[str, str]] = [("scan_pattern", sim.sensor.scan_pattern.name),
                                   ("ray_backend", sim.backend.name)]
    if isinstance(scenario.sensor.datasheet, str):
        used.append(("sensor", scenario.sensor.datasheet))
    used += [("noise_model", m.name) for m in sim.noise]
    used.append(("trajectory", scenario.sensor.trajectory_config().kind))
    for target in scenario.targets:
        used.append(("trajectory", target.trajectory_config().kind))
        if target.mesh.model is not None:
            used.append(("target_model", target.mesh.model))
    return {f"{kind}/{name}": _provider(registry, kind, name) for kind, name in sorted(set(used))}


def package_versions(extra: tuple[str, ...] = ()) -> dict[str, str]:
    """Installed versions of :data:`NUMERIC_PACKAGES` and ``extra`` (missing ones omitted)."""
    return {name: version for name in (*NUMERIC_PACKAGES, *extra)
            if (version := _version(name)) is not None}


@functools.lru_cache(maxsize=None)
def _version(name: str) -> str | None:
    # read once per process (~1.4 ms each from the installed metadata): the modules this
    # process imported do not change under it
    try:
        return metadata.version(name)
    except metadata.PackageNotFoundError:
        return None


def sequence_identity(name: str, sim: "Simulation", registry: Registry,
                      poses_sha256: str) -> dict[str, Any]:
    """The identity of one sequence (see the module docstring)."""
    scenario = sim.scenario
    return {"name": name,
            "scenario_sha256": canonical_sha256(scenario.model_dump(mode="json")),
            "datasheet_sha256": canonical_sha256(sim.sensor.model_dump(mode="json")),
            "meshes": {t.name: t.mesh.key for t in sim.targets},
            "poses_sha256": poses_sha256,
            "plugins": plugin_providers(sim, registry)}


def exporter_identity(exporter: "Exporter", registry: Registry) -> dict[str, Any]:
    """The exporter's name, options, file suffix and provider."""
    return {"name": exporter.name, "options": exporter.options.model_dump(mode="json"),
            "suffix": exporter.suffixes[0] if exporter.suffixes else "",
            "provider": _provider(registry, "exporter", exporter.name)}


def dataset_identity(sequences: list[dict[str, Any]], exporter: dict[str, Any], *,
                     multi: bool, packages: dict[str, str]) -> dict[str, Any]:
    """The identity of a whole dataset."""
    return {"software": f"lidarsim-core {__version__}", "packages": packages,
            "layout": "sequences" if multi else "single", "exporter": exporter,
            "sequences": sequences}


def differences(old: Any, new: Any, prefix: str = "") -> list[str]:
    """Human-readable ``path: old → new`` lines for every difference of two JSON values."""
    if isinstance(old, dict) and isinstance(new, dict):
        out: list[str] = []
        for key in sorted(set(old) | set(new), key=str):
            path = f"{prefix}.{key}" if prefix else str(key)
            if key not in old:
                out.append(f"{path}: (absent) → {_short(new[key])}")
            elif key not in new:
                out.append(f"{path}: {_short(old[key])} → (absent)")
            else:
                out += differences(old[key], new[key], path)
        return out
    if isinstance(old, list) and isinstance(new, list) and len(old) == len(new):
        out = []
        for i, (a, b) in enumerate(zip(old, new)):
            out += differences(a, b, f"{prefix}.{i}" if prefix else str(i))
        return out
    return [] if old == new else [f"{prefix or '<root>'}: {_short(old)} → {_short(new)}"]


def _short(value: Any, limit: int = 40) -> str:
    text = json.dumps(value, sort_keys=True)
    return text if len(text) <= limit else text[:limit - 1] + "…"
