"""Hypothesis strategies that build fuzz cases by mutating valid inputs.

Each strategy draws a small valid input (the bad-input corpus's base scenario and datasheet,
a one-triangle mesh, a dataset file, a valid command line) and applies one to four mutations
from pools of hostile values: wrong types, NaN and infinities, 1e308, 2^64 + 1, negative and
zero sizes, markup-like text (``[/x]``, ``[red]``), repeated Euler axes, absurd rates, special
files (FIFOs, ``/dev/zero``, symbolic-link loops, directories), and hostile environment
variables. The case is written into a fresh directory and returned with its command line.
"""

from __future__ import annotations

import copy
import json
import math
import os
import struct
import tempfile
from pathlib import Path
from typing import Any

import yaml
from hypothesis import strategies as st

from .harness import BUDGET_ENV, Case

BASE_SCENARIO: dict[str, Any] = {
    "seed": 1,
    "sensor": {"datasheet": "livox-mid70-rose", "pose": {"position_m": [0, 0, 0]}},
    "targets": [{"name": "plate", "mesh": {"model": "plate", "options": {"size_m": [20, 20]}},
                 "pose": {"position_m": [30, 0, 0]}}],
    "scan": {"duration_s": 0.01},
    "backend": "numpy",
}
BASE_DATASHEET: dict[str, Any] = {
    "name": "fuzz-sensor", "manufacturer": "Fuzz", "model": "Rose 40",
    "sources": [{"title": "fuzz"}], "fov_type": "circular", "fov_h_deg": 40, "fov_v_deg": 40,
    "range_max_m": 200, "range_min_m": 0.1, "range_precision_m": 0.01,
    "angular_precision_deg": 0.05, "point_rate_hz": 10000,
    "scan_pattern": {"name": "rose", "options": {"b": 4, "turn_period_s": 0.02}},
}

NUMBERS = [0, -1, 1, 2, 0.5, 3.7, 1e-300, 1e308, -1e308, math.nan, math.inf, -math.inf,
           2 ** 64 + 1, 2 ** 63, -2 ** 63, 1e15, 1e9, 1e6, 100000, 7]
TEXTS = ["", "1e308", "xxz", "ZXZ", "zxz", "[/x]", "[red]x", "extra_[b]key", "x.[/i]", "nan",
         "-1", "abc", "\x00", "é", "{frame.__class__}"]
OTHERS = [None, [], {}, True, [1, 2], [1e308, 0, 0], [0, 0, 0], [math.nan, 0, 0], [1, 2, 3, 4],
          {"[/x]": 1}]
VALUES = NUMBERS + TEXTS + OTHERS

SCENARIO_PATHS = [
    "seed", "chunk_rays", "scan.duration_s", "scan.start_s", "scan.frames",
    "scan.frame_period_s", "scan.frame_rate_hz", "scan.sequence_duration_s", "scan.motion",
    "sensor.pose.position_m", "sensor.pose.position_m.0", "sensor.pose.euler_deg",
    "sensor.pose.euler_sequence", "sensor.pose.quaternion_xyzw", "sensor.datasheet",
    "sensor.pattern_options.turn_period_s", "sensor.pattern_options.b", "targets.0.name",
    "targets.0.pose.position_m.0", "targets.0.pose.euler_deg", "targets.0.pose.euler_sequence",
    "targets.0.mesh.scale", "targets.0.mesh.options.size_m", "targets.0.mesh.model",
    "targets.0.mesh.path", "backend", "noise", "noise.0", "sensor.beam.sub_rays",
    "sensor.returns.mode", "materials", "[/x]", "extra_[b]key", "scan.[red]x",
]
DATASHEET_KEYS = ["point_rate_hz", "fov_h_deg", "fov_v_deg", "range_max_m", "range_min_m",
                  "range_precision_m", "angular_precision_deg", "fov_type", "name",
                  "scan_pattern.options.turn_period_s", "scan_pattern.options.b",
                  "scan_pattern.name", "beam_divergence_deg", "max_returns", "[/x]"]
