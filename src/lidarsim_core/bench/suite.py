"""The realistic scenes of ``lidarsim bench``: whole simulation against bare Embree, per scene.

Each scene is a scenario this project exists for (:data:`SUITE`): a tumbling Envisat seen by
the Risley MID-70 from an HCW hold, a fly-around with a moving and turning sensor, a VLP-16
circling the target, the 256 × 256 flash, beam divergence with detection and dual returns, two
targets, a ~1M-triangle mesh, and the static demo they are compared with. For each scene, in
interleaved rounds (:func:`lidarsim_core.bench.timing.interleaved_best`) after as many
interleaved rounds that are not timed as the simulation's first frames need to choose between
its threads and its calling thread (:mod:`lidarsim_core.pipeline.balance`):

* ``simulate`` / ``simulate_1thread``: ``Simulation.run_frame`` of frame 0, emitted rays per
  second (pulses; with beam divergence each pulse is K cast rays), on all threads and on one;
* ``bare_embree`` / ``bare_embree_1thread``: plain embreex in float32 casting exactly the rays
  the simulation casts (every pulse, or every sub-ray, in each target's body frame), with no
  lidarsim code around it, per emitted ray;
* ``simulate_over_bare`` / ``simulate_over_bare_1thread``: their ratios (1 would be a
  simulation as fast as Embree alone on the same rays);
* ``bare_embree_packets`` (``_1thread``) and ``simulate_over_packets`` (``_1thread``): the
  same rays through the fastest call of lidarsim's Embree binding (packets of 16 rays where
  the CPU traces them natively; :func:`lidarsim_core.bench.timing.packet_embree_probe`), and
  the simulation over it;
* ``stages_1thread``: nanoseconds per emitted ray of each stage on one thread (pattern, poses,
  cull, cast, measurement, record; :func:`suite_stages`), and where the scene runs the fast
  path (:mod:`lidarsim_core.pipeline.fused`), its own parts under ``fused`` (:func:`fused_stages`);
* ``compiled_1thread_s``: the compiled kernels' own time in the frame on one thread
  (:func:`lidarsim_core.bench.compiled.compiled_share`), and ``bare_over_compiled_1thread``,
  bare Embree's time over it: the highest ``simulate_over_bare_1thread`` the kernels allow.

:func:`bench_dataset` compares a serial ``lidarsim dataset`` run on a tumbling sequence with
simulating the same frames in memory.
"""

from __future__ import annotations

import os
import tempfile
import time
from pathlib import Path
from typing import Any, Callable

import numpy as np

from ..base.threads import worker_threads
from ..pipeline.cast import process_piece, pulse_frames
from .compiled import compiled_share
from .startup import bench_startup
from .timing import (add_packet_columns, bare_embree_probe, interleaved_best,
                     packet_embree_probe, threads_env, with_threads)

#: Envisat's LVLH tumbling in 2013 (2.67 °/s about the orbit anti-normal), as in
#: ``examples/scenarios/envisat_tumbling_hold.yaml``.
ENVISAT_2013 = {"kind": "tumbling", "position_m": [0, 0, 0], "euler_deg": [-90, 0, -90],
                "symmetry_axis": [0, 1, 0], "angular_momentum_axis": [0, 0, -1],
                "spin_rate_deg_s": 2.67, "orbit": {"altitude_km": 780}}
ORBIT = {"altitude_km": 780}
ENVISAT_LVLH_POSE = {"position_m": [0, 0, 0], "euler_deg": [90, 0, -90]}


def _envisat(detail: str = "medium", **where: Any) -> dict[str, Any]:
    return {"name": "envisat", "mesh": {"model": "envisat", "options": {"detail": detail}},
            **where}


def _hcw(sensor: str, position: list[float], segment: dict[str, Any]) -> dict[str, Any]:
    return {"datasheet": sensor, "trajectory": {
        "kind": "hcw", "orbit": ORBIT, "position_m": position, "segments": [segment],
        "attitude": {"mode": "look_at", "point_m": [0, 0, 0], "up": [0, 0, 1]}}}


