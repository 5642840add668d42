"""The bad-input corpus: load ``cases.yaml``, build a case's files, run it through the CLI
(in process or as a real process) and through the Python API.

Binary inputs (garbage bytes, truncated STL, pickled NPY) are generated here so that the
repository holds only small text files.
"""

from __future__ import annotations

import copy
import dataclasses
import io
import json
import os
import shutil
import struct
import subprocess
import sys
from dataclasses import dataclass
from pathlib import Path
from typing import Any, Callable

import numpy as np
import yaml

HERE = Path(__file__).resolve().parent
FILES = HERE / "files"


@dataclass
class Case:
    """One row of ``cases.yaml`` (see the comment at the top of that file for the keys)."""

    id: str
    category: str
    files: dict[str, Any]
    run: list[str]
    exit: int
    file: str | None = None
    field: str | None = None
    message: list[str] = dataclasses.field(default_factory=list)
    result: str | None = None
    outputs: list[str] = dataclasses.field(default_factory=list)
    keep: dict[str, str] = dataclasses.field(default_factory=dict)
    env: dict[str, str] = dataclasses.field(default_factory=dict)
    api: str = "command"
    api_reason: str = ""
    subprocess: bool = False
    writable: bool = True
    spool_memory: int | None = None

    @property
    def fragments(self) -> list[str]:
        """Everything the one-line message must contain."""
        out = list(self.message)
        if self.file:
            out.append(self.file)
        if self.field:
            out.append(f"field '{self.field}'")
        return out


def load_cases() -> list[Case]:
    """Every case of ``cases.yaml``, in file order."""
    data = yaml.safe_load((HERE / "cases.yaml").read_text(encoding="utf-8"))
    cases = [Case(**row) for row in data["cases"]]
    ids = [c.id for c in cases]
    assert len(ids) == len(set(ids)), "case ids must be unique"
    return cases


# ---- building the files ------------------------------------------------------------------
def _set_dotted(data: Any, path: str, value: Any) -> None:
    keys = path.split(".")
    node = data
    for key in keys[:-1]:
        node = node[int(key)] if isinstance(node, list) else node.setdefault(key, {})
    last = keys[-1]
    if isinstance(node, list):
        index = int(last)
        if index == len(node):
            node.append(value)
        else:
            node[index] = value
    else:
        node[last] = value


def _unset_dotted(data: Any, path: str) -> None:
    keys = path.split(".")
    node = data
    for key in keys[:-1]:
        node = node[int(key)] if isinstance(node, list) else node[key]
    del node[keys[-1]]


def _variant(base: str, spec: dict[str, Any]) -> dict[str, Any]:
    data = copy.deepcopy(yaml.safe_load((FILES / base).read_text(encoding="utf-8")))
    for path in spec.get("unset", []):
        _unset_dotted(data, path)
    for path, value in (spec.get("set") or {}).items():
        _set_dotted(data, path, value)
    return data


def _toml_value(value: Any) -> str:
    if isinstance(value, bool):
        return "true" if value else "false"
    if isinstance(value, (int, float)):
        if isinstance(value, float) and np.isnan(value):
            return "nan"
        if isinstance(value, float) and np.isinf(value):
            return "inf" if value > 0 else "-inf"
        return repr(value)
    if isinstance(value, str):
        return json.dumps(value)
    if isinstance(value, list):
        return "[" + ", ".join(_toml_value(v) for v in value) + "]"
    if isinstance(value, dict):
        return "{" + ", ".join(f"{json.dumps(k)} = {_toml_value(v)}"
                               for k, v in value.items()) + "}"
    raise TypeError(f"cannot write {type(value).__name__} as TOML")


def to_toml(data: dict[str, Any]) -> str:
    """``data`` as TOML, every nested value as an inline table or array."""
    return "".join(f"{json.dumps(k)} = {_toml_value(v)}\n" for k, v in data.items())


def dump_config(data: dict[str, Any], suffix: str) -> bytes:
    """``data`` in the format of ``suffix`` (.yaml, .toml or .json)."""
    if suffix == ".toml":
        return to_toml(data).encode()
    if suffix == ".json":
        return json.dumps(data, indent=1).encode()
    return yaml.safe_dump(data, sort_keys=False).encode()


