"""The plugin manager: built-ins, entry-point plugins and explicitly named modules.

Built-in components are registered through the very same hooks as third-party ones, by importing
the modules listed by :func:`builtin_plugin_modules`, so a plain checkout works without installed
metadata. Third-party plugins come from the ``lidarsim`` entry-point group and are loaded one at a
time: a plugin that fails to import becomes a :class:`PluginLoadWarning` naming its distribution.

Environment variables
---------------------
``LIDARSIM_DISABLE_PLUGIN_AUTOLOAD``
    If set to a non-empty value other than ``0``, entry-point plugins are not loaded at all
    (the test-suite does this so the machine's installed plugins cannot change results).
``LIDARSIM_BLOCK_PLUGINS``
    Comma-separated entry-point names or distribution names that are never loaded.
``LIDARSIM_PLUGINS``
    Comma-separated importable module names to register as plugins in addition (like
    ``pytest -p``); this is the only other way code gets loaded as a plugin.
"""

from __future__ import annotations

import importlib
import os
import threading
import warnings
from importlib import metadata
from pathlib import Path
from typing import Any, Iterable

import pluggy

from .. import hookspecs
from ..base.errors import ConfigError, LidarsimError, PluginError
from ..scenario.datasheet import SensorDatasheet, load_datasheet
from .registry import BUILTIN_PROVIDER, KINDS, Registry

ENTRY_POINT_GROUP = "lidarsim"

#: Subpackages whose ``BUILTIN_MODULES`` tuples list the modules that provide the built-in
#: components. Each module is imported (cheaply) and registered when the registry is built.
BUILTIN_PACKAGES: tuple[str, ...] = (
    "lidarsim_core.patterns", "lidarsim_core.noise", "lidarsim_core.backends",
    "lidarsim_core.io", "lidarsim_core.models", "lidarsim_core.trajectories",
    "lidarsim_core.evaluate",
)


def builtin_plugin_modules() -> list[str]:
    """Every built-in plugin module, in registration order."""
    modules = ["lidarsim_core.instrument.catalogue"]
    for package in BUILTIN_PACKAGES:
        pkg = importlib.import_module(package)
        modules += [f"{package}.{name}" for name in pkg.BUILTIN_MODULES]
    return modules


class PluginLoadWarning(UserWarning):
    """A third-party plugin could not be loaded or registered; it was skipped."""


def _env_list(var: str) -> list[str]:
    return [item.strip() for item in os.environ.get(var, "").split(",") if item.strip()]


def autoload_disabled() -> bool:
    """Whether ``LIDARSIM_DISABLE_PLUGIN_AUTOLOAD`` turns entry-point loading off."""
    return os.environ.get("LIDARSIM_DISABLE_PLUGIN_AUTOLOAD", "") not in ("", "0")


def _dist_label(dist: Any) -> str:
    if dist is None:
        return "unknown distribution"
    return f"{dist.metadata['Name']} {dist.version}"


class PluginManager(pluggy.PluginManager):
    """A pluggy manager that remembers who provided each plugin."""

    def __init__(self) -> None:
        super().__init__(hookspecs.PROJECT_NAME)
        self.add_hookspecs(hookspecs)
        self.providers: dict[str, str] = {}

    def register_plugin(self, plugin: Any, name: str, provider: str) -> None:
        """Register ``plugin`` under ``name`` and remember ``provider`` for the registry."""
        self.register(plugin, name=name)
        self.providers[name] = provider

    def load_entry_points(self, entry_points: Iterable[metadata.EntryPoint] | None = None) -> None:
        """Load the ``lidarsim`` entry points one at a time, turning failures into warnings."""
        if autoload_disabled():
            return
        blocked = set(_env_list("LIDARSIM_BLOCK_PLUGINS"))
        eps = entry_points if entry_points is not None else \
            metadata.entry_points(group=ENTRY_POINT_GROUP)
        for ep in eps:
            dist = getattr(ep, "dist", None)
            dist_name = dist.metadata["Name"] if dist is not None else ""
            if ep.name in blocked or dist_name in blocked or self.has_plugin(ep.name):
                continue
            provider = _dist_label(dist)
            try:
                plugin = ep.load()
            except Exception as exc:  # a broken plugin must not break lidarsim
                warnings.warn(f"lidarsim plugin '{ep.name}' from {provider} failed to load and "
                              f"was skipped: {type(exc).__name__}: {exc}", PluginLoadWarning,
                              stacklevel=2)
                continue
            self.register_plugin(plugin, ep.name, provider)

    def load_named_modules(self, modules: Iterable[str]) -> None:
        """Import and register explicitly named plugin modules (``LIDARSIM_PLUGINS``)."""
        for modname in modules:
            if self.has_plugin(modname):
                continue
            try:
                module = importlib.import_module(modname)
            except Exception as exc:
                raise PluginError(f"plugin module '{modname}' named in LIDARSIM_PLUGINS could "
                                  f"not be imported: {type(exc).__name__}: {exc}") from None
            self.register_plugin(module, modname, f"module {modname}")


