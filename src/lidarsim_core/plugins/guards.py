"""Third-party components that fail at run time are reported with their name and distribution.

:func:`guard_component` makes a third-party pattern, noise model, backend, trajectory or
exporter that raises in the middle of a run fail with a
:class:`~lidarsim_core.base.errors.PluginError` naming the component and the distribution that
provides it.
"""

from __future__ import annotations

import functools
from typing import Any, Callable, Iterable

from .registry import BUILTIN_PROVIDER, Registry

# ---- plugins failing at run time ---------------------------------------------------------
#: Methods of each component kind that run during a simulation or an export.
GUARDED_METHODS: dict[str, tuple[str, ...]] = {
    "scan_pattern": ("rays_for_indices", "index_range", "time_of_index"),
    "noise_model": ("perturb_rays", "perturb_returns"),
    "ray_backend": ("prepare", "intersect"),
    "trajectory": ("poses_at",),
    "exporter": ("write", "write_points"),
}


def _flat(text: object) -> str:
    return " ".join(str(text).split())


def _guarded(method: Callable[..., Any], what: str) -> Callable[..., Any]:
    from ..base.errors import LidarsimError, PluginError

    @functools.wraps(method)
    def call(*args: Any, **kwargs: Any) -> Any:
        try:
            return method(*args, **kwargs)
        except LidarsimError:
            raise
        except Exception as exc:
            raise PluginError(f"{what} failed in {method.__name__}(): "
                              f"{type(exc).__name__}: {_flat(exc)}") from exc

    call.__lidarsim_guarded__ = True  # type: ignore[attr-defined]
    return call


def guard_component(obj: Any, kind: str, provider: str) -> Any:
    """Make ``obj``'s run-time methods raise :class:`~lidarsim_core.base.errors.PluginError`
    naming ``kind``, ``obj.name`` and ``provider`` instead of an anonymous exception.

    The wrappers are instance attributes, so the object keeps its class (``isinstance`` and
    class-level caches still work). Wrapping twice does nothing.
    """
    what = f"{kind.replace('_', ' ')} '{getattr(obj, 'name', type(obj).__name__)}' from {provider}"
    for name in GUARDED_METHODS.get(kind, ()):
        method = getattr(obj, name, None)
        if method is None or getattr(method, "__lidarsim_guarded__", False):
            continue
        setattr(obj, name, _guarded(method, what))
    return obj


def _provider(registry: Registry, kind: str, obj: Any) -> str | None:
    entry = registry.entries.get(kind, {}).get(getattr(obj, "name", ""))
    return entry.provider if entry is not None and entry.obj is type(obj) else None


def guard_components(parts: Iterable[tuple[str, Any]], registry: Registry) -> None:
    """Guard every third-party component among ``parts`` (``(kind, instance)`` pairs: a
    built simulation's pattern, backend, noise models and trajectories).

    Built-in components are left alone: a failure there is a lidarsim bug and is reported as
    such.
    """
    for kind, obj in parts:
        provider = _provider(registry, kind, obj)
        if provider is not None and provider != BUILTIN_PROVIDER:
            guard_component(obj, kind, provider)


def guard_exporter(exporter: Any, registry: Registry) -> Any:
    """Guard a third-party exporter instance (see :func:`guard_component`); returns it."""
    guard_components([("exporter", exporter)], registry)
    return exporter
