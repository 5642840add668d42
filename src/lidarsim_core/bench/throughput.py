"""Throughput benchmark: every ray backend, bare Embree and the whole pipeline on the same rays.

Scenes are the embedded demo (Envisat 30 m in front of a Livox MID-70, rose pattern, with the
datasheet's errors) at two levels of detail: ``envisat`` (medium, ~10k triangles) and
``envisat-fine`` (~96k triangles); and ``envisat-close``, the medium model 12 m away, where
most rays hit. For each scene the rays of one scan, exactly as the
pipeline casts them (pattern, angular error, frame changes into Envisat's body frame), are
timed through:

* every available registered backend (``backends``: rays per second of ``backend.cast`` on a
  prepared mesh; ``backends_1thread`` with ``LIDARSIM_THREADS=1``);
* bare embreex on those rays in float32, on one thread and on all threads, with no lidarsim
  code around it (``bare_embree_1thread``, ``bare_embree``): what the hardware can do;
* the whole simulation, ``Simulation.run_frame`` with the ``auto`` backend, from ray indices
  to the finished point cloud (``simulate``; ``simulate_1thread`` with ``LIDARSIM_THREADS=1``,
  ``simulate_by_backend`` for every backend, ``simulate_noiseless`` without the noise
  models), and its ratio to bare Embree on all threads (``simulate_over_bare``);
* ``cores_used``: the average number of cores each of these kept busy (process CPU time over
  wall time); ``backend_speedup_all_threads``: each backend's rate on all threads over its
  rate on one;
* ``stages_1thread``: nanoseconds per ray of each pipeline stage on one thread, and the
  fraction of pulses left after culling (:func:`pipeline_stages`).

``machine.kernels`` says whether the compiled kernels ran (:mod:`lidarsim_core.kernels`);
``machine.embree_binding`` what Embree library the binding loaded
(:mod:`lidarsim_core.backends.embree4`).

The cost of beam divergence (``divergence``): the demo scan with the link-budget detection
model, once with K sub-rays per pulse (``sensor.beam``) and once with one ray per pulse over a
scan K times longer (K times as many pulses); ``ratio`` is the time per pulse with K sub-rays
over the time of K independent single rays. Sub-rays go through the same vectorised casting
path as pulses, so the ratio stays near or below 1 (frame changes and noise are paid once per
pulse, not per sub-ray).

Most rays of the demo scan miss Envisat (``hit_fraction`` ≈ 0.11), and a miss is cheap for
every backend; ``backends_hits_only`` gives each backend's rate on the rays that hit.

Each figure is the shortest of several runs, interleaved with the other figures' runs
(:func:`interleaved_best`), so that load from other work on a shared machine biases no figure
against another.
"""

from __future__ import annotations

import os
import platform
import time
from typing import Any, Callable

import numpy as np

from .. import kernels
from ..base.threads import worker_threads
from ..pipeline.balance import SPANS_TO_CHOOSE
from ..pipeline.cast import body_rays, process_piece
from .timing import (bare_embree_probe, binding_description, interleaved_best, threads_env,
                     with_threads)

#: Benchmark scenes: name → Envisat model detail, or detail and distance (default 30 m).
SCENES: dict[str, str | dict[str, Any]] = {
    "envisat": "medium", "envisat-fine": "fine",
    # Envisat 12 m away fills most of the field of view: most rays hit, and the ray cast,
    # not the pipeline around it, dominates
    "envisat-close": {"detail": "medium", "range_m": 12.0}}




def scan_rays(sim: Any, frame: int = 0) -> tuple[np.ndarray, np.ndarray]:
    """Origins and directions of every ray of ``frame`` in the first target's body frame,
    exactly as :class:`~lidarsim_core.pipeline.simulation.Simulation` casts them."""
    k0, k1 = sim.frame_rays(frame)
    batch = sim.pattern.rays_for_indices(np.arange(k0, k1, dtype=np.int64))
    t_frame = sim.scenario.scan.frame_interval(frame)[0]
    _, bodies = body_rays(sim.context, batch, sim.context.noise_contexts(frame), t_frame)
    origins, directions = bodies[0]
    return np.ascontiguousarray(origins), np.ascontiguousarray(directions)




