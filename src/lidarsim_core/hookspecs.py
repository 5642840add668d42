"""Every pluggy hook that lidarsim calls, documented.

A plugin is a module or object with functions decorated by :data:`hookimpl` whose names are the
hook names below. Every hook is a *registration* hook: lidarsim calls it once, when the registry
is first needed, with a ``register`` callable; the plugin calls ``register`` once per thing it
provides. Registration must be cheap: register classes, never instances, and never import heavy
optional dependencies (embreex, pyvista, laspy, ...) while registering; import them inside the
methods that need them.

Plugin components (patterns, noise models, backends, exporters, target models, trajectories,
pose estimators) are classes with

``name: ClassVar[str]``
    the name users write in scenarios and on the command line (lower-case, ``[a-z0-9_-]+``);
``Options: ClassVar[type[pydantic.BaseModel]]``
    the pydantic model of their options (configure it with ``extra="forbid"`` so unknown keys are
    rejected; :class:`lidarsim_core.base.components.ComponentOptions` does that);
``__init__(self, options)``
    taking a validated ``Options`` instance.

See :mod:`lidarsim_core.base.components` for the base classes of each kind. Third-party plugins are
found through the ``lidarsim`` entry-point group::

    [project.entry-points.lidarsim]
    my_sensor_pack = "my_package.lidarsim_plugin"
"""

from __future__ import annotations

from typing import Any, Callable

import pluggy

PROJECT_NAME = "lidarsim"

hookspec = pluggy.HookspecMarker(PROJECT_NAME)
hookimpl = pluggy.HookimplMarker(PROJECT_NAME)

Register = Callable[[Any], None]


@hookspec
def lidarsim_register_sensors(register: Register) -> None:
    """Register sensor datasheets.

    Parameters
    ----------
    register
        Call ``register(source)`` once per sensor, where ``source`` is a
        :class:`lidarsim_core.scenario.datasheet.SensorDatasheet`, a path to a datasheet YAML file, or a
        path to a directory whose ``*.yaml`` files are all datasheets. Paths are read lazily,
        the first time the catalogue is listed or a sensor is looked up.

    Examples
    --------
    >>> from importlib.resources import files
    >>> @hookimpl
    ... def lidarsim_register_sensors(register):
    ...     register(files("my_vendor_pack") / "sensors")
    """


@hookspec
def lidarsim_register_scan_patterns(register: Register) -> None:
    """Register scan patterns.

    Parameters
    ----------
    register
        Call ``register(cls)`` with a subclass of :class:`lidarsim_core.patterns.base.ScanPattern`.
        ``cls.name`` is the name a datasheet's ``scan_pattern.name`` refers to.
    """


@hookspec
def lidarsim_register_noise_models(register: Register) -> None:
    """Register measurement-noise models.

    Parameters
    ----------
    register
        Call ``register(cls)`` with a subclass of :class:`lidarsim_core.noise.base.NoiseModel`.
        A scenario's ``noise`` list names them in the order they are applied.
    """


@hookspec
def lidarsim_register_ray_backends(register: Register) -> None:
    """Register ray-casting backends.

    Parameters
    ----------
    register
        Call ``register(cls)`` with a subclass of :class:`lidarsim_core.backends.base.RayBackend`.
        Every backend must pass the conformance suite in :mod:`lidarsim_core.testing`.
    """


@hookspec
def lidarsim_register_exporters(register: Register) -> None:
    """Register point-cloud file writers.

    Parameters
    ----------
    register
        Call ``register(cls)`` with a subclass of :class:`lidarsim_core.io.base.Exporter`.
        ``cls.suffixes`` lists the file suffixes that select it (e.g. ``(".ply",)``).
    """


@hookspec
def lidarsim_register_target_models(register: Register) -> None:
    """Register procedural target models (meshes built in code, such as ``envisat``).

    Parameters
    ----------
    register
        Call ``register(cls)`` with a subclass of :class:`lidarsim_core.scene.targets.TargetModel`.
        Scenarios use them as ``mesh: {model: NAME, options: {...}}``.
    """


@hookspec
def lidarsim_register_trajectories(register: Register) -> None:
    """Register trajectory kinds (how a sensor or target pose evolves with time).

    Parameters
    ----------
    register
        Call ``register(cls)`` with a subclass of
        :class:`lidarsim_core.trajectories.base.Trajectory`. Scenarios use them as
        ``trajectory: {kind: NAME, ...options}``.
    """


@hookspec
def lidarsim_register_pose_estimators(register: Register) -> None:
    """Register pose estimators, scored by ``lidarsim evaluate`` (docs/evaluate.md).

    Parameters
    ----------
    register
        Call ``register(cls)`` with a subclass of
        :class:`lidarsim_core.evaluate.base.PoseEstimator`. Its ``estimate(frame)`` gets one
        frame's points (sensor frame, per-point timestamps, the whole point record), the
        target's mesh in its body frame and the previous frame's estimate (``None`` on the
        first frame) as a :class:`~lidarsim_core.evaluate.base.FrameInput`, and returns the
        target's pose in the sensor frame as a
        :class:`~lidarsim_core.evaluate.base.PoseEstimate` (optionally with a fitness and a
        covariance) or :meth:`~lidarsim_core.evaluate.base.PoseEstimate.failure`. The harness
        times each call. ``lidarsim evaluate --estimator NAME`` uses ``cls.name``.
    """
