"""Compiled kernels of the simulation hot path (optional; extra ``fast``, needs numba).

The pipeline is written in vectorised NumPy, and that code stays the reference. When numba is
installed, a few steps that NumPy cannot do at the speed of an Embree ray cast run as compiled
loops instead:

* :mod:`.philox`: the counter-based random numbers of :mod:`lidarsim_core.noise.rng`, bit for bit
  the same words as NumPy's ``Philox`` (integer arithmetic), but generated only for the rays
  asked for;
* :mod:`.ziggurat`: the ``ziggurat`` normal generator on the same words (Marsaglia & Tsang),
  bit for bit the NumPy reference of :mod:`lidarsim_core.noise.ziggurat`;
* :mod:`.rotation`: the seed paper's angular error (two rotations about axes perpendicular to
  the ray), the same arithmetic in the same order as the NumPy code;
* :mod:`.trig` and :mod:`.rose`: the rose pattern with a sine and cosine that LLVM can inline
  (within 2 ulp of the C library's);
* :mod:`.risley`: the Risley prisms' vector refraction, blocks of rays through every prism
  in one vectorised loop per prism;
  :mod:`.patterns`: firing schedules (time, slot, channel in one pass) and the spinning and
  Lissajous directions; :mod:`.groups`: the patterns' direction groups for culling before
  their directions;
* :mod:`.poses`: per-ray rotations of the built-in trajectories (chains of rotations at
  constant rates: tumbling, constant angular velocity; the look-at attitude);
* :mod:`.embree_cast`: Embree's ``rtcIntersect1``/``rtcIntersect4/8/16`` called by address
  (the Embree backend passes the addresses and the scene at run time), with the float64
  shift of each ray before it and the float64 distance refinement after it in the same loop;
* :mod:`.fused`: the seed paper's model after culling, around the cast (angular error with
  the inverse normal CDF, frame changes, closest target, range gate, range error, the
  record's points; :mod:`lidarsim_core.pipeline.fused`);
* :mod:`.cull`: a conservative test that skips pulses which cannot reach any target's
  bounding box, even after their angular error and beam divergence, before anything else is
  computed for them.

Environment variables
---------------------
``LIDARSIM_KERNELS``
    ``auto`` (default): use the kernels when numba can be imported; ``numba``: require them
    (an error names the missing package); ``numpy``: never use them.

Kernels are compiled on first use and cached on disk by numba (``NUMBA_CACHE_DIR`` moves the
cache), so only the first run on a machine pays the compile time (tens of seconds; compile
them up front with progress through :func:`warm_up`'s ``display``); a new process loads them
from the cache (:func:`cache_report` tells which were compiled and which loaded).
"""

from __future__ import annotations

import functools
import os
from typing import Any, Callable

from ..base.errors import ConfigError

#: Values accepted by ``LIDARSIM_KERNELS``.
MODES = ("auto", "numba", "numpy")


@functools.lru_cache(maxsize=1)
def numba_importable() -> bool:
    """Whether numba can be imported here (checked once; importing it takes ~0.3 s)."""
    try:
        import numba  # noqa: F401
    except ImportError:
        return False
    return True


def mode() -> str:
    """The kernel mode from ``LIDARSIM_KERNELS`` (validated)."""
    value = os.environ.get("LIDARSIM_KERNELS", "auto").strip().lower() or "auto"
    if value not in MODES:
        raise ConfigError(f"LIDARSIM_KERNELS must be one of {', '.join(MODES)}, not {value!r}",
                          source="environment", field="LIDARSIM_KERNELS")
    return value


def enabled() -> bool:
    """Whether the compiled kernels are used (see ``LIDARSIM_KERNELS``)."""
    selected = mode()
    if selected == "numpy":
        return False
    if numba_importable():
        return True
    if selected == "numba":
        raise ConfigError("LIDARSIM_KERNELS=numba but numba is not installed; "
                          "pip install 'lidarsim-core[fast]'", source="environment",
                          field="LIDARSIM_KERNELS")
    return False


#: A warm-up's progress callback: ``display(done, total, name)``, called before each kernel
#: is compiled or loaded (``done`` of ``total`` finished) and once more at the end.
Display = Callable[[int, int, str], None]


