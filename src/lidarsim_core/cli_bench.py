"""``lidarsim bench``: ray-casting and pipeline throughput on the embedded Envisat scenes."""

from __future__ import annotations

import json
from typing import Any

import typer

from .cli import app, run_guarded


@app.command()
def bench(as_json: bool = typer.Option(False, "--json", help="Print one JSON object."),
          quick: bool = typer.Option(False, "--quick",
                                     help="0.2 s scans, fewer repetitions (smoke test).")) -> None:
    """Rays/s of every backend, of bare Embree (1 and all threads) and of the whole pipeline."""
    run_guarded(lambda: _bench(as_json, quick))


def _rate(value: float | None) -> str:
    return "-" if value is None else f"{value / 1e6:.2f}M"


def _bench(as_json: bool, quick: bool) -> None:
    from .bench import run_benchmark

    result = run_benchmark(quick=quick)
    if as_json:
        typer.echo(json.dumps(result, indent=2))
        return
    from rich.console import Console
    from rich.table import Table

    console = Console(highlight=False, width=max(112, Console().width))
    machine = result["machine"]
    console.print(f"[bold]lidarsim bench[/]: {machine['cpus']} CPUs, {machine['threads']} "
                  f"threads, NumPy {machine['numpy']}, embreex {machine['embreex'] or 'absent'}"
                  f", kernels {machine.get('kernels', 'numpy')}"
                  f"{' (quick)' if quick else ''}. Rays per second (M = million), best of "
                  "several runs.")
    scenes: dict[str, Any] = result["scenes"]
    names = sorted({b for s in scenes.values() for b in s["backends"]})
    table = Table(show_edge=False)
    columns = ["scene", "faces", "rays", "hit %"] + names + [
        "bare 1t", f"bare {machine['threads']}t", "simulate", "sim/bare"]
    for col in columns:
        table.add_column(col, justify="left" if col == "scene" else "right", no_wrap=True)
    for name, s in scenes.items():
        ratio = s["simulate_over_bare"]
        table.add_row(name, f"{s['triangles']:,}", f"{s['rays']:,}",
                      f"{100 * (s['hit_fraction'] or 0):.1f}",
                      *[_rate(s["backends"].get(b)) for b in names],
                      _rate(s["bare_embree_1thread"]), _rate(s["bare_embree"]),
                      _rate(s["simulate"]), "-" if ratio is None else f"{ratio:.2f}")
    console.print(table)
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
    console.print("backend columns: backend.cast on the scan's rays; bare: plain embreex on "
                  "the same rays in float32; simulate: Simulation.run_frame with the "
                  f"'{next(iter(scenes.values()))['simulate_backend']}' backend, from ray "
                  "indices to the point cloud. --json gives every figure.")
