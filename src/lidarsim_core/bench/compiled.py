"""How much of a frame the compiled kernels take: the floor a frame would reach on one thread
if every Python and NumPy step around them were free.

numba's dispatchers report their calls to Python's profiler, so :mod:`cProfile` charges each
kernel call to the kernel's own function, its time spent in compiled code (and the few
microseconds of the dispatcher's type check). The benchmark sets that against bare Embree's
time on the same rays: ``bare_over_compiled_1thread`` is the highest ``simulate_over_bare``
one thread could reach with the kernels as they are (docs/performance.md, "The compiled
kernels' ceiling").
"""

from __future__ import annotations

import cProfile
import pstats
import time
from pathlib import Path
from typing import Any

#: The kernels' folder: a profiled function defined in one of its modules (its package's
#: ``__init__``, plain Python, aside) is a compiled kernel.
_KERNELS = Path(__file__).resolve().parents[1] / "kernels"


def _compiled_seconds(stats: pstats.Stats) -> float:
    total = 0.0
    for (filename, _, _), (_, _, own, _, _) in stats.stats.items():  # type: ignore[attr-defined]
        path = Path(filename)
        if path.parent == _KERNELS and path.name != "__init__.py":
            total += own
    return total


def compiled_share(sim: Any, frame: int = 0, rounds: int = 3) -> dict[str, float]:
    """``frame`` of ``sim`` run ``rounds`` times under :mod:`cProfile` on the calling thread
    (run it with one worker thread: the profiler sees only its own thread): in the round
    where the kernels took least, ``compiled_s``, their own time, and ``profiled_frame_s``,
    the whole frame's (slowed by the profiler's cost on every Python call, so only
    ``compiled_s`` is a floor)."""
    best: dict[str, float] | None = None
    for _ in range(rounds):
        profile = cProfile.Profile()
        start = time.perf_counter()
        profile.enable()
        sim.run_frame(frame)
        profile.disable()
        whole = time.perf_counter() - start
        compiled = _compiled_seconds(pstats.Stats(profile))
        if best is None or compiled < best["compiled_s"]:
            best = {"compiled_s": compiled, "profiled_frame_s": whole}
    assert best is not None
    return best