TRAJECTORIES = [
    {"kind": "torque_free", "inertia_kg_m2": [1, 2, 2.5], "angular_velocity_deg_s": [1e9, 0, 0]},
    {"kind": "torque_free", "inertia_kg_m2": [1, 2, 2.5], "angular_velocity_deg_s": [5, 1, 0]},
    {"kind": "torque_free", "inertia_kg_m2": [1, 2, 2.5], "angular_velocity_deg_s": [3, 0, 0],
     "t_ref_s": -1e7},
    {"kind": "tumbling", "spin_rate_deg_s": 1e12},
    {"kind": "keyframes", "file": "kf.csv"},
]
SPECIAL = ["fifo", "dev_zero", "link_loop", "directory", "missing", "empty", "dangling"]


def set_path(data: Any, path: str, value: Any) -> Any:
    """``data`` with the dotted ``path`` set to ``value`` (creating mappings on the way;
    a scalar in the way is replaced by a mapping)."""
    keys = path.split(".")
    node = data
    for key in keys[:-1]:
        if isinstance(node, list) and key.isdigit() and int(key) < len(node):
            if not isinstance(node[int(key)], (dict, list)):
                node[int(key)] = {}
            node = node[int(key)]
        elif isinstance(node, dict):
            if not isinstance(node.get(key), (dict, list)):
                node[key] = {}
            node = node[key]
        else:
            return data
    last = keys[-1]
    if isinstance(node, list) and last.isdigit() and int(last) < len(node):
        node[int(last)] = value
    elif isinstance(node, dict):
        node[last] = value
    return data


def delete_path(data: Any, path: str) -> Any:
    keys = path.split(".")
    node = data
    for key in keys[:-1]:
        node = node.get(key) if isinstance(node, dict) else None
        if node is None:
            return data
    if isinstance(node, dict):
        node.pop(keys[-1], None)
    return data


def dump(data: Any, suffix: str) -> bytes:
    """``data`` as YAML or JSON (NaN and infinities as each format writes them)."""
    if suffix == ".json":
        return json.dumps(data).encode("utf-8")
    return yaml.safe_dump(data, sort_keys=False, allow_unicode=True).encode("utf-8")


def make_special(path: Path, kind: str) -> None:
    """A hostile file system object at ``path``."""
    if kind == "fifo":
        os.mkfifo(path)
    elif kind == "dev_zero":
        os.symlink("/dev/zero", path)
    elif kind == "link_loop":
        os.symlink(path.name, path)
    elif kind == "directory":
        path.mkdir()
    elif kind == "empty":
        path.write_bytes(b"")
    elif kind == "dangling":
        os.symlink("nowhere-" + path.name, path)
    # "missing": nothing


def new_dir(base: Path) -> Path:
    return Path(tempfile.mkdtemp(prefix="case-", dir=base))


def mutations(paths: list[str]) -> st.SearchStrategy:
    """One to three changes; numbers are drawn half of the time (sizes, rates and times are
    where resources go), one change in five deletes a key."""
    value = st.one_of(st.sampled_from(NUMBERS), st.sampled_from(NUMBERS),
                      st.sampled_from(TEXTS), st.sampled_from(OTHERS))
    one = st.one_of(
        st.tuples(st.just("set"), st.sampled_from(paths), value),
        st.tuples(st.just("set"), st.sampled_from(paths), value),
        st.tuples(st.just("set"), st.sampled_from(paths), value),
        st.tuples(st.just("set"), st.sampled_from(paths), value),
        st.tuples(st.just("delete"), st.sampled_from(paths), st.none()))
    return st.lists(one, min_size=1, max_size=3)


def apply(data: dict[str, Any], ops: list[tuple[str, str, Any]]) -> dict[str, Any]:
    data = copy.deepcopy(data)
    for op, path, value in ops:
        if op == "set":
            set_path(data, path, copy.deepcopy(value))
        else:
            delete_path(data, path)
    return data


