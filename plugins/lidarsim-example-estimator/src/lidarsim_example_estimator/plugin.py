"""The plugin: the user's function wrapped as a lidarsim pose estimator in a few lines."""

from pydantic import Field

from lidarsim_core.base.components import ComponentOptions
from lidarsim_core.hookspecs import hookimpl


class Options(ComponentOptions):
    """Options users give as ``--option KEY=VALUE``."""

    model_points: int = Field(50_000, ge=100, description="Points sampled over the mesh.")
    max_distance_m: float = Field(1.0, gt=0, description="Largest pairing distance (m).")


def my_tracker(frame, options):
    """Point-to-point ICP from the previous estimate (principal axes on the first frame)."""
    from .registration import icp, principal_axes_guess

    model, _ = frame.model.sample_points(options.model_points)
    previous = frame.previous
    start = previous.matrix() if previous is not None and previous.success else \
        principal_axes_guess(frame.xyz, model)
    pose, paired = icp(frame.xyz, model, start, max_distance=options.max_distance_m)
    return pose if paired > 0.5 else None  # None: no estimate for this frame


@hookimpl
def lidarsim_register_pose_estimators(register):
    from lidarsim_core.evaluate import function_estimator

    register(function_estimator("example-tracker", my_tracker, options=Options))