def pipeline_stages(sim: Any, frame: int = 0, rounds: int = 5) -> dict[str, Any]:
    """Where the pipeline's time goes, on one thread: nanoseconds per emitted ray of each
    stage of a frame (best of ``rounds``), and the fraction of pulses left after culling.

    ``pattern``: the scan pattern's rays; ``cull``: deciding which pulses may reach a target
    (:mod:`lidarsim_core.pipeline.cull`); ``cast``: ``backend.cast`` of the remaining pulses;
    ``rest``: everything else of :func:`lidarsim_core.pipeline.cast.process_piece` on
    them (angular error, frame changes, returns, range error, the point record), or of the
    fast path (:mod:`lidarsim_core.pipeline.fused`) where the scenario runs it.
    """
    k0, k1 = sim.frame_rays(frame)
    n = k1 - k0
    t_frame = sim.scenario.scan.frame_interval(frame)[0]
    contexts = sim.context.noise_contexts(frame)
    index = np.arange(k0, k1, dtype=np.int64)
    batch = sim.pattern.rays_for_indices(index)
    kept = batch if sim.culler is None else batch.take(sim.culler.keep(sim.context, batch, t_frame))
    _, bodies = body_rays(sim.context, kept, contexts, t_frame)
    target = sim.targets[0].mesh

    def pattern() -> Any:
        return sim.pattern.rays_for_indices(index)

    def cull() -> Any:
        return None if sim.culler is None else sim.culler.keep(sim.context, batch, t_frame)

    def cast() -> Any:
        return sim.backend.cast(target, *bodies[0])

    def process() -> Any:  # the path the pipeline takes: the fast one where it applies
        if sim.fused is not None:
            return sim.fused.process(kept, contexts, t_frame)
        return process_piece(sim.context, sim.stages, kept, contexts, t_frame, frame)

    def run() -> dict[str, float]:
        return interleaved_best({"pattern": pattern, "cull": cull, "cast": cast,
                                 "process": process}, rounds)[0]

    best = with_threads(1, run)
    ns = {key: 1e9 * seconds / n for key, seconds in best.items()}
    return {"ns_per_ray": {"pattern": ns["pattern"], "cull": ns["cull"], "cast": ns["cast"],
                           "rest": max(0.0, ns["process"] - ns["cast"])},
            "pulses_after_cull": len(kept) / n if n else None}




def _core_label(probe: str) -> str:
    """The name in ``cores_used`` of a probe of :func:`bench_scene`."""
    kind, _, backend = probe.partition(":")
    labels = {"backend": backend, "backend1": f"{backend}_1thread",
              "simulate": f"simulate_{backend}" if backend else "simulate",
              "simulate1": "simulate_1thread", "noiseless": "simulate_noiseless",
              "bare": "bare_embree", "bare1": "bare_embree_1thread"}
    return labels[kind]




