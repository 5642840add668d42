"""Benchmark training sets (issue 23): samples/s read next to frames/s simulated, and the file
count of a 10,000-frame sharded layout.

Run from the repository root::

    python benchmarks/bench_training.py [--sequences 10] [--layout-frames 10000]

Read vs simulate: ``examples/datasets/training.yaml`` drawn with ``--sequences`` sequences
(20 frames each) is generated serially into a temporary directory; frames/s simulated is the
generation's frame loop (``DatasetResult.elapsed_s``: simulate, sample, write the shards).
Then ``ls.open_dataset`` reads every train sample twice in a shuffled order (the second pass
is reported: the page cache holds the shards, as on a training machine after the first
epoch), in this process, one sample at a time.

Layout: a cheap scene (a 1 m box in front of a 4 × 4-pixel flash sensor) drawn as 10
sequences of ``--layout-frames / 10`` frames, sharded at 1,000 frames; the benchmark counts the
shard files and every file of the directory.
"""

from __future__ import annotations

import argparse
import tempfile
import time
from pathlib import Path

import numpy as np
import yaml

import lidarsim_core as ls
from lidarsim_core.dataset import generate_dataset

ROOT = Path(__file__).resolve().parents[1]

def cheap_scene() -> dict:
    """A 1 m box 20 m in front of a 4 × 4-pixel flash sensor (the VNS-class flash datasheet,
    shrunk)."""
    sheet = yaml.safe_load((ROOT / "sensors" / "ball-vns-flash.yaml").read_text())
    sheet.update(name="tiny-flash", fov_h_deg=10.0, fov_v_deg=10.0, point_rate_hz=480)
    sheet["scan_pattern"]["options"].update(rows=4, columns=4)
    return {
        "seed": 0,
        "sensor": {"datasheet": sheet,
                   "trajectory": {"kind": "static", "position_m": [0, 0, 0]}},
        "targets": [{"name": "box",
                     "mesh": {"model": "box", "options": {"extents_m": [1, 1, 1]}},
                     "trajectory": {"kind": "static", "position_m": [20, 0, 0]}}],
        "scan": {"duration_s": 1 / 30, "frame_rate_hz": 30, "frames": 10},
        "backend": "numpy",
    }


def read_vs_simulate(sequences: int) -> None:
    with tempfile.TemporaryDirectory() as tmp:
        out = Path(tmp) / "ds"
        result = generate_dataset(ROOT / "examples" / "datasets" / "training.yaml", out,
                                  sequences=sequences)
        simulated = result.frames_written / result.elapsed_s
        ds = ls.open_dataset(out, split="train")
        order = np.random.default_rng(0).permutation(len(ds))
        rates = []
        for _ in range(2):
            start = time.perf_counter()
            for i in order:
                ds[int(i)]
            rates.append(len(order) / (time.perf_counter() - start))
        print(f"simulated: {result.frames_written} frames in {result.elapsed_s:.1f} s = "
              f"{simulated:.1f} frames/s (generation: simulate, sample, write shards)")
        print(f"read: {len(order)} train samples, first pass {rates[0]:.0f} samples/s, "
              f"second pass {rates[1]:.0f} samples/s")
        print(f"read / simulate: {rates[1] / simulated:.0f}x")


def layout(frames: int) -> None:
    with tempfile.TemporaryDirectory() as tmp:
        tmp_path = Path(tmp)
        (tmp_path / "scene.yaml").write_text(yaml.safe_dump(cheap_scene(), sort_keys=False))
        data = {"seed": 1, "format": "shards",
                "sequences": [{"scenario": "scene.yaml", "name": "box", "count": 10,
                               "frames": frames // 10,
                               "randomize": {"targets.0.trajectory.position_m":
                                             {"vector": [{"uniform": [10, 50]}, 0, 0]}}}],
                "samples": {"points": 16, "shard_frames": 1000}}
        (tmp_path / "ds.yaml").write_text(yaml.safe_dump(data, sort_keys=False))
        out = tmp_path / "ds"
        result = generate_dataset(tmp_path / "ds.yaml", out)
        shards = sorted((out / "shards").iterdir())
        every = [p for p in out.rglob("*") if p.is_file()]
        print(f"layout: {result.frames_total} frames in {result.elapsed_s:.1f} s, "
              f"{len(shards)} shard files ({len(shards) / result.frames_total * 1000:.2f} per "
              f"1,000 frames), {len(every)} files in all (the shards, manifest.json, splits.json, "
              f"sequences.tar and the hidden lock file)")
        assert len(ls.open_dataset(out, split=None)) == frames


def main() -> None:
    parser = argparse.ArgumentParser(description=__doc__.split("\n")[0])
    parser.add_argument("--sequences", type=int, default=10)
    parser.add_argument("--layout-frames", type=int, default=10_000)
    parser.add_argument("--skip-layout", action="store_true")
    args = parser.parse_args()
    read_vs_simulate(args.sequences)
    if not args.skip_layout:
        layout(args.layout_frames)


if __name__ == "__main__":
    main()