def _scene_static(duration: float) -> dict[str, Any]:
    from ..scenario.demo import demo_scenario

    return demo_scenario(duration_s=duration).model_dump(mode="json")


def _scene_static_risley(duration: float) -> dict[str, Any]:
    from ..scenario.demo import demo_scenario

    return demo_scenario(duration_s=duration, sensor="livox-mid70").model_dump(mode="json")


def _scene_tumbling(sensor: str) -> Callable[[float], dict[str, Any]]:
    def build(duration: float) -> dict[str, Any]:
        return {"seed": 2013,
                "sensor": _hcw(sensor, [0, 30, 0], {"type": "hold", "duration_s": 600}),
                "targets": [_envisat(trajectory=ENVISAT_2013)],
                "scan": {"duration_s": duration}}
    return build


def _scene_tumbling_fixed(sensor: str) -> Callable[[float], dict[str, Any]]:
    def build(duration: float) -> dict[str, Any]:
        # the sensor still at the origin, Envisat's body origin 31 m ahead; 15 s into the
        # tumble its bounding box is nearer than its own size (28 m)
        return {"seed": 2013,
                "sensor": {"datasheet": sensor, "pose": {"position_m": [0, 0, 0]}},
                "targets": [_envisat(trajectory={**ENVISAT_2013, "position_m": [31, 0, 0]})],
                "scan": {"duration_s": duration, "start_s": 15.0}}
    return build


def _scene_flyaround(duration: float) -> dict[str, Any]:
    # start a quarter of the way round, where the chaser moves fastest across the target
    return {"seed": 50,
            "sensor": _hcw("livox-mid70", [0, 50, 0], {"type": "fly_around", "orbits": 1,
                                                       "out_of_plane": True}),
            "targets": [_envisat(pose=ENVISAT_LVLH_POSE)],
            "scan": {"duration_s": duration, "start_s": 1500.0}}


def _scene_vlp16(duration: float) -> dict[str, Any]:
    return {"seed": 16,
            "sensor": _hcw("velodyne-vlp16", [0, 15, 0], {"type": "fly_around", "orbits": 1,
                                                          "out_of_plane": True}),
            "targets": [_envisat(pose=ENVISAT_LVLH_POSE)],
            "scan": {"duration_s": duration / 3.0}}  # 300k points/s: ~the MID-70's rays


def _scene_flash(duration: float) -> dict[str, Any]:
    data = _scene_static(1.0)
    data["sensor"]["datasheet"] = "ball-vns-flash"
    data["scan"] = {"duration_s": 1.0 / 30.0}  # one flash: 256 × 256 rays
    return data


def _scene_divergence(duration: float) -> dict[str, Any]:
    data = _scene_static(duration)
    data["sensor"]["beam"] = {"sub_rays": 7}
    data["sensor"]["detection"] = {}
    data["sensor"]["returns"] = {"mode": "dual"}
    return data


def _scene_two_targets(duration: float) -> dict[str, Any]:
    # examples/scenarios/two_targets.yaml: Envisat 40 m ahead, a tumbling box crossing at 25 m
    return {"seed": 2, "sensor": {"datasheet": "livox-mid70-rose",
                                  "pose": {"position_m": [0, 0, 0]}},
            "targets": [
                _envisat(pose={"position_m": [40, -2, 0], "euler_deg": [-90, 0, 90]}),
                {"name": "debris", "mesh": {"model": "box", "options": {
                    "extents_m": [1.2, 0.8, 0.4]}},
                 "trajectory": {"kind": "constant_velocity", "position_m": [25, -4, 0],
                                "velocity_m_s": [0, 2, 0], "euler_deg": [0, 0, 0],
                                "angular_velocity_deg_s": [10, 20, 20]}}],
            "scan": {"duration_s": duration}}


def _scene_mesh_1m(duration: float) -> dict[str, Any]:
    data = _scene_static(duration)
    data["targets"][0]["mesh"] = {"path": str(_million_triangle_mesh())}
    return data


_MESH_CACHE: dict[str, Path] = {}