def _warm_up_calls() -> list[tuple[str, Callable[[], Any], Any]]:
    """``(name, call, dispatcher)`` for every kernel, with the argument types the pipeline
    passes."""
    import numpy as np

    from .cull import cull_by_grid, cull_by_grid_cones, cull_posed, direction_grid, motion_bound
    from .embree_cast import cast_faces, cast_refined
    from .fused import body_rays, closest_hit, measure, normals, ray_stage, ray_stage_drawn
    from .fused_cast import cast_closest
    from .groups import group_members, slot_groups
    from .patterns import cycle_rays, lissajous_directions, spinning_directions
    from .philox import ray_uniforms
    from .poses import chain_matrices, look_at_matrices
    from .raycast import embree_rays, refine_hits
    from .reflectance import reflectance_sum, reflectance_terms
    from .risley import risley_directions
    from .rose import rose_directions
    from .rotation import rotate_two_angles
    from .ziggurat import ray_normals as ziggurat_normals

    one = np.zeros((1, 3))
    one[0, 0] = 1.0
    index = np.zeros(1, dtype=np.int64)
    two = np.ones(2)
    box = np.array([[-1.0, -1.0, -1.0]])
    corners = np.ones((1, 8, 3))
    key = np.zeros(2, dtype=np.uint64)  # stream keys and the Ziggurat tables are read-only
    key.flags.writeable = False
    table = np.ones(257)
    table.flags.writeable = False
    return [
        ("philox", lambda: ray_uniforms(key, index, 1), ray_uniforms),
        ("ziggurat", lambda: ziggurat_normals(key, index, 1, table, table), ziggurat_normals),
        ("rose", lambda: rose_directions(index, 1.0, 4.0, 0.5, 1.0, 5.0, 0.0), rose_directions),
        ("schedule", lambda: cycle_rays(index, 1, 1.0, np.zeros(1),
                                        np.zeros(1, dtype=np.int16)), cycle_rays),
        ("spinning", lambda: spinning_directions(np.zeros(1), index, 1.0, 0.0, 1.0,
                                                 np.zeros(1), np.zeros(1)),
         spinning_directions),
        ("lissajous", lambda: lissajous_directions(np.zeros(1), 1.0, 0.0, 0.1, 1.0, 0.0, 0.1,
                                                   0.0), lissajous_directions),
        ("risley", lambda: risley_directions(np.zeros(1), np.zeros(1, dtype=np.int16), one,
                                             0.1 * two, two, two, two,
                                             np.array([True, False]), 1.5 * two),
         risley_directions),
        ("direction groups", lambda: slot_groups(0, 0, 1, 1), slot_groups),
        ("group members", lambda: group_members(index, index, index, 1, index), group_members),
        ("angular error", lambda: rotate_two_angles(one, np.zeros((1, 2))), rotate_two_angles),
        ("embree rays", lambda: embree_rays(one, one, np.zeros(3), 1.0, 1e-6), embree_rays),
        ("refinement", lambda: refine_hits(np.full(1, -1, dtype=np.int32), one, one, one, one,
                                           1e-6, np.empty(1, dtype=np.int64), np.empty(1),
                                           np.empty((1, 3)), 0), refine_hits),
        # no rays: compiled for the backend's argument types without calling Embree
        ("embree cast", lambda: cast_refined(0, 0, 16, 21, one, one, np.zeros(3), 1.0, 1e-6,
                                             one, one, np.empty(1, dtype=np.int64),
                                             np.empty(1), np.empty((1, 3)), 0, 0),
         cast_refined),
        ("embree faces", lambda: cast_faces(0, 0, 16, 21, np.zeros((0, 3), np.float32),
                                            np.zeros((0, 3), np.float32),
                                            np.empty(0, dtype=np.int32)), cast_faces),
        ("cull per pulse", lambda: cull_posed(
            one, np.eye(3)[None], one, np.eye(3)[None], one, index,
            np.zeros(1, dtype=np.bool_), box, -box, np.full(1, -1, dtype=np.int64), index, 0.0),
         cull_posed),
        ("motion bound", lambda: motion_bound(np.eye(3)[None], one, np.eye(3)[None], one, 0,
                                              1.0), motion_bound),
        ("cube map", lambda: direction_grid(corners, 4), direction_grid),
        ("cube map lookup", lambda: cull_by_grid(one, np.ones((6, 4, 4), dtype=np.uint8)),
         cull_by_grid),
        ("cube map and cones", lambda: cull_by_grid_cones(
            one, np.ones((6, 4, 4), dtype=np.uint8), True, 1, np.ones((1, 1, 3)),
            np.ones((1, 1))), cull_by_grid_cones),
        ("rotation chains", lambda: chain_matrices(np.zeros(1),
                                                   np.array([[0.0, 0.0, 0.0, 1.0]] * 2), one,
                                                   np.ones(1)), chain_matrices),
        ("look-at", lambda: look_at_matrices(one, np.zeros(3), np.array([0.0, 0.0, 1.0])),
         look_at_matrices),
        ("normals", lambda: normals(np.zeros(2, dtype=np.uint64), index, 2), normals),
        ("reflectance", lambda: reflectance_terms(np.zeros(1, dtype=np.int16), two[:1], two,
                                                  two, two, two), reflectance_terms),
        ("reflectance sum", lambda: reflectance_sum(
            two[:1].copy(), two[:1], np.zeros(1, dtype=np.int16), index, two[:1], two, two,
            index, two[:1], two, two), reflectance_sum),
        ("fused ray stage", lambda: ray_stage(one, index, np.zeros((1, 2), dtype=np.uint64),
                                              np.ones(1), np.eye(3)[None], np.empty((1, 3)),
                                              np.empty((1, 3))), ray_stage),
        ("fused ray stage, normals drawn", lambda: ray_stage_drawn(
            one, np.zeros((1, 1, 2)), np.ones(1), np.eye(3)[None], np.empty((1, 3)),
            np.empty((1, 3))), ray_stage_drawn),
        ("fused body rays", lambda: body_rays(one, one, one, np.eye(3)[None], np.empty((1, 3)),
                                              np.empty((1, 3))), body_rays),
        ("fused closest hit", lambda: closest_hit(
            0, np.ones(1), index, one, one, np.zeros(1, dtype=np.int32), 0, np.full(1, np.inf),
            np.full(1, -1, dtype=np.int16), np.full(1, -1, dtype=np.int64),
            np.full(1, -1, dtype=np.int16), np.zeros(1)), closest_hit),
        ("fused measure", lambda: measure(np.ones(1), np.zeros(1, dtype=np.int16), one, index,
                                          0.0, 2.0, np.zeros(1, dtype=np.int64),
                                          np.zeros((1, 2), dtype=np.uint64),
                                          np.ones((1, 2)), np.empty((1, 0))), measure),
        # no rays: compiled for the fast path's argument types without calling Embree
        ("fused embree cast", lambda: cast_closest(
            0, 0, 16, 21, np.empty((0, 3)), one, one, np.eye(3)[None], np.zeros(3), 1.0, 1e-6,
            one, one, np.zeros(1, dtype=np.int32), 0, 0, np.full(0, np.inf),
            np.full(0, -1, dtype=np.int16), np.full(0, -1, dtype=np.int64),
            np.full(0, -1, dtype=np.int16), np.zeros(0)), cast_closest),
    ]