def build_plugin_manager() -> PluginManager:
    """A manager with the built-ins, the entry-point plugins and ``LIDARSIM_PLUGINS`` modules."""
    pm = PluginManager()
    for modname in builtin_plugin_modules():
        pm.register_plugin(importlib.import_module(modname), modname, BUILTIN_PROVIDER)
    pm.load_entry_points()
    pm.load_named_modules(_env_list("LIDARSIM_PLUGINS"))
    return pm


def _call_registration(pm: PluginManager, registry: Registry, kind: str) -> None:
    """Call one registration hook plugin by plugin, so every entry knows its provider."""
    from .manager import register_sensor_source

    hook = getattr(pm.hook, KINDS[kind])
    for impl in hook.get_hookimpls():  # registration order
        provider = pm.providers.get(impl.plugin_name, impl.plugin_name)
        builtin = provider == BUILTIN_PROVIDER

        def register(obj: Any, _provider: str = provider, _builtin: bool = builtin) -> None:
            if kind == "sensor":
                register_sensor_source(registry, obj, _provider, strict=_builtin)
            else:
                registry.add(kind, getattr(obj, "name", None), obj, _provider)

        try:
            impl.function(register=register)
        except LidarsimError:
            raise
        except Exception as exc:
            if builtin:
                raise
            raise PluginError(f"plugin '{impl.plugin_name}' from {provider} raised while "
                              f"registering {kind}s: {type(exc).__name__}: {exc}") from exc


def build_registry(pm: PluginManager | None = None) -> Registry:
    """Build a fresh :class:`Registry` by calling every registration hook."""
    pm = pm if pm is not None else build_plugin_manager()
    registry = Registry()
    for kind in KINDS:
        _call_registration(pm, registry, kind)
    return registry


_lock = threading.Lock()
_registry: Registry | None = None
_building = threading.local()


def get_registry() -> Registry:
    """The process-wide registry, built on first use.

    Raises
    ------
    RuntimeError
        If called by a plugin while the registry is being built (it would otherwise wait for
        itself forever); the plugin manager reports it naming that plugin.
    """
    global _registry
    if getattr(_building, "active", False):
        raise RuntimeError("get_registry() was called while the registry is being built; a "
                           "registration hook must not look up other components")
    with _lock:
        if _registry is None:
            _building.active = True
            try:
                _registry = build_registry()
            finally:
                _building.active = False
        return _registry


def reset_registry() -> None:
    """Forget the cached registry (tests; after changing plugin environment variables)."""
    global _registry
    with _lock:
        _registry = None


def register_sensor_source(registry: Registry, source: Any, provider: str, *, strict: bool) -> None:
    """Add a datasheet, a datasheet file, or a directory of them to ``registry``.

    A third-party datasheet that fails validation becomes a warning naming file and provider
    (``strict=False``); a built-in one is an error, because it is our bug.
    """
    if isinstance(source, SensorDatasheet):
        registry.add("sensor", source.name, source, provider)
        return
    if hasattr(source, "is_dir") and hasattr(source, "iterdir"):
        path = Path(str(source))
    elif isinstance(source, (str, Path)):
        path = Path(source)
    else:
        raise PluginError(f"{provider} registered a sensor of unsupported type "
                          f"{type(source).__name__}; give a SensorDatasheet or a path")
    files = sorted(p for p in path.iterdir() if p.suffix in (".yaml", ".yml")) \
        if path.is_dir() else [path]
    for file in files:
        try:
            sheet = load_datasheet(file)
        except ConfigError as exc:
            if strict:
                raise
            warnings.warn(f"sensor datasheet from {provider} skipped: {exc}", PluginLoadWarning,
                          stacklevel=2)
            continue
        registry.add("sensor", sheet.name, sheet, provider)