def _million_triangle_mesh() -> Path:
    """The fine Envisat (~96k triangles) subdivided twice (~1.5M), as a binary PLY in a
    temporary directory kept for the process."""
    path = _MESH_CACHE.get("mesh")
    if path is None or not path.is_file():
        import trimesh

        from ..plugins.manager import get_registry

        model = get_registry().get("target_model", "envisat").from_config({"detail": "fine"})
        mesh = model.mesh()
        vertices, faces = mesh.vertices, mesh.faces
        for _ in range(2):
            vertices, faces = trimesh.remesh.subdivide(vertices, faces)
        folder = Path(tempfile.mkdtemp(prefix="lidarsim-bench-"))
        path = folder / "envisat_1m.ply"
        trimesh.Trimesh(vertices, faces, process=False).export(path)
        _MESH_CACHE["mesh"] = path
    return path


#: The suite: name → (description, scenario builder taking the scan duration of the rose
#: scenes in seconds).
SUITE: dict[str, tuple[str, Callable[[float], dict[str, Any]]]] = {
    "static-demo": ("Envisat 30 m, MID-70 rose, static (the demo)", _scene_static),
    "static-risley": ("the demo with the Risley MID-70", _scene_static_risley),
    "tumbling-risley": ("Envisat tumbling at 2.67 °/s (2013), Risley MID-70, HCW hold at 30 m",
                        _scene_tumbling("livox-mid70")),
    "tumbling-rose": ("the tumbling Envisat with the MID-70 rose",
                      _scene_tumbling("livox-mid70-rose")),
    "tumbling-fixed-risley": ("Envisat tumbling 31 m ahead of a still Risley MID-70",
                              _scene_tumbling_fixed("livox-mid70")),
    "tumbling-fixed-rose": ("the tumbling Envisat ahead of a still MID-70 rose",
                            _scene_tumbling_fixed("livox-mid70-rose")),
    "flyaround-50m": ("50 m out-of-plane fly-around, sensor moving and turning (look-at)",
                      _scene_flyaround),
    "vlp16-circling-15m": ("VLP-16 circling Envisat at 15 m (HCW fly-around)", _scene_vlp16),
    "flash-256": ("256 × 256 flash (Ball VNS class), one frame", _scene_flash),
    "divergence-7": ("demo with 7 sub-rays per pulse, detection and dual returns",
                     _scene_divergence),
    "two-targets": ("Envisat and a tumbling box moving across (examples/two_targets)",
                    _scene_two_targets),
    "mesh-1m": ("demo with a ~1.5M-triangle Envisat", _scene_mesh_1m),
}


def cast_rays(sim: Any, frame: int = 0) -> list[tuple[Any, np.ndarray, np.ndarray]]:
    """Every ray the simulation casts in ``frame``, without culling: per target its mesh and
    the (sub-)rays' origins and directions in its body frame, as
    :func:`lidarsim_core.pipeline.cast.cast_piece` forms them."""
    k0, k1 = sim.frame_rays(frame)
    batch = sim.pattern.rays_for_indices(np.arange(k0, k1, dtype=np.int64))
    t_frame = sim.scenario.scan.frame_interval(frame)[0]
    _, _, bodies, _ = pulse_frames(sim.context, batch, sim.context.noise_contexts(frame), t_frame)
    out = []
    for target, (origin, vecs) in zip(sim.targets, bodies):
        if sim.sub_rays is None:
            directions = vecs[0]
        else:
            directions = sim.sub_rays.directions(*vecs)
            if len(origin) > 1:
                origin = np.repeat(origin, sim.rays_per_pulse, axis=0)
        out.append((target.mesh, np.ascontiguousarray(np.broadcast_to(origin, directions.shape)),
                    np.ascontiguousarray(directions)))
    return out


