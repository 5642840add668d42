"""``lidarsim bench``: ray-casting and pipeline throughput on the embedded Envisat scenes."""

from __future__ import annotations

import json
from typing import Any

import typer

from .app import app
from .errors import run_guarded
from .output import Column, print_table
from .output import console as make_console


@app.command()
def bench(as_json: bool = typer.Option(False, "--json", help="Print one JSON object."),
          quick: bool = typer.Option(False, "--quick",
                                     help="0.2 s scans, fewer repetitions (smoke test).")) -> None:
    """Rays/s of every backend, of bare Embree (1 and all threads) and of the whole pipeline."""
    run_guarded(lambda: _bench(as_json, quick))


def _rate(value: float | None) -> str:
    return "-" if value is None else f"{value / 1e6:.2f}M"


def _bench(as_json: bool, quick: bool) -> None:
    from ..bench.throughput import run_benchmark

    result = run_benchmark(quick=quick)
    if as_json:
        typer.echo(json.dumps(result, indent=2))
        return
    console = make_console()
    machine = result["machine"]
    console.print(f"[bold]lidarsim bench[/]: {machine['cpus']} CPUs, {machine['threads']} "
                  f"threads, NumPy {machine['numpy']}, embreex {machine['embreex'] or 'absent'}"
                  f", kernels {machine.get('kernels', 'numpy')}"
                  f"{' (quick)' if quick else ''}. Rays per second (M = million), best of "
                  "several runs.")
    scenes: dict[str, Any] = result["scenes"]
    names = sorted({b for s in scenes.values() for b in s["backends"]})
    threads = machine["threads"]
    # narrow enough for 80 columns; faces and rays of each scene are on its line below
    columns = [Column("scene", whole=True), Column("hit %", right=True)] + [
        Column(b, right=True) for b in names] + [
        Column(h, right=True) for h in ("bare 1t", f"bare {threads}t", "sim", "s/b")]
    rows = []
    for name, s in scenes.items():
        ratio = s["simulate_over_bare"]
        rows.append([name, f"{100 * (s['hit_fraction'] or 0):.1f}",
                     *[_rate(s["backends"].get(b)) for b in names],
                     _rate(s["bare_embree_1thread"]), _rate(s["bare_embree"]),
                     _rate(s["simulate"]), "-" if ratio is None else f"{ratio:.2f}"])
    print_table(columns, rows)
    console.print(f"sim: the whole simulation; s/b: sim over bare {threads}t")
    for name, s in scenes.items():
        console.print(f"{name}: {s['triangles']:,} faces, {s['rays']:,} rays")
    for name, s in scenes.items():
        single = ", ".join(f"{b} {_rate(v)}" for b, v in sorted(s["backends_1thread"].items()))
        cores = s.get("cores_used", {})
        busy = ", ".join(f"{k} {cores[k]:.2f}" for k in (*names, "bare_embree", "simulate")
                         if k in cores)
        speedup = ", ".join(f"{b} {v:.2f}x" for b, v in
                            sorted(s.get("backend_speedup_all_threads", {}).items()))
        console.print(f"{name} on one thread: {single}; simulate "
                      f"{_rate(s['simulate_1thread'])}. All threads over one: {speedup}. "
                      f"Cores kept busy: {busy}")
        stages = s.get("stages_1thread")
        if stages:
            parts = ", ".join(f"{k} {v:.0f}" for k, v in stages["ns_per_ray"].items())
            kept = stages["pulses_after_cull"]
            console.print(f"{name} pipeline stages on one thread, ns per ray: {parts}; "
                          f"pulses left after culling {100 * kept:.1f} %")
    div = result.get("divergence")
    if div:
        console.print(f"Beam divergence, {div['sub_rays']} sub-rays per pulse: "
                      f"{1e6 * div['time_per_pulse_s']:.2f} µs per pulse against "
                      f"{1e6 * div['time_per_k_single_rays_s']:.2f} µs for "
                      f"{div['sub_rays']} single rays (ratio {div['ratio']:.2f}).")
    if result.get("suite"):
        _print_suite(console, result["suite"], machine["threads"])
    console.print("backend columns: backend.cast on the scan's rays; bare: plain embreex on "
                  "the same rays in float32; simulate: Simulation.run_frame with the "
                  f"'{next(iter(scenes.values()))['simulate_backend']}' backend, from ray "
                  "indices to the point cloud. --json gives every figure.")


def _ratio(value: float | None) -> str:
    return "-" if value is None else f"{value:.2f}"