def bench_scene(detail: str, *, duration_s: float = 1.0, rounds: int = 12,
                range_m: float | None = None) -> dict[str, Any]:
    """Benchmark one Envisat scene (see the module docstring for the figures); every figure
    is the best of ``rounds`` interleaved runs (:func:`interleaved_best`)."""
    from ..pipeline.simulation import Simulation
    from ..plugins.manager import get_registry
    from ..scenario.demo import demo_scenario

    def simulation(backend: str, noise: bool = True) -> Any:
        extra = {} if range_m is None else {"range_m": range_m}
        run = Simulation(demo_scenario(duration_s=duration_s, detail=detail, backend=backend,
                                       noise=noise, **extra))
        for target in run.targets:
            run.backend.prepared(target.mesh)
        return run

    sim = simulation("auto")
    mesh = sim.targets[0].mesh
    origins, directions = scan_rays(sim)
    n = len(origins)
    threads = worker_threads()
    result: dict[str, Any] = {"triangles": int(mesh.n_faces), "rays": int(n),
                              "duration_s": duration_s, "threads": threads,
                              "range_m": range_m or 30.0}
    probes: dict[str, Callable[[], Any]] = {}
    rays: dict[str, int] = {}
    build: dict[str, float] = {}
    hit_fraction = None
    for entry in get_registry().iter("ray_backend"):
        if not entry.obj.is_available()[0]:
            continue
        name, backend = entry.name, entry.obj.from_config({})
        start = time.perf_counter()
        backend.prepare(mesh)
        build[name] = time.perf_counter() - start
        backend.prepared(mesh)
        hit = backend.cast(mesh, origins, directions).hit
        hit_fraction = float(hit.mean())
        o_hit, d_hit = origins[hit], directions[hit]

        def cast(b: Any = backend, o: np.ndarray = origins, d: np.ndarray = directions) -> Any:
            return b.cast(mesh, o, d)

        probes[f"backend:{name}"], rays[f"backend:{name}"] = cast, n
        probes[f"backend1:{name}"], rays[f"backend1:{name}"] = threads_env(1, cast), n
        # the same on the rays that hit: most of a scan misses the satellite
        probes[f"hits:{name}"] = lambda b=backend, o=o_hit, d=d_hit: b.cast(mesh, o, d)
        rays[f"hits:{name}"] = len(o_hit)
        if name != sim.backend.name:
            probes[f"simulate:{name}"] = lambda run=simulation(name): run.run_frame(0)
            rays[f"simulate:{name}"] = n
    for label, count in (("bare1", 1), ("bare", threads)):
        probe = bare_embree_probe(mesh, origins, directions, count)
        if probe is not None:
            probes[label], rays[label] = probe, n
    probes["simulate"], rays["simulate"] = (lambda: sim.run_frame(0)), n
    probes["simulate1"] = threads_env(1, lambda: sim.run_frame(0))
    rays["simulate1"] = n
    noiseless = simulation("auto", noise=False)
    probes["noiseless"], rays["noiseless"] = (lambda: noiseless.run_frame(0)), n
    # as many untimed rounds as the simulations' first frames need to choose between their
    # threads and their calling thread (lidarsim_core.pipeline.balance)
    best, cores = interleaved_best(probes, rounds, warmup=SPANS_TO_CHOOSE)
    rate = {key: rays[key] / seconds for key, seconds in best.items()}

    def prefixed(prefix: str) -> dict[str, float]:
        return {k.split(":", 1)[1]: v for k, v in rate.items() if k.startswith(prefix + ":")}

    result.update({
        "hit_fraction": hit_fraction, "backends": prefixed("backend"),
        "backends_1thread": prefixed("backend1"), "backends_hits_only": prefixed("hits"),
        "build_s": build, "bare_embree_1thread": rate.get("bare1"),
        "bare_embree": rate.get("bare"), "simulate_backend": sim.backend.name,
        "simulate": rate["simulate"], "simulate_1thread": rate["simulate1"],
        "simulate_noiseless": rate["noiseless"],
        "cores_used": {_core_label(key): round(c, 2) for key, c in cores.items()
                       if not key.startswith("hits:")},
        "simulate_by_backend": {**prefixed("simulate"), sim.backend.name: rate["simulate"]},
    })
    bare = result["bare_embree"]
    result["simulate_over_bare"] = result["simulate"] / bare if bare else None
    result["backend_speedup_all_threads"] = {
        name: rate / result["backends_1thread"][name]
        for name, rate in result["backends"].items() if result["backends_1thread"].get(name)}
    result["stages_1thread"] = pipeline_stages(sim)
    return result