def _stl_bytes(triangles: np.ndarray, count: int | None = None) -> bytes:
    """A binary STL of ``triangles`` ((F, 3, 3)); ``count`` overrides the header's count."""
    out = io.BytesIO()
    out.write(b"bad-input corpus".ljust(80, b" "))
    out.write(struct.pack("<I", len(triangles) if count is None else count))
    for tri in triangles:
        normal = np.cross(tri[1] - tri[0], tri[2] - tri[0])
        out.write(struct.pack("<12fH", *normal, *tri.ravel(), 0))
    return out.getvalue()


def _generate(kind: str, **params: Any) -> bytes:
    if kind == "garbage":
        return np.random.default_rng(params["seed"]).bytes(params["size"])
    if kind == "truncated_scenario_yaml":
        text = (FILES / "base_scenario.yaml").read_text(encoding="utf-8")
        cut = text.index("position_m: [30") + len("position_m: [30")
        return text[:cut].encode()
    if kind == "truncated_scenario_toml":
        text = to_toml(_variant("base_scenario.yaml", {}))
        cut = text.index('"position_m" = [30') + len('"position_m" = [30')
        return text[:cut].encode()
    if kind == "duplicate_key_yaml":
        text = (FILES / "base_scenario.yaml").read_text(encoding="utf-8")
        return text.replace("scan: {duration_s: 0.01}",
                            "scan:\n  duration_s: 0.01\n  duration_s: 5.0").encode()
    if kind == "alias_bomb_yaml":  # ten levels of ten aliases: 10**10 values in 11 lines
        lines = ["l0: &l0 [1, 1, 1, 1, 1, 1, 1, 1, 1, 1]"]
        lines += [f"l{i}: &l{i} [{', '.join([f'*l{i - 1}'] * 10)}]" for i in range(1, 10)]
        text = (FILES / "base_scenario.yaml").read_text(encoding="utf-8")
        return text.replace("pose: {position_m: [0, 0, 0]}",  # options hold any values
                            "pose: {position_m: [0, 0, 0]}\n  pattern_options:\n"
                            + "".join(f"    {line}\n" for line in lines)).encode()
    tri = np.array([[[0, -1, -1], [0, 0, 1], [0, 1, -1]],
                    [[0, -1, -1], [0, 1, -1], [0, -1, 1]]], dtype=np.float64)
    if kind == "truncated_stl":
        full = _stl_bytes(np.repeat(tri, 50, axis=0))
        return full[:84 + 50 * 3]  # header says 100 triangles; the bytes end inside the first
    if kind == "nan_stl":
        bad = tri.copy()
        bad[1, 2, 0] = np.nan
        return _stl_bytes(bad)
    if kind == "pickled_npy":
        buf = io.BytesIO()
        np.save(buf, np.array([{"t_s": 0.0}, {"t_s": 1.0}], dtype=object), allow_pickle=True)
        return buf.getvalue()
    if kind == "flat_npy":
        buf = io.BytesIO()
        np.save(buf, np.linspace(0.0, 1.0, 10))
        return buf.getvalue()
    raise ValueError(f"unknown generator {kind!r}")


def build(case: Case, root: Path) -> Path:
    """Write the case's files into a fresh directory under ``root``; returns it."""
    work = root / case.id
    work.mkdir(parents=True)
    for name, spec in case.files.items():
        path = work / name
        if spec.get("dir"):
            path.mkdir()
            continue
        if "file" in spec:
            shutil.copyfile(FILES / spec["file"], path)
        elif "text" in spec:
            path.write_bytes(spec["text"].encode())
        elif "scenario" in spec:
            path.write_bytes(dump_config(_variant("base_scenario.yaml", spec["scenario"] or {}),
                                         path.suffix))
        elif "datasheet" in spec:
            path.write_bytes(dump_config(_variant("base_datasheet.yaml", spec["datasheet"] or {}),
                                         path.suffix))
        elif "generate" in spec:
            params = {k: v for k, v in spec.items() if k != "generate"}
            path.write_bytes(_generate(spec["generate"], **params))
        else:
            raise ValueError(f"{case.id}: cannot build {name}: {spec}")
    for name, text in case.keep.items():
        (work / name).write_text(text)
    return work


def snapshot(work: Path) -> dict[str, bytes | None]:
    """Every path under ``work`` (hidden ones too) with its bytes (``None`` for directories)."""
    return {str(p.relative_to(work)): (None if p.is_dir() else p.read_bytes())
            for p in sorted(work.rglob("*"))}