def suite_stages(sim: Any, frame: int = 0, rounds: int = 3) -> dict[str, Any]:
    """Nanoseconds per emitted ray of each stage of ``frame`` on one thread, the whole frame
    as one piece (best of ``rounds``).

    ``pattern``: the scan pattern's rays (for a pattern that groups its rays by direction,
    the groups, their representatives and the rays of the groups kept); ``poses``: the sensor's and targets' poses at the
    pulses kept by the cull (at every pulse when a trajectory gives no rate bounds;
    :func:`lidarsim_core.pipeline.posing.with_piece_poses`); ``cull``: which pulses may reach
    a target (:func:`lidarsim_core.pipeline.cull.culled_with_poses`); ``cast``: ``backend.cast`` of the remaining (sub-)rays on every target;
    ``measurement``: the rest of the per-pulse work (angular error, frame changes, returns,
    detection, range error, the record's columns); ``record``: assembling the point cloud
    and its metadata.
    """
    from ..pipeline.cull import culled_with_poses, pattern_candidates
    from ..pipeline.posing import with_piece_poses
    from ..records.pointcloud import PointCloud

    k0, k1 = sim.frame_rays(frame)
    n = k1 - k0
    t_frame = sim.scenario.scan.frame_interval(frame)[0]
    contexts = sim.context.noise_contexts(frame)
    index = np.arange(k0, k1, dtype=np.int64)
    # a pattern that groups its rays by direction computes the groups' representatives and
    # then the rays of the groups that may reach a target only
    grouped = None if sim.culler is None else sim.pattern.direction_groups(index)
    representatives = None if grouped is None else \
        sim.pattern.rays_for_indices(grouped.representative)
    candidates = pattern_candidates(sim.context, sim.culler, index, t_frame, grouped,
                                    representatives)
    batch = sim.pattern.rays_for_indices(candidates)
    kept = culled_with_poses(sim.context, sim.culler, batch, t_frame)
    # the pipeline's order: cull on the pattern's rays, then pose the pulses kept (or, for
    # trajectories without rate bounds, pose every pulse and cull on the posed batch)
    early = None if sim.culler is None else sim.culler.keep_before_poses(sim.context, batch,
                                                                        t_frame)
    to_pose = batch if early is None else batch.take(early)
    posed = with_piece_poses(sim.context, batch, t_frame)
    _, _, bodies, _ = pulse_frames(sim.context, kept, contexts, t_frame)
    rays = []
    for target, (origin, vecs) in zip(sim.targets, bodies):
        d = vecs[0] if sim.sub_rays is None else sim.sub_rays.directions(*vecs)
        if sim.sub_rays is not None and len(origin) > 1:
            origin = np.repeat(origin, sim.rays_per_pulse, axis=0)
        rays.append((target.mesh, np.broadcast_to(origin, d.shape), d))
    columns = process_piece(sim.context, sim.stages, kept, contexts, t_frame, frame)

    probes = {
        "pattern": lambda: sim.pattern.rays_for_indices(index) if grouped is None else (
            sim.pattern.direction_groups(index),
            sim.pattern.rays_for_indices(grouped.representative),
            sim.pattern.rays_for_indices(candidates)),
        "poses": lambda: with_piece_poses(sim.context, to_pose, t_frame),
        "cull": lambda: None if sim.culler is None else (
            None if grouped is None else pattern_candidates(
                sim.context, sim.culler, index, t_frame, grouped, representatives),
            sim.culler.keep(sim.context, posed, t_frame) if early is None else
            sim.culler.keep_before_poses(sim.context, batch, t_frame)),
        "cast": lambda: [sim.backend.cast(mesh, o, d) for mesh, o, d in rays],
        "process": lambda: process_piece(sim.context, sim.stages, kept, contexts, t_frame, frame),
        "record": lambda: PointCloud.concatenate([columns], sim.frame_info(frame)),
    }
    fused = sim.fused
    if fused is not None:  # the pipeline's piece: the fast path (the general one is "general")
        probes["process"] = lambda: fused.process(kept, contexts, t_frame)
        probes["general"] = lambda: process_piece(sim.context, sim.stages, kept, contexts,
                                                  t_frame, frame)
    best = with_threads(1, lambda: interleaved_best(probes, rounds)[0])
    ns = {key: 1e9 * seconds / n for key, seconds in best.items()}
    process = ns.pop("process")
    ns["measurement"] = max(0.0, process - ns["cast"])
    out: dict[str, Any] = {"ns_per_ray": {key: ns[key] for key in
                                          ("pattern", "poses", "cull", "cast", "measurement",
                                           "record")},
                           "pulses_after_cull": len(kept) / n if n else None}
    if fused is not None:
        out["fused"] = fused_stages(fused, kept, contexts, t_frame, n, rounds)
        out["fused"]["general_measurement"] = max(0.0, ns["general"] - ns["cast"])
    return out