def _mesh_bytes(draw: Any) -> tuple[str, bytes]:
    kind = draw(st.sampled_from(["obj", "stl_ascii", "stl_binary"]))
    coords = st.sampled_from([0.0, 1.0, -1.0, 5.0, 1e7, 1e308, -1e308, math.inf, math.nan,
                              1e-300, 2.5])
    vertices = draw(st.lists(st.tuples(coords, coords, coords), min_size=0, max_size=5))
    if kind == "obj":
        faces = draw(st.lists(st.tuples(*[st.sampled_from([1, 2, 3, 4, 0, -1, 99])] * 3),
                              min_size=0, max_size=3))
        text = "".join(f"v {x!r} {y!r} {z!r}\n" for x, y, z in vertices)
        text += "".join(f"f {a} {b} {c}\n" for a, b, c in faces)
        return "m.obj", text.replace("nan", "nan").encode()
    if kind == "stl_ascii":
        tri = vertices[:3] + [(0.0, 0.0, 0.0)] * (3 - len(vertices[:3]))
        body = "".join(f"vertex {x!r} {y!r} {z!r}\n" for x, y, z in tri)
        return "m.stl", (f"solid f\nfacet normal 0 0 1\nouter loop\n{body}endloop\nendfacet\n"
                         "endsolid f\n").encode()
    count = draw(st.sampled_from([0, 1, 2, 2 ** 32 - 1, 10 ** 8]))
    tri = vertices[:3] + [(0.0, 0.0, 1.0)] * (3 - len(vertices[:3]))
    facet = struct.pack("<12fH", 0, 0, 1, *[c for v in tri for c in v], 0) \
        if all(math.isfinite(c) and abs(c) < 3e38 for v in tri for c in v) else b"\xff" * 50
    facets = draw(st.integers(0, 2))
    return "m.stl", b"fuzz".ljust(80, b" ") + struct.pack("<I", count) + facet * facets


@st.composite
def scenario_case(draw: Any, base: Path) -> Case:
    """A mutated scenario (YAML or JSON), sometimes with a mutated or hostile mesh file,
    datasheet file or trajectory, simulated to a file."""
    directory = new_dir(base)
    data = apply(BASE_SCENARIO, draw(mutations(SCENARIO_PATHS)))
    extra = draw(st.sampled_from(["none", "mesh", "special_mesh", "datasheet", "trajectory",
                                  "inline_datasheet"]))
    if extra == "mesh":
        name, content = _mesh_bytes(draw)
        (directory / name).write_bytes(content)
        set_path(data, "targets.0.mesh", {"path": name})
    elif extra == "special_mesh":
        make_special(directory / "m.stl", draw(st.sampled_from(SPECIAL)))
        set_path(data, "targets.0.mesh", {"path": "m.stl"})
    elif extra in ("datasheet", "inline_datasheet"):
        sheet = apply(BASE_DATASHEET, draw(mutations(DATASHEET_KEYS)))
        if extra == "datasheet":
            (directory / "d.yaml").write_bytes(dump(sheet, ".yaml"))
            set_path(data, "sensor.datasheet", "d.yaml")
        else:
            set_path(data, "sensor.datasheet", sheet)
    elif extra == "trajectory":
        trajectory = copy.deepcopy(draw(st.sampled_from(TRAJECTORIES)))
        if trajectory["kind"] == "keyframes":
            rows = draw(st.lists(st.tuples(st.sampled_from([0.0, 0.005, 0.01, 0.02, -1.0,
                                                            math.nan, 1e308]),
                                           st.sampled_from([30.0, 1e308, math.inf, 0.0])),
                                 min_size=0, max_size=4))
            text = "t_s,x_m,y_m,z_m\n" + "".join(f"{t!r},{x!r},0,0\n" for t, x in rows)
            if draw(st.booleans()):
                (directory / "kf.csv").write_text(text)
            else:
                make_special(directory / "kf.csv", draw(st.sampled_from(SPECIAL)))
        delete_path(data, "targets.0.pose")
        set_path(data, "targets.0.trajectory", trajectory)
    suffix = draw(st.sampled_from([".yaml", ".json", ".yml"]))
    name = draw(st.sampled_from(["scene", "[red]scene", "sc[b]ene"])) + suffix
    (directory / name).write_bytes(dump(data, suffix))
    out = draw(st.sampled_from(["out.ply", "out.npz", "out_{frame}.ply", "out.csv"]))
    argv = ["simulate", name, "--out", out]
    frames = data.get("scan", {}).get("frames") if isinstance(data.get("scan"), dict) else None
    outputs = [out]
    if "{frame}" in out:
        outputs = [out.replace("{frame}", str(f)) for f in range(6)]
    del frames
    return Case(directory, argv, dict(BUDGET_ENV), outputs=outputs)