def _print_suite(console: Any, suite: dict[str, Any], threads: int) -> None:
    """The realistic scenes (:mod:`lidarsim_core.bench.suite`): a table, the stages and the
    issue's targets."""

    columns = [Column("scene", whole=True), Column("rays", right=True)] + [
        Column(h, right=True) for h in ("sim 1t", f"sim {threads}t", "bare 1t",
                                        f"bare {threads}t", "s/b 1t", f"s/b {threads}t")]
    rows = [[name, f"{s['rays_emitted']:,}", _rate(s["simulate_1thread"]), _rate(s["simulate"]),
             _rate(s["bare_embree_1thread"]), _rate(s["bare_embree"]),
             _ratio(s["simulate_over_bare_1thread"]), _ratio(s["simulate_over_bare"])]
            for name, s in suite["scenes"].items()]
    print_table(columns, rows, title="Realistic scenes: emitted rays per second (s/b: "
                                     "simulate over bare Embree)")
    for name, s in suite["scenes"].items():
        if s.get("simulate_over_packets") is not None:  # lidarsim's Embree binding
            console.print(f"{name}: bare Embree in packets through lidarsim's binding "
                          f"{_rate(s.get('bare_embree_packets_1thread'))} (1t), "
                          f"{_rate(s.get('bare_embree_packets'))} ({threads}t); simulate over "
                          f"it (s/p) {_ratio(s.get('simulate_over_packets_1thread'))} (1t), "
                          f"{_ratio(s['simulate_over_packets'])} ({threads}t)")
        stages = s.get("stages_1thread")
        if stages:
            parts = ", ".join(f"{k} {v:.0f}" for k, v in stages["ns_per_ray"].items())
            console.print(f"{name}: {s['description']}, {s['triangles']:,} faces. One thread, "
                          "ns per emitted ray: "
                          f"{parts}; pulses left after culling "
                          f"{100 * (stages['pulses_after_cull'] or 0):.1f} %")
            fused = stages.get("fused")
            if fused:  # the fast path's own parts (lidarsim_core.pipeline.fused)
                console.print("  fast path, ns per emitted ray: " + ", ".join(
                    f"{k} {v:.0f}" for k, v in fused.items() if k != "general_measurement")
                    + f" (the general path's measurement: {fused['general_measurement']:.0f})")
        if s.get("bare_over_compiled_1thread") is not None:
            console.print(f"  compiled kernels alone: {1e3 * s['compiled_1thread_s']:.2f} ms a "
                          "frame; bare over them "
                          f"{_ratio(s['bare_over_compiled_1thread'])} (the 1t s/b ceiling)")
    targets = suite.get("targets", {})
    console.print("Targets: lowest sim/bare "
                  f"{_ratio(targets.get('min_simulate_over_bare'))} (goal 0.5); tumbling over "
                  f"static {_ratio(targets.get('tumbling_over_static_rose'))} (rose), "
                  f"{_ratio(targets.get('tumbling_over_static_risley'))} (Risley), from a "
                  f"still sensor {_ratio(targets.get('tumbling_fixed_over_static_rose'))} "
                  f"(rose), {_ratio(targets.get('tumbling_fixed_over_static_risley'))} "
                  "(Risley) (goal 0.6); "
                  f"Risley over rose {_ratio(targets.get('risley_over_rose_static'))} "
                  "(goal 0.5).")
    data = suite.get("dataset")
    if data:
        console.print(f"Dataset, {data['frames']} frames of the tumbling scene: in memory "
                      f"{data['in_memory_frames_per_s']:.1f} frames/s, serial lidarsim "
                      f"dataset {data['dataset_frames_per_s']:.1f} frames/s (ratio "
                      f"{data['dataset_over_in_memory']:.2f}, goal 0.8).")
        cpu_ms = data.get("cpu_ms_per_frame")
        if cpu_ms:
            child = cpu_ms.get("writer_process")
            console.print(f"  CPU per frame: in memory {cpu_ms['in_memory']:.2f} ms, dataset "
                          f"{cpu_ms['dataset']:.2f} ms"
                          + ("." if child is None else f" + {child:.2f} ms in the writer "
                             "process."))
        if data.get("file_create_us") is not None:
            console.print(f"  Creating a file where it wrote: {data['file_create_us']:.0f} µs "
                          "(two a frame).")
    start = suite.get("startup")
    if start:
        console.print(f"A new process, from import to the demo's first frame: "
                      f"{start['import_to_first_frame_s']:.2f} s "
                      f"({start['import_to_first_frame_cpu_s']:.2f} s of CPU; goal 1 s).")
        if start.get("dependencies_s") is not None:
            console.print(f"  The libraries alone: {start['dependencies_s']:.2f} s (imports, "
                          f"numba's set-up); lidarsim: {start['lidarsim_s']:.2f} s.")
