"""Benchmark the two normal generators: ``inverse_cdf`` (the seed paper's stream) against
``ziggurat`` (Marsaglia & Tsang on the same Philox words).

Run from the repository root::

    python benchmarks/bench_normals.py [--rays 1048576] [--rounds 11] [--duration 1.0]
    python benchmarks/bench_normals.py --stats 1000000000   # + a long statistical check

Every figure is the best of ``--rounds`` interleaved rounds (lidarsim_core.bench.timing
.interleaved_best), so the ratios within one run are fair on a shared machine. It prints:

* ns per normal of :func:`lidarsim_core.noise.rng.ray_normals` for ``--rays`` rays × 2 draws
  (the angular error's draw), with the compiled kernels (Philox in numba, then SciPy's
  ``ndtri`` for the inverse CDF; the whole Ziggurat in numba) and with the NumPy reference;
  the Philox uniforms alone (the words' cost, a floor for both) beside them;
* the demo frame (``lidarsim demo``'s scene, ``--duration`` s scan, the datasheet's angular and
  range errors) with ``normals: inverse_cdf`` and ``normals: ziggurat``, on one thread and on
  all threads: the time of ``Simulation.run_frame`` and the ratio;
* with ``--stats N``: N Ziggurat normals (40 seeds × 25 frames of one stream) summed up
  against the normal law: the mean, the variance and the fraction of negatives as z-scores,
  the counts beyond 3–6σ against their expectation with exact binomial p-values (a check
  far beyond the tests' 4·10^6 draws: 10^9 take about a minute).
"""

from __future__ import annotations

import argparse
import os
import sys
from pathlib import Path

import numpy as np

sys.path.insert(0, str(Path(__file__).resolve().parents[1] / "src"))

from lidarsim_core import kernels  # noqa: E402
from lidarsim_core.bench.timing import interleaved_best, with_threads  # noqa: E402
from lidarsim_core.noise import rng  # noqa: E402
from lidarsim_core.pipeline import Simulation  # noqa: E402
from lidarsim_core.scenario import demo_scenario  # noqa: E402


def _with_kernels(mode: str, func):  # noqa: ANN001, ANN202
    def probe():  # noqa: ANN202
        before = os.environ.get("LIDARSIM_KERNELS")
        os.environ["LIDARSIM_KERNELS"] = mode
        try:
            return func()
        finally:
            if before is None:
                del os.environ["LIDARSIM_KERNELS"]
            else:
                os.environ["LIDARSIM_KERNELS"] = before
    return probe


def per_normal(rays: int, rounds: int) -> dict[str, float]:
    """ns per normal of each generator (and of the uniforms alone), compiled and NumPy."""
    index = np.arange(rays, dtype=np.int64)
    draws = 2
    probes = {}
    modes = ["numba", "numpy"] if kernels.numba_importable() else ["numpy"]
    for mode in modes:
        probes[f"{mode} uniforms"] = _with_kernels(
            mode, lambda: rng.ray_uniforms(7, 0, "noise.0.angular", index, draws))
        for generator in rng.NORMAL_GENERATORS:
            probes[f"{mode} {generator}"] = _with_kernels(
                mode, lambda g=generator: rng.ray_normals(7, 0, "noise.0.angular", index,
                                                          draws, g))
    best, _ = interleaved_best(probes, rounds)
    return {name: 1e9 * t / (rays * draws) for name, t in best.items()}


def demo_frames(duration: float, rounds: int) -> dict[str, float]:
    """Best run_frame time (s) of the demo with each generator, 1 thread and all threads."""
    base = demo_scenario(duration_s=duration)
    sims = {g: Simulation(base.with_updates(normals=g)) for g in rng.NORMAL_GENERATORS}
    probes = {}
    for threads in (1, None):
        label = "1 thread" if threads == 1 else "all threads"
        for generator, sim in sims.items():
            probes[f"{label} {generator}"] = (
                lambda s=sim, t=threads: with_threads(t, lambda: s.run_frame(0)))
    best, _ = interleaved_best(probes, rounds)
    return best


def statistics(total: int) -> None:
    """Print the moments and tail counts of ``total`` Ziggurat normals (see module doc)."""
    from scipy import stats

    per = max(4, total // 1000) // 4  # 40 seeds × 25 frames, 4 draws per ray
    count, s1, s2, negative = 0, 0.0, 0.0, 0
    beyond = dict.fromkeys((3, 4, 5, 6), 0)
    for seed in range(300, 340):
        for frame in range(25):
            z = rng.ray_normals(seed, frame, "big", np.arange(per), 4, "ziggurat").ravel()
            count += z.size
            s1 += float(z.sum())
            s2 += float((z * z).sum())
            negative += int((z < 0).sum())
            for k in beyond:
                beyond[k] += int((np.abs(z) > k).sum())
    print(f"\n{count:,} Ziggurat normals: mean z-score {s1 / np.sqrt(count):+.2f}, "
          f"variance z-score {(s2 / count - 1) / np.sqrt(2 / count):+.2f}, "
          f"negatives z-score {(negative / count - 0.5) / np.sqrt(0.25 / count):+.2f}")
    for k, seen in beyond.items():
        p = 2 * stats.norm.sf(k)
        print(f"  |z| > {k}: {seen:,} (expected {count * p:,.1f}), binomial p = "
              f"{stats.binomtest(seen, count, p).pvalue:.3f}")


def main() -> None:
    parser = argparse.ArgumentParser(description=__doc__.splitlines()[0])
    parser.add_argument("--rays", type=int, default=1 << 20)
    parser.add_argument("--rounds", type=int, default=11)
    parser.add_argument("--duration", type=float, default=1.0)
    parser.add_argument("--stats", type=int, default=0, metavar="N",
                        help="also check N Ziggurat normals' moments and tails")
    args = parser.parse_args()
    kernels.warm_up()
    print(f"ns per normal ({args.rays:,} rays × 2 draws, best of {args.rounds} interleaved "
          f"rounds, one thread)")
    ns = per_normal(args.rays, args.rounds)
    for name, value in ns.items():
        print(f"  {name:<22} {value:7.2f} ns")
    for mode in ("numba", "numpy"):
        if f"{mode} ziggurat" in ns:
            print(f"  {mode}: ziggurat / inverse_cdf = "
                  f"{ns[f'{mode} ziggurat'] / ns[f'{mode} inverse_cdf']:.3f}")
    print(f"\ndemo frame ({args.duration:g} s scan, best of {args.rounds} interleaved rounds)")
    frames = demo_frames(args.duration, args.rounds)
    for name, value in frames.items():
        print(f"  {name:<26} {1e3 * value:8.2f} ms")
    for label in ("1 thread", "all threads"):
        ratio = frames[f"{label} inverse_cdf"] / frames[f"{label} ziggurat"]
        print(f"  {label}: inverse_cdf time / ziggurat time = {ratio:.3f}")
    if args.stats:
        statistics(args.stats)


if __name__ == "__main__":
    main()
