"""Guards around a run: clean interrupts, plugins failing at run time, impossible geometry.

Three safety nets that keep a failing run from leaving wrong data or a traceback behind:

* :func:`sigterm_as_interrupt` turns ``SIGTERM`` into :class:`Terminated`, a
  :class:`KeyboardInterrupt`, so a terminated run cleans up exactly like one stopped with
  Ctrl-C (atomic writes remove their temporary file; the CLI prints one line and exits 143).
* :func:`guard_components` makes a third-party pattern, noise model, backend, trajectory or
  exporter that raises in the middle of a run fail with a :class:`~lidarsim_core.errors.PluginError`
  naming the component and the distribution that provides it.
* :func:`check_sensor_outside` refuses a frame whose sensor sits inside a closed target mesh
  (every point would lie on the inside of the hull: data that looks plausible and is wrong).
"""

from __future__ import annotations

import functools
import signal
import threading
from contextlib import contextmanager
from typing import TYPE_CHECKING, Any, Callable, Iterator

if TYPE_CHECKING:
    from .pipeline import Simulation
    from .registry import Registry

#: Exit status of the CLI after SIGTERM (128 + signal number, the shell convention).
SIGTERM_EXIT_CODE = 128 + int(signal.SIGTERM)


class Terminated(KeyboardInterrupt):
    """The process received ``SIGTERM``; handled like Ctrl-C, reported as a termination."""


def _raise_terminated(signum: int, frame: Any) -> None:
    # later SIGTERMs must not interrupt the clean-up this one starts
    signal.signal(signal.SIGTERM, signal.SIG_IGN)
    raise Terminated()


@contextmanager
def sigterm_as_interrupt() -> Iterator[None]:
    """While the block runs, ``SIGTERM`` raises :class:`Terminated` in the main thread.

    Outside the main thread (where Python cannot install signal handlers) this does nothing.
    The previous handler is restored on exit.
    """
    if threading.current_thread() is not threading.main_thread():
        yield
        return
    previous = signal.signal(signal.SIGTERM, _raise_terminated)
    try:
        yield
    finally:
        signal.signal(signal.SIGTERM, previous)


