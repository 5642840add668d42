"""What the plugins registered, with the distribution that provided each entry.

The registry is filled once, on first use, by calling every plugin's registration hooks (see
:mod:`lidarsim_core.plugins.manager`). Look-ups by an unknown name raise
:class:`~lidarsim_core.base.errors.UnknownNameError` listing what is installed.
"""

from __future__ import annotations

import difflib
import re
from dataclasses import dataclass, field
from typing import Any, Iterator

from .._version import __version__
from ..base.errors import PluginError, UnknownNameError

#: Provider label of the components lidarsim itself registers.
BUILTIN_PROVIDER = f"lidarsim-core {__version__} (built-in)"

#: Registry kinds, in the order hooks are called, with the hook that fills each.
KINDS: dict[str, str] = {
    "sensor": "lidarsim_register_sensors",
    "scan_pattern": "lidarsim_register_scan_patterns",
    "noise_model": "lidarsim_register_noise_models",
    "ray_backend": "lidarsim_register_ray_backends",
    "exporter": "lidarsim_register_exporters",
    "target_model": "lidarsim_register_target_models",
    "trajectory": "lidarsim_register_trajectories",
    "pose_estimator": "lidarsim_register_pose_estimators",
}

_NAME_RE = re.compile(r"^[a-z0-9][a-z0-9_.-]*$")


@dataclass(frozen=True)
class Entry:
    """One registered thing.

    Attributes
    ----------
    kind
        One of :data:`KINDS`.
    name
        The name users refer to it by.
    obj
        The registered class (or, for sensors, the datasheet or its loader).
    provider
        The distribution (``"name version"``) or plugin that registered it.
    """

    kind: str
    name: str
    obj: Any
    provider: str


@dataclass
class Registry:
    """Name → :class:`Entry` tables, one per kind."""

    entries: dict[str, dict[str, Entry]] = field(
        default_factory=lambda: {kind: {} for kind in KINDS})

    def add(self, kind: str, name: str, obj: Any, provider: str) -> None:
        """Add an entry; a name registered twice is a :class:`PluginError` naming both providers."""
        if not isinstance(name, str) or not _NAME_RE.match(name):
            raise PluginError(f"{provider} registered a {kind} with an invalid name {name!r} "
                              "(use lower-case letters, digits, '-', '_' or '.')")
        table = self.entries[kind]
        if name in table:
            raise PluginError(
                f"{kind} '{name}' is registered twice: by {table[name].provider} and by {provider}")
        table[name] = Entry(kind, name, obj, provider)

    def names(self, kind: str) -> list[str]:
        """Sorted names registered for ``kind``."""
        return sorted(self.entries[kind])

    def iter(self, kind: str) -> Iterator[Entry]:
        """Entries of ``kind`` sorted by name."""
        for name in self.names(kind):
            yield self.entries[kind][name]

    def entry(self, kind: str, name: str, *, source: str | None = None,
              field: str | None = None) -> Entry:
        """Return the entry for ``name`` or raise an error listing the installed names."""
        try:
            return self.entries[kind][name]
        except KeyError:
            installed = self.names(kind)
            close = difflib.get_close_matches(str(name), installed, n=1)
            hint = f" (did you mean '{close[0]}'?)" if close else ""
            raise UnknownNameError(
                f"unknown {kind.replace('_', ' ')} '{name}'{hint}; installed: "
                f"{', '.join(installed) or 'none'}", source=source, field=field) from None

    def get(self, kind: str, name: str, **where: Any) -> Any:
        """Shortcut for ``entry(kind, name).obj``."""
        return self.entry(kind, name, **where).obj