def warm_up(display: Display | None = None) -> bool:
    """Compile (or load from numba's cache) every kernel now, so that the first simulation is
    not timed with it; returns whether the kernels are in use.

    Parameters
    ----------
    display
        Called as ``display(done, total, name)`` before each kernel and once at the end
        (``done == total``), so that a first run on a machine, which compiles every kernel
        (tens of seconds), shows progress; later runs load them from the disk cache in a
        fraction of a second (:func:`cache_report`).
    """
    if not enabled():
        return False
    calls = _warm_up_calls()
    for done, (name, call, _) in enumerate(calls):
        if display is not None:
            display(done, len(calls), name)
        call()
    if display is not None:
        display(len(calls), len(calls), "")
    return True


def cache_report() -> dict[str, Any]:
    """What this process's kernels came from, once they ran (e.g. after :func:`warm_up`):
    ``{"compiled": [...], "loaded": [...]}`` kernel names (compiled here, or loaded from
    numba's disk cache), and the cache ``directory``."""
    compiled, loaded, directory = [], [], None
    for name, _, dispatcher in _warm_up_calls():
        stats = dispatcher.stats
        directory = directory or stats.cache_path
        if sum(stats.cache_misses.values()):
            compiled.append(name)
        elif sum(stats.cache_hits.values()):
            loaded.append(name)
    return {"compiled": compiled, "loaded": loaded, "directory": directory}


def describe() -> str:
    """``numba x.y`` when the kernels are in use, else ``numpy``."""
    if not enabled():
        return "numpy"
    import numba

    return f"numba {numba.__version__}"