def interrupt_behind(exc: BaseException | None) -> KeyboardInterrupt | None:
    """The Ctrl-C or ``SIGTERM`` (:class:`Terminated`) behind ``exc``, if any.

    A signal handled while a compiled (numba) kernel is being called can surface as a
    ``SystemError`` ("returned a result with an exception set") whose cause is the
    interrupt; callers use this to report it as the interrupt it is.
    """
    seen: set[int] = set()
    while exc is not None and id(exc) not in seen:
        if isinstance(exc, KeyboardInterrupt):
            return exc
        seen.add(id(exc))
        exc = exc.__cause__ or exc.__context__
    return None


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
    from .errors import LidarsimError, PluginError

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
    """Make ``obj``'s run-time methods raise :class:`~lidarsim_core.errors.PluginError`
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


def _provider(registry: "Registry", kind: str, obj: Any) -> str | None:
    entry = registry.entries.get(kind, {}).get(getattr(obj, "name", ""))
    return entry.provider if entry is not None and entry.obj is type(obj) else None


def guard_components(sim: "Simulation", registry: "Registry | None" = None) -> "Simulation":
    """Guard every third-party component of a built :class:`~lidarsim_core.pipeline.Simulation`.

    Built-in components are left alone: a failure there is a lidarsim bug and is reported as
    such. Returns ``sim``.
    """
    from .plugins import BUILTIN_PROVIDER, get_registry

    registry = registry or get_registry()
    parts: list[tuple[str, Any]] = [("scan_pattern", sim.pattern), ("ray_backend", sim.backend),
                                    ("trajectory", sim.sensor_trajectory)]
    parts += [("noise_model", model) for model in sim.noise]
    parts += [("trajectory", target.trajectory) for target in sim.targets]
    for kind, obj in parts:
        provider = _provider(registry, kind, obj)
        if provider is not None and provider != BUILTIN_PROVIDER:
            guard_component(obj, kind, provider)
    return sim


def guard_exporter(exporter: Any, registry: "Registry | None" = None) -> Any:
    """Guard a third-party exporter instance (see :func:`guard_component`); returns it."""
    from .plugins import BUILTIN_PROVIDER, get_registry

    provider = _provider(registry or get_registry(), "exporter", exporter)
    if provider is not None and provider != BUILTIN_PROVIDER:
        guard_component(exporter, "exporter", provider)
    return exporter


# ---- impossible geometry -----------------------------------------------------------------
def _probe_directions() -> Any:
    import numpy as np

    # the 6 axes and the 8 cube diagonals, slightly skewed so that no probe runs exactly
    # along an edge or face of an axis-aligned box
    axes = np.vstack([np.eye(3), -np.eye(3)])
    diagonals = np.array([[x, y, z] for x in (-1, 1) for y in (-1, 1) for z in (-1, 1)], float)
    dirs = np.vstack([axes, diagonals]) + np.array([0.0123, -0.0071, 0.0049])
    return dirs / np.linalg.norm(dirs, axis=1, keepdims=True)


def check_sensor_outside(sim: "Simulation", frame: int) -> None:
    """Refuse a frame whose sensor is inside a closed target at the frame's start or end.

    The sensor counts as inside when probe rays in 14 directions all hit the target and all
    hit the back (inner) side of a face first, which is only possible from inside a closed,
    outward-oriented surface. Open meshes (a plate) and meshes with some inward faces never
    trigger it. A sensor outside the target's bounding box needs no probe.

    Raises
    ------
    ConfigError
        Naming the scenario file and the target's ``pose`` (or ``trajectory``) field.
    """
    import numpy as np

    from .errors import ConfigError

    scenario = sim.scenario
    t0, t1 = scenario.scan.frame_interval(frame)
    times = np.array([t0] if scenario.scan.motion == "frozen" else [t0, t1], dtype=np.float64)
    sensor_at = sim.sensor_trajectory.poses_at(times).position
    dirs = _probe_directions()
    for i, target in enumerate(sim.targets):
        poses = target.trajectory.poses_at(times)
        origins = poses.apply_inverse(sensor_at)
        lo, hi = target.mesh.bounds
        for t, origin in zip(times, origins):
            if (origin < lo).any() or (origin > hi).any():
                continue  # outside the bounding box: outside any closed surface, no probe
            hits = sim.backend.cast(target.mesh, np.repeat(origin[None, :], len(dirs), axis=0),
                                    dirs)
            if hits.hit.all() and (np.einsum("ij,ij->i", hits.normal, dirs) > 0).all():
                cfg = scenario.targets[i]
                field = f"targets.{i}.trajectory" if cfg.trajectory is not None else \
                    f"targets.{i}.pose"
                raise ConfigError(
                    f"the sensor is inside the closed target '{target.name}' at t = {t:g} s "
                    "(every probe ray meets the inner side of its surface); move the sensor "
                    "or the target", source=scenario.source, field=field)


# ---- the error boundary: output paths, OS errors, numerical warnings ------------------------
def describe_os_error(exc: OSError) -> str:
    """The reason of an OS error in words ("no space left on the device", ...)."""
    from .config_io import _describe

    return _describe(exc)


def os_error_line(exc: OSError) -> str:
    """One line for an OS error: the path (both, for a rename) and the reason."""
    paths = [str(p) for p in (exc.filename, exc.filename2) if p is not None]
    reason = describe_os_error(exc)
    return f"{' → '.join(paths)}: {reason}" if paths else reason


@contextmanager
def quiet_numerics() -> Iterator[None]:
    """While the block runs, NumPy floating-point warnings (overflow, invalid values) are not
    printed: inputs that would cause them are refused with a message of their own, and a
    warning line would break the one-line error contract of the CLI."""
    import warnings

    import numpy as np

    with warnings.catch_warnings(), np.errstate(all="ignore"):
        warnings.simplefilter("ignore", RuntimeWarning)
        yield