# ---- running -----------------------------------------------------------------------------
@dataclass
class Outcome:
    """What a command did."""

    exit: int
    stdout: str
    stderr: str

    @property
    def error_lines(self) -> list[str]:
        """The non-blank lines written to stderr."""
        return [line for line in self.stderr.splitlines() if line.strip()]


def run_subprocess(case: Case, work: Path) -> Outcome:
    """``python -m lidarsim_core <run>`` in ``work``."""
    env = {**os.environ, "LIDARSIM_DISABLE_PLUGIN_AUTOLOAD": "1", "COLUMNS": "200",
           **case.env}
    if "LIDARSIM_PLUGINS" in case.env:
        env["PYTHONPATH"] = os.pathsep.join([str(work), env.get("PYTHONPATH", "")])
    res = subprocess.run([sys.executable, "-m", "lidarsim_core", *case.run], cwd=work, env=env,
                         capture_output=True, text=True, timeout=120)
    return Outcome(res.returncode, res.stdout, res.stderr)


def run_in_process(case: Case) -> Outcome:
    """The command through the Typer app in this process (the caller sets cwd and env)."""
    from typer.testing import CliRunner

    from lidarsim_core import cli
    result = CliRunner().invoke(cli.app, case.run, catch_exceptions=False)
    return Outcome(result.exit_code, result.stdout, result.stderr)


def _options(argv: list[str], switches: tuple[str, ...] = ()) -> tuple[list[str], dict[str, Any]]:
    positional, opts = [], {}
    it = iter(argv)
    for arg in it:
        if arg in switches:
            opts[arg] = True
        elif arg.startswith("-"):
            opts[arg] = next(it)
        else:
            positional.append(arg)
    return positional, opts


def _api_simulate(argv: list[str]) -> list[Any]:
    import lidarsim_core as ls

    (path,), opts = _options(argv, ("--overwrite",))
    scenario = ls.load_scenario(path)
    sim = ls.Simulation(scenario)
    frames = [int(opts["--frame"])] if "--frame" in opts else range(scenario.scan.frames)
    clouds = []
    for f in frames:
        cloud = sim.run_frame(f)
        cloud.save(opts["--out"], format=opts.get("--format"),
                   overwrite=bool(opts.get("--overwrite")))
        clouds.append(cloud)
    return clouds


def _api_pattern(argv: list[str]) -> Any:
    from lidarsim_core.plugins.resolve import get_sensor, pattern_for

    (sheet,), opts = _options(argv)
    return pattern_for(get_sensor(sheet), source=sheet).rays(0.0, float(opts["--duration"]))


def _api_coverage(argv: list[str]) -> Any:
    from lidarsim_core.patterns.fov import fov_coverage
    from lidarsim_core.plugins.resolve import get_sensor, pattern_for

    (sheet,), opts = _options(argv)
    return fov_coverage(pattern_for(get_sensor(sheet), source=sheet), float(opts["--time"]), 0.5)


def _api_poses(argv: list[str]) -> Any:
    from lidarsim_core.io.groundtruth import write_ground_truth
    from lidarsim_core.pipeline.simulation import sequence_frame_infos
    from lidarsim_core.scenario import load_scenario

    (path,), opts = _options(argv)
    infos = sequence_frame_infos(load_scenario(path))
    return write_ground_truth(opts["--out"], infos, overwrite=False)


def _api_dataset(argv: list[str]) -> Any:
    from lidarsim_core.dataset import generate_dataset

    (path,), opts = _options(argv, ("--quiet",))
    return generate_dataset(path, opts["--out"], quiet=True)


API: dict[str, Callable[[list[str]], Any]] = {
    "simulate": _api_simulate, "pattern": _api_pattern, "coverage": _api_coverage,
    "poses": _api_poses, "dataset": _api_dataset,
}


def run_api(case: Case) -> Any:
    """The Python-API equivalent of the case's command (the caller sets cwd and env)."""
    return API[case.run[0]](case.run[1:])


def points_in(path: Path) -> int:
    """Number of points in an output file (NPZ or PLY)."""
    if path.suffix == ".npz":
        with np.load(path, allow_pickle=False) as data:
            return int(data["x"].size)
    header = path.read_bytes().split(b"end_header", 1)[0].decode()
    return int(next(line.split()[2] for line in header.splitlines()
                    if line.startswith("element vertex")))