OPTION_VALUES = ["0", "-1", "1", "0.01", "0.5", "nan", "inf", "-inf", "1e308", "1e-300", "abc",
                 "", "18446744073709551617", "1e6", "3"]
OUT_NAMES = ["o.ply", "o.npz", "o.xyz", "x.[/i]", "[red]o.ply", "a" * 300 + ".ply",
             "o_{frame}.ply", "o_{frame.__class__}.ply", "o_{0}.ply", "nodir/o.ply",
             "loop.ply", "dir", "exists.ply", "o.[b]npz"]
YAML_VALUES = ["[unclosed", "!!python/object/apply:os.system [ls]", "1e308", ".nan", "-1", "{a: 1}",
               "x", "0.001", "&a [*a]", "'[/x]'"]


@st.composite
def option_case(draw: Any, base: Path) -> Case:
    """A command line with hostile option values: simulate, pattern or coverage."""
    directory = new_dir(base)
    (directory / "s.yaml").write_bytes(dump(BASE_SCENARIO, ".yaml"))
    (directory / "d.yaml").write_bytes(dump(BASE_DATASHEET, ".yaml"))
    os.symlink("loop.ply", directory / "loop.ply")
    (directory / "dir").mkdir()
    (directory / "exists.ply").write_bytes(b"keep me")
    command = draw(st.sampled_from(["simulate", "pattern", "coverage"]))
    value = st.sampled_from(OPTION_VALUES)
    outputs: list[str] = []
    if command == "simulate":
        out = draw(st.sampled_from(OUT_NAMES))
        argv = ["simulate", "s.yaml", "--out", out]
        outputs = [out, out.replace("{frame}", "0")]
        for flag in draw(st.lists(st.sampled_from(["--seed", "--frame", "--backend",
                                                   "--format"]), max_size=2, unique=True)):
            argv += [flag, draw(value if flag in ("--seed", "--frame") else
                                st.sampled_from(["numpy", "nope", "[b]x", "ply", "npz"]))]
    else:
        sensor = draw(st.sampled_from(["livox-mid70", "livox-mid70-rose", "d.yaml", "nope",
                                       "/dev/zero", "[red]s.yaml"]))
        argv = [command, sensor]
        if command == "pattern":
            out = draw(st.sampled_from(["p.npz", "x.[/i]", "p.ply", "nodir/p.npz", "loop.ply"]))
            argv += ["--duration", draw(st.sampled_from(["0.01", "0.002"]) | value),
                     "--out", out]
            outputs = [out]
            flags = ["--start", "--option"]
        else:
            argv += ["--time", draw(st.sampled_from(["0.01", "0.005"]) | value)]
            flags = ["--start", "--option", "--cell-deg", "--bin-deg", "--json"]
        for flag in draw(st.lists(st.sampled_from(flags), max_size=3, unique=True)):
            if flag == "--json":
                argv.append(flag)
            elif flag == "--option":
                key = draw(st.sampled_from(["turn_period_s", "b", "[/x]", "nope", ""]))
                argv += [flag, f"{key}={draw(st.sampled_from(YAML_VALUES))}"]
            else:
                argv += [flag, draw(st.sampled_from(["0.5", "2"]) | value)]
    return Case(directory, argv, dict(BUDGET_ENV), outputs=outputs, names=[argv[1]])


