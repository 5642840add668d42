"""Reader cases of the fuzzer (issue 27): mutated point-cloud files (PLY, PCD, LAS, NPZ),
meshes (OBJ with its MTL, GLB) and dataset files (``manifest.json``, ``poses.json``), each
read through the Python reader a user would call (``ls.read``, the mesh loader, the dataset
reader of ``lidarsim evaluate``) in the fuzz worker, and held to the same contract as the
command-line cases: a correct result (every column one length; a finite mesh with valid
indices) or one ``error:`` line naming the file, never an uncontrolled exception, a hang,
memory exhaustion or a stray file.

Mutations: a header field replaced by a hostile value (counts of -1, 2^31, 2^40, 2^64, text,
a fraction, nothing), a header line dropped or repeated, truncation at any byte, 1-8 byte
flips anywhere, an NPZ member replaced by an array of another shape, length or type, and
manifest/pose values replaced by the pools of :mod:`fuzz.cases` (paths out of the dataset,
NaN, zero quaternions, wrong types).
"""

from __future__ import annotations

import copy
import io
import json
import re
import shutil
import zipfile
from pathlib import Path
from typing import Any

import numpy as np
from hypothesis import strategies as st

from .cases import VALUES, new_dir, set_path
from .harness import BUDGET_ENV, Case

#: Values a header count or field is replaced with.
HEADER_VALUES = [b"-1", b"0", b"1", b"2147483648", b"1099511627776", b"18446744073709551617",
                 b"3.5", b"abc", b"", b"1e9", b"\x1b[2J", b"99999999999999999999999"]

#: Dotted paths of ``manifest.json`` and ``poses.json`` the JSON mutations set.
MANIFEST_PATHS = ["format", "complete", "sequences", "sequences.0.root", "sequences.0.poses",
                  "sequences.0.scenario", "sequences.0.frames", "sequences.0.frames.0",
                  "sequences.0.frames.0.file", "sequences.0.frames.0.sha256",
                  "sequences.0.frames.0.frame", "sequences.0.frames.1.points",
                  "sequences.0.name"]
POSES_PATHS = ["format", "frames", "target_names", "frames.0", "frames.0.frame",
               "frames.0.t_start_s", "frames.1.t_end_s", "frames.0.targets",
               "frames.0.targets.0", "frames.0.targets.0.q_target_in_sensor",
               "frames.1.targets.0.q_target_in_sensor_end",
               "frames.0.targets.0.r_target_in_sensor_m",
               "frames.1.targets.0.r_target_in_sensor_end_m"]
PATH_VALUES = ["../outside.npz", "/etc/hostname", "frames/../../x", "link_out.npz", "",
               "frames/frame_000001.npz", "\x1b[2J.npz"]

TEXT_HEADER_END = {".ply": b"end_header\n", ".pcd": b"DATA binary\n", ".obj": None}


def _header_fields(data: bytes, end: bytes | None) -> list[tuple[int, int]]:
    """Spans of the numbers in a text header (the whole file for OBJ/MTL text)."""
    head = data if end is None else data[: data.find(end) + len(end)]
    return [m.span() for m in re.finditer(rb"-?\d+(\.\d+)?", head)][:400]


@st.composite
def mutate_bytes(draw: Any, data: bytes, suffix: str) -> bytes:
    """One to three mutations of a file's bytes."""
    for _ in range(draw(st.integers(1, 3))):
        kind = draw(st.sampled_from(["field", "truncate", "flip", "line"]
                                    if suffix in TEXT_HEADER_END else
                                    ["truncate", "flip", "flip", "las_count"]
                                    if suffix == ".las" else ["truncate", "flip"]))
        if kind == "field":
            spans = _header_fields(data, TEXT_HEADER_END[suffix])
            if spans:
                start, stop = draw(st.sampled_from(spans))
                data = data[:start] + draw(st.sampled_from(HEADER_VALUES)) + data[stop:]
        elif kind == "line":
            end = TEXT_HEADER_END[suffix]
            head_len = len(data) if end is None else data.find(end)
            lines = data[:head_len].split(b"\n")
            if len(lines) > 1:
                i = draw(st.integers(0, len(lines) - 1))
                if draw(st.booleans()):
                    lines.insert(i, lines[i])  # a repeated line (duplicate property, DATA)
                else:
                    del lines[i]
                data = b"\n".join(lines) + data[head_len:]
        elif kind == "truncate":
            data = data[:draw(st.integers(0, max(len(data) - 1, 0)))]
        elif kind == "las_count" and len(data) > 255:
            import struct

            out = bytearray(data)
            at = draw(st.sampled_from([107, 247, 105, 96]))
            value = draw(st.sampled_from([0, 1, 2 ** 31, 2 ** 32 - 1, 2 ** 40, 7]))
            fmt = "<Q" if at == 247 else "<H" if at == 105 else "<I"
            struct.pack_into(fmt, out, at, value % (2 ** (8 * struct.calcsize(fmt))))
            data = bytes(out)
        elif data:
            out = bytearray(data)
            for _ in range(draw(st.integers(1, 8))):
                out[draw(st.integers(0, len(out) - 1))] = draw(st.integers(0, 255))
            data = bytes(out)
    return data