def fused_stages(fused: Any, batch: Any, contexts: list[Any], t_frame: float, emitted: int,
                 rounds: int = 3) -> dict[str, float]:
    """Nanoseconds per emitted ray of each part of the fast path on one piece
    (:class:`lidarsim_core.pipeline.fused.FusedPath`), one thread: ``before_cast`` (angular
    error and frame changes), ``cast`` (the backend on every target), ``closest`` (closest
    target, face, part, incidence) — or, when the cast runs inside the compiled loop
    (Embree through its binding), ``cast_in_loop`` (body-frame rays, Embree's packets, the
    float64 refinement and the closest target, every target) in place of both —, ``measure`` (range gate, range error, points) and
    ``columns`` (the other record columns, in NumPy)."""
    rays = fused.before_cast(batch, contexts, t_frame)
    if fused.compiled is not None:  # the cast inside the compiled loop: cast and closest
        best = fused.cast_closest(rays)
        returned = fused.measure(rays, best, contexts)
        probes = {
            "before_cast": lambda: fused.before_cast(batch, contexts, t_frame),
            "cast_in_loop": lambda: fused.cast_closest(rays),
            "measure": lambda: fused.measure(rays, best, contexts),
            "columns": lambda: fused.columns(rays, best, returned, t_frame),
        }
    else:
        hits = fused.cast(rays)
        best = fused.closest(rays, hits)
        returned = fused.measure(rays, best, contexts)
        probes = {
            "before_cast": lambda: fused.before_cast(batch, contexts, t_frame),
            "cast": lambda: fused.cast(rays),
            "closest": lambda: fused.closest(rays, hits),
            "measure": lambda: fused.measure(rays, best, contexts),
            "columns": lambda: fused.columns(rays, best, returned, t_frame),
        }
    seconds = with_threads(1, lambda: interleaved_best(probes, rounds)[0])
    return {key: 1e9 * value / emitted if emitted else 0.0 for key, value in seconds.items()}