ENV_VALUES = ["", "abc", "-1", "0", "nan", "inf", "1e-3", "99999999", "1.5", " 2 ", "\u0663"]
ENV_NAMES = ["LIDARSIM_THREADS", "LIDARSIM_MAX_RAYS_PER_FRAME", "LIDARSIM_MAX_FRAMES",
             "LIDARSIM_MAX_CONFIG_BYTES", "LIDARSIM_MAX_DATA_BYTES",
             "LIDARSIM_MAX_MESH_TRIANGLES", "LIDARSIM_MAX_INTEGRATION_RAD"]


@st.composite
def environment_case(draw: Any, base: Path) -> Case:
    """A valid simulate or pattern run under hostile environment variables."""
    directory = new_dir(base)
    (directory / "s.yaml").write_bytes(dump(BASE_SCENARIO, ".yaml"))
    env = dict(BUDGET_ENV)
    for name in draw(st.lists(st.sampled_from(ENV_NAMES), min_size=1, max_size=2, unique=True)):
        env[name] = draw(st.sampled_from(ENV_VALUES))
    if draw(st.booleans()):
        return Case(directory, ["simulate", "s.yaml", "--out", "o.ply"], env, outputs=["o.ply"])
    return Case(directory, ["pattern", "livox-mid70", "--duration", "0.01", "--out", "p.npz"],
                env, outputs=["p.npz"])


DATASET_PATHS = ["sequences.0.seed", "sequences.0.seeds", "sequences.0.frames",
                 "sequences.0.name", "sequences.0.split", "sequences.0.group",
                 "sequences.0.scenario", "sequences.0.set", "splits.train", "split_seed",
                 "format", "exporter_options", "sequences", "[/x]"]
SET_PATHS = ["scan.duration_s", "seed", "targets.0.pose.position_m", "scan.frames",
             "targets.0.mesh.path", "nope.deeper", "targets.5.name"]


@st.composite
def dataset_case(draw: Any, base: Path) -> Case:
    """``lidarsim dataset`` of a mutated dataset file or scenario, into a new, empty, foreign
    or file output."""
    directory = new_dir(base)
    scenario = BASE_SCENARIO if draw(st.booleans()) else \
        apply(BASE_SCENARIO, draw(mutations(SCENARIO_PATHS)))
    (directory / "s.yaml").write_bytes(dump(scenario, ".yaml"))
    if draw(st.booleans()):
        plan: dict[str, Any] = {"sequences": [{"scenario": "s.yaml", "name": "a", "seeds": [1, 2]},
                                              {"scenario": "s.yaml", "name": "b", "frames": 2}],
                                "splits": {"train": 0.5, "val": 0.5, "test": 0.0}}
        plan = apply(plan, draw(mutations(DATASET_PATHS)))
        if draw(st.booleans()):
            set_path(plan, "sequences.0.set", {draw(st.sampled_from(SET_PATHS)):
                                               draw(st.sampled_from(VALUES))})
        (directory / "ds.yaml").write_bytes(dump(plan, ".yaml"))
        source = "ds.yaml"
    else:
        source = "s.yaml"
    out = draw(st.sampled_from(["out", "empty", "foreign", "afile", "[red]out"]))
    if out == "empty":
        (directory / out).mkdir()
    elif out == "foreign":
        (directory / out).mkdir()
        (directory / out / "mine.txt").write_text("not a dataset")
    elif out == "afile":
        (directory / out).write_text("a file")
    argv = ["dataset", source, "--out", out, "--quiet"]
    if draw(st.booleans()):
        argv += ["--frames", draw(st.sampled_from(["1", "2", "0", "-1", "1000000000"]))]
    return Case(directory, argv, dict(BUDGET_ENV), outputs=[out])