def _npy(array: np.ndarray) -> bytes:
    buffer = io.BytesIO()
    np.lib.format.write_array(buffer, array, allow_pickle=True)
    return buffer.getvalue()


@st.composite
def mutate_npz(draw: Any, data: bytes) -> bytes:
    """An NPZ with a member replaced (another shape, length, type, a pickle, a header that
    lies), or its bytes mutated."""
    if draw(st.booleans()):
        return draw(mutate_bytes(data, ".npz"))
    with zipfile.ZipFile(io.BytesIO(data)) as src:
        names = src.namelist()
        n = len(np.load(io.BytesIO(src.read("x.npy"))))
        members = {name: src.read(name) for name in names}
    target = draw(st.sampled_from(names))
    choice = draw(st.sampled_from(["2d", "longer", "text", "object", "lie", "drop", "empty"]))
    if choice == "2d":
        members[target] = _npy(np.zeros((n, 2)))
    elif choice == "longer":
        members[target] = _npy(np.zeros(n + draw(st.integers(1, 5))))
    elif choice == "text":
        members[target] = _npy(np.array(["x"] * n))
    elif choice == "object":
        members[target] = _npy(np.array([None] * n, dtype=object))
    elif choice == "lie":
        header = _npy(np.zeros(1))
        members[target] = header.replace(b"(1,)", b"(%d,)" % draw(st.sampled_from(
            [2 ** 36, 2 ** 20, n + 1, 0])))
    elif choice == "drop":
        del members[target]
    else:
        members[target] = b""
    out = io.BytesIO()
    with zipfile.ZipFile(out, "w", compression=zipfile.ZIP_DEFLATED) as dst:
        for name, payload in members.items():
            dst.writestr(name, payload)
    return out.getvalue()


@st.composite
def reader_case(draw: Any, base: Path, seeds: dict[str, Any]) -> Case:
    """A mutated cloud, mesh or dataset, and the reader that reads it."""
    kind = draw(st.sampled_from(["ply", "pcd", "las", "npz", "obj", "glb", "manifest",
                                 "poses"]))
    directory = new_dir(base)
    env = dict(BUDGET_ENV)
    if kind in ("ply", "pcd", "las", "npz"):
        suffix = f".{kind}"
        valid = seeds[kind]
        data = draw(mutate_npz(valid)) if kind == "npz" else draw(mutate_bytes(valid, suffix))
        (directory / f"c{suffix}").write_bytes(data)
        (directory / f"c{suffix}.json").write_bytes(seeds["sidecar"])
        return Case(directory, [f"c{suffix}"], env, api="read")
    if kind == "obj":
        target = draw(st.sampled_from(["obj", "mtl"]))
        obj, mtl = seeds["obj"], seeds["mtl"]
        if target == "obj":
            obj = draw(mutate_bytes(obj, ".obj"))
        else:
            mtl = draw(mutate_bytes(mtl, ".obj"))
        (directory / "m.obj").write_bytes(obj)
        (directory / "m.mtl").write_bytes(mtl)
        return Case(directory, ["m.obj"], env, api="mesh")
    if kind == "glb":
        (directory / "m.glb").write_bytes(draw(mutate_bytes(seeds["glb"], ".glb")))
        return Case(directory, ["m.glb"], env, api="mesh")
    root = directory / "ds"
    shutil.copytree(seeds["dataset"], root, symlinks=True)
    (directory / "outside.npz").write_bytes(b"not inside")
    (root / "link_out.npz").symlink_to(directory / "outside.npz")
    name = "manifest.json" if kind == "manifest" else "poses.json"
    paths = MANIFEST_PATHS if kind == "manifest" else POSES_PATHS
    if draw(st.booleans()):
        document = json.loads((root / name).read_text())
        for _ in range(draw(st.integers(1, 3))):
            path = draw(st.sampled_from(paths))
            pool = PATH_VALUES + VALUES if path.endswith(("file", "root", "poses",
                                                          "scenario")) else VALUES
            # a copy: the pools' lists and mappings are shared by every case
            document = set_path(document, path, copy.deepcopy(draw(st.sampled_from(pool))))
        (root / name).write_text(json.dumps(document))
    else:
        (root / name).write_bytes(draw(mutate_bytes((root / name).read_bytes(), ".obj")))
    return Case(directory, ["ds"], env, api="dataset",
                names=["manifest.json", "poses.json", "frame_", "ds"])