def bench_suite_scene(name: str, *, duration_s: float = 1.0, rounds: int = 5,
                      stages: bool = True) -> dict[str, Any]:
    """Benchmark one scene of :data:`SUITE` (see the module docstring)."""
    from ..pipeline.balance import SPANS_TO_CHOOSE
    from ..pipeline.simulation import Simulation
    from ..scenario.load import scenario_from_dict

    description, build = SUITE[name]
    sim = Simulation(scenario_from_dict(build(duration_s), source=f"<bench {name}>"))
    for target in sim.targets:
        sim.backend.prepared(target.mesh)
    k0, k1 = sim.frame_rays(0)
    emitted = k1 - k0
    cast = cast_rays(sim)
    threads = worker_threads()
    probes: dict[str, Callable[[], Any]] = {
        "simulate": lambda: sim.run_frame(0),
        "simulate_1thread": threads_env(1, lambda: sim.run_frame(0)),
    }
    for label, count, probe in (
            ("bare_embree_1thread", 1, bare_embree_probe),
            ("bare_embree", threads, bare_embree_probe),
            ("bare_embree_packets_1thread", 1, packet_embree_probe),
            ("bare_embree_packets", threads, packet_embree_probe)):
        parts = [probe(mesh, o, d, count) for mesh, o, d in cast]
        if all(p is not None for p in parts):
            probes[label] = lambda parts=parts: [p() for p in parts]
    # the simulation's first frames try its threads and its calling thread in turn
    # (:mod:`lidarsim_core.pipeline.balance`): they are the warm-up rounds, interleaved with
    # the other probes as the timed rounds are, so that the plan chooses in their conditions
    best, cores = interleaved_best(probes, rounds, warmup=SPANS_TO_CHOOSE)
    rate = {key: emitted / seconds for key, seconds in best.items()}
    result: dict[str, Any] = {
        "description": description, "backend": sim.backend.name,
        "sensor": sim.sensor.name, "triangles": int(sum(t.mesh.n_faces for t in sim.targets)),
        "rays_emitted": int(emitted), "rays_cast": int(sum(len(o) for _, o, _ in cast)),
        "rays_per_pulse": sim.rays_per_pulse, "threads": threads,
        "simulate": rate["simulate"], "simulate_1thread": rate["simulate_1thread"],
        "bare_embree": rate.get("bare_embree"),
        "bare_embree_1thread": rate.get("bare_embree_1thread"),
        "cores_used": {key: round(value, 2) for key, value in cores.items()}}
    for suffix in ("", "_1thread"):
        bare = result[f"bare_embree{suffix}"]
        result[f"simulate_over_bare{suffix}"] = \
            result[f"simulate{suffix}"] / bare if bare else None
    add_packet_columns(result, rate)
    if stages:
        result["stages_1thread"] = suite_stages(sim, rounds=max(2, rounds // 2))
        # the compiled kernels' own time: the floor of a frame on one thread
        floor = threads_env(1, lambda: compiled_share(sim, rounds=max(2, rounds)))()
        result["compiled_1thread_s"] = floor["compiled_s"]
        result["profiled_frame_1thread_s"] = floor["profiled_frame_s"]
        bare = result["bare_embree_1thread"]
        result["bare_over_compiled_1thread"] = \
            emitted / bare / floor["compiled_s"] if bare and floor["compiled_s"] > 0 else None
    return result


def suite_targets(scenes: dict[str, dict[str, Any]]) -> dict[str, Any]:
    """The issue's targets from the suite's figures (None where a scene is missing): every
    ``simulate_over_bare`` ≥ 0.5 (all threads and one), tumbling ≥ 0.6 × static with the
    same sensor (rose and Risley; from an HCW hold and from a still sensor), Risley static ≥ 0.5 × rose static."""
    def ratio(a: str, b: str, key: str = "simulate") -> float | None:
        if a in scenes and b in scenes and scenes[b].get(key):
            return scenes[a][key] / scenes[b][key]
        return None

    ratios = [s.get(f"simulate_over_bare{x}") for s in scenes.values() for x in ("", "_1thread")]
    known = [r for r in ratios if r is not None]
    return {"min_simulate_over_bare": min(known) if known else None,
            "tumbling_over_static_rose": ratio("tumbling-rose", "static-demo"),
            "tumbling_over_static_risley": ratio("tumbling-risley", "static-risley"),
            "tumbling_fixed_over_static_rose": ratio("tumbling-fixed-rose", "static-demo"),
            "tumbling_fixed_over_static_risley": ratio("tumbling-fixed-risley",
                                                       "static-risley"),
            "risley_over_rose_static": ratio("static-risley", "static-demo")}


def run_suite(*, quick: bool = False, scenes: list[str] | None = None) -> dict[str, Any]:
    """Every scene of :data:`SUITE` (or ``scenes``), the dataset throughput and a new
    process's start (:func:`lidarsim_core.bench.startup.bench_startup`):
    ``{"scenes": {NAME: {...}}, "targets": {...}, "dataset": {...}, "startup": {...}}``. ``quick``: 0.1 s scans
    and two rounds, no 1M-triangle mesh, a 20-frame dataset."""
    names = scenes or [n for n in SUITE if not (quick and n == "mesh-1m")]
    duration, rounds = (0.1, 2) if quick else (1.0, 5)
    results = {name: bench_suite_scene(name, duration_s=duration, rounds=rounds)
               for name in names}
    return {"duration_s": duration, "rounds": rounds, "scenes": results,
            "targets": suite_targets(results),
            "dataset": bench_dataset(frames=20 if quick else 200, rounds=2 if quick else 3),
            "startup": bench_startup(rounds=1 if quick else 3)}


def _file_create_us(folder: Path, files: int = 64) -> float:
    """The median time (µs) to create an empty file in a new ``folder`` (``O_EXCL``, then
    closed): what the file system charges for each of a dataset frame's two files, which
    bounds the writer process when it is slow (docs/performance.md, "One write a frame, the
    collector, and the file system"). The files stay until the folder goes."""
    folder.mkdir()
    times = []
    for i in range(files):
        start = time.perf_counter()
        os.close(os.open(folder / f"f{i}", os.O_WRONLY | os.O_CREAT | os.O_EXCL, 0o644))
        times.append(time.perf_counter() - start)
    return round(1e6 * float(np.median(times)), 1)


def bench_dataset(*, frames: int = 200, rounds: int = 3) -> dict[str, Any]:
    """Frames per second of a tumbling sequence (:data:`SUITE`'s ``tumbling-risley``, 0.1 s
    frames at 10 Hz): simulated in memory (``Simulation.run_frame`` of every frame) and
    written by a serial ``lidarsim dataset`` run (binary PLY files, checksums, sidecars,
    manifest; a fresh directory each round); best of ``rounds`` interleaved runs, and the
    least CPU time (all threads, user and system) per frame of each, the dataset's writer
    process apart (``writer_process``, :mod:`lidarsim_core.dataset.writer_process`; in 10 ms
    ticks), and ``file_create_us``, what creating a file costs where the rounds write
    (:func:`_file_create_us`).

    The rounds' directories are removed after the last round, not between rounds: removing
    them is no part of writing a dataset, and on a file system that checks every new file
    against the inodes freed in the last seconds (ext4 without a journal, as on the project's
    test machine) a round that follows the removal of 400 files pays 0.2–1 ms per file it
    creates instead of ~0.02 ms (docs/performance.md, "Datasets")."""
    import shutil

    from ..dataset.generate import generate_dataset
    from ..dataset.writer_process import writer_process
    from ..pipeline.simulation import Simulation
    from ..scenario.load import scenario_from_dict

    data = _scene_tumbling("livox-mid70")(0.1)
    data["scan"] = {"duration_s": 0.1, "frame_rate_hz": 10, "frames": frames}
    scenario = scenario_from_dict(data, source="<bench dataset>")
    sim = Simulation(scenario)
    folder = Path(tempfile.mkdtemp(prefix="lidarsim-bench-dataset-"))
    runs = iter(range(10 ** 6))
    cpu: dict[str, list[float]] = {"in_memory": [], "dataset": [], "writer_process": []}

    def in_memory() -> None:
        start = time.process_time()
        for frame in range(frames):
            sim.run_frame(frame)
        cpu["in_memory"].append(time.process_time() - start)

    def dataset() -> None:
        child = writer_process(start=False)
        start, child_start = time.process_time(), child and child.cpu_seconds()
        generate_dataset(scenario, folder / f"run{next(runs)}")
        cpu["dataset"].append(time.process_time() - start)
        child = writer_process(start=False)
        child_end = child and child.cpu_seconds()
        if child_end is not None:  # the writer process's time (started in the first round)
            cpu["writer_process"].append(child_end - (child_start or 0.0))

    try:
        create_us = _file_create_us(folder / "probe")
        best, cores = interleaved_best({"in_memory": in_memory, "dataset": dataset}, rounds)
    finally:
        shutil.rmtree(folder, ignore_errors=True)
    result = {"scene": "tumbling-risley", "frames": frames, "frame_s": 0.1,
              "in_memory_frames_per_s": frames / best["in_memory"],
              "dataset_frames_per_s": frames / best["dataset"],
              "cores_used": {key: round(value, 2) for key, value in cores.items()},
              "cpu_ms_per_frame": {key: round(1e3 * min(values[1:]) / frames, 3)
                                   for key, values in cpu.items() if values[1:]},
              "file_create_us": create_us}
    result["dataset_over_in_memory"] = \
        result["dataset_frames_per_s"] / result["in_memory_frames_per_s"]
    return result