def bench_divergence(detail: str, *, duration_s: float = 0.2, sub_rays: int = 16,
                     rounds: int = 5) -> dict[str, Any]:
    """Time per pulse with ``sub_rays`` sub-rays against ``sub_rays`` independent single rays
    (see the module docstring); best of ``rounds`` interleaved runs."""
    from ..pipeline.simulation import Simulation
    from ..scenario.demo import demo_scenario
    from ..scenario.load import scenario_from_dict

    def simulation(duration: float, beam: bool) -> Any:
        data = demo_scenario(duration_s=duration, detail=detail).model_dump()
        data["sensor"]["detection"] = {}
        if beam:
            data["sensor"]["beam"] = {"sub_rays": sub_rays}
        run = Simulation(scenario_from_dict(data, source="<bench>"))
        for target in run.targets:
            run.backend.prepared(target.mesh)
        return run

    div = simulation(duration_s, True)
    single = simulation(duration_s * sub_rays, False)
    pulses = div.frame_rays(0)[1] - div.frame_rays(0)[0]
    rays = single.frame_rays(0)[1] - single.frame_rays(0)[0]
    best, _ = interleaved_best({"divergence": lambda: div.run_frame(0),
                                "single": lambda: single.run_frame(0)}, rounds)
    per_pulse = best["divergence"] / pulses
    per_k_rays = sub_rays * best["single"] / rays
    return {"sub_rays": sub_rays, "pulses": int(pulses), "single_rays": int(rays),
            "time_per_pulse_s": per_pulse, "time_per_k_single_rays_s": per_k_rays,
            "ratio": per_pulse / per_k_rays}


def run_benchmark(*, quick: bool = False, scenes: dict[str, str] | None = None,
                  duration_s: float | None = None,
                  suite: bool | list[str] | None = None) -> dict[str, Any]:
    """Benchmark every scene; ``quick`` scans 0.2 s with fewer repetitions (a smoke test).

    ``scenes`` (name → Envisat detail, or a mapping with ``detail`` and ``range_m``) and
    ``duration_s`` override :data:`SCENES` and the scan time. ``suite``: the realistic scenes
    of :mod:`lidarsim_core.bench.suite` (True: all, or a list of names; default: all unless
    ``scenes`` is given), under the key ``suite``.

    Returns
    -------
    dict
        ``{"machine": {...}, "scenes": {SCENE: {"triangles", "rays", "backends": {NAME:
        rays_per_s}, "bare_embree_1thread", "bare_embree", "simulate",
        "simulate_over_bare", ...}}, "divergence": {"sub_rays", "time_per_pulse_s",
        "time_per_k_single_rays_s", "ratio", ...}}`` (divergence on the first scene);
        Embree figures are None without embreex.
    """
    from .._version import __version__

    try:
        import embreex

        embree_version = getattr(embreex, "__version__", "installed")
    except ImportError:
        embree_version = None
    machine = {"cpus": os.cpu_count(), "threads": worker_threads(),
               "python": platform.python_version(), "numpy": np.__version__,
               "embreex": embree_version, "kernels": kernels.describe(),
               "embree_binding": binding_description(),
               "lidarsim": __version__,
               "processor": platform.processor() or platform.machine()}
    duration, rounds = (0.2, 3) if quick else (1.0, 12)
    duration = duration_s or duration
    specs = {name: {"detail": spec} if isinstance(spec, str) else dict(spec)
             for name, spec in (scenes or SCENES).items()}
    result = {"machine": machine, "quick": quick,
              "scenes": {name: bench_scene(spec["detail"], duration_s=duration, rounds=rounds,
                                           range_m=spec.get("range_m"))
                         for name, spec in specs.items()},
              "divergence": bench_divergence(next(iter(specs.values()))["detail"],
                                             duration_s=min(duration, 0.2),
                                             rounds=max(2, rounds // 2))}
    if suite is None:
        suite = scenes is None
    if suite:
        from .suite import run_suite

        result["suite"] = run_suite(quick=quick,
                                    scenes=None if suite is True else list(suite))
    return result
