"""The fuzzer's runner and its contract.

A case is a directory of input files, a ``lidarsim`` command line and environment variables.
:class:`Worker` runs cases in a separate process whose memory is capped (``RLIMIT_AS``) and
kills it when a case exceeds its time; :func:`check_contract` then asserts what every run of
lidarsim must end with, whatever the input:

* exit 0, and every output is valid (clouds match their sidecar's size and checksum, pattern
  exports hold unit directions, ``--json`` output parses, datasets list every frame); or
* exit 2 with exactly one line on stderr, ``error: ...``, naming one of the case's files, an
  option it used or an environment variable it set;
* never exit 1, another status, a traceback, a warning line, a hang or memory exhaustion;
* nothing stray: a failed case leaves its directory byte for byte as it was, a successful one
  adds only its outputs, and no hidden ``.part`` file ever remains.
"""

from __future__ import annotations

import hashlib
import json
import os
import select
import subprocess
import sys
from collections import Counter
from dataclasses import dataclass, field
from pathlib import Path
from typing import Any

WORKER = Path(__file__).with_name("worker.py")
#: Address-space cap of the worker (bytes): the interpreter, NumPy, SciPy, trimesh and the
#: compiled kernels take about 1.5 GiB of address space; a case gets the rest.
MEMORY_BYTES = int(float(os.environ.get("LIDARSIM_FUZZ_MEMORY", 4 * 2 ** 30)))
#: Longest a case may take (s); the budget below keeps legitimate cases far shorter.
CASE_SECONDS = float(os.environ.get("LIDARSIM_FUZZ_CASE_SECONDS", 60))
#: The resource budget the fuzzer runs under: small, so that every accepted input finishes in
#: a second or two. The contract is that sizes beyond the budget are refused before work
#: starts, whatever the budget is.
BUDGET_ENV = {
    "LIDARSIM_MAX_RAYS_PER_FRAME": "3e5",
    "LIDARSIM_MAX_FRAMES": "5",
    "LIDARSIM_MAX_PATTERN_RAYS": "3e5",
    "LIDARSIM_MAX_COVERAGE_CELLS": "2e5",
    "LIDARSIM_MAX_PROFILE_BINS": "2000",
    "LIDARSIM_MAX_INTEGRATION_RAD": "2000",
    "LIDARSIM_MAX_MESH_TRIANGLES": "1e5",
    "LIDARSIM_MAX_KEYFRAME_ROWS": "1e4",
    "LIDARSIM_MAX_CONFIG_BYTES": "1e6",
    "LIDARSIM_MAX_DATA_BYTES": "1e7",
    "LIDARSIM_THREADS": "2",
    "LIDARSIM_MAX_THREADS": "8",
}


@dataclass
class Case:
    """One fuzz case, ready to run in ``directory``."""

    directory: Path
    argv: list[str]
    env: dict[str, str] = field(default_factory=dict)
    #: Output names (files or directories, relative to ``directory``) a success may create.
    outputs: list[str] = field(default_factory=list)
    #: Extra strings an error line may use to name what is wrong (e.g. the sensor argument).
    names: list[str] = field(default_factory=list)
    #: A Python reader to call instead of the command line (``read``, ``mesh``, ``dataset``;
    #: ``argv[0]`` is its file or directory).
    api: str | None = None

    def describe(self) -> str:
        env = " ".join(f"{k}={v}" for k, v in self.env.items() if BUDGET_ENV.get(k) != v)
        files = {p.name: _preview(p) for p in sorted(self.directory.iterdir())}
        run = f"api {self.api}(" if self.api else "lidarsim "
        return f"{env} {run}{' '.join(self.argv)}\nfiles: {json.dumps(files)[:3000]}"


def _preview(path: Path) -> str:
    if path.is_symlink():
        return f"-> {os.readlink(path)}"
    if path.is_dir():
        return "<dir>"
    if not path.is_file():
        return "<special>"
    data = path.read_bytes()[:600]
    try:
        return data.decode("utf-8")
    except UnicodeDecodeError:
        return data.hex()[:200]


class Worker:
    """A long-lived worker process (see ``worker.py``), restarted after a case kills it."""

    def __init__(self, extra_env: dict[str, str] | None = None) -> None:
        self.extra_env = extra_env or {}
        self.proc: subprocess.Popen[str] | None = None
        self.cases = 0
        #: exit status → number of cases (what the fuzzer reports at the end)
        self.outcomes: Counter[str] = Counter()
        #: the slowest case (s) and the largest peak resident memory of the worker (KiB)
        self.slowest = 0.0
        self.max_rss_kib = 0

    def _start(self) -> None:
        env = {**os.environ, "LIDARSIM_DISABLE_PLUGIN_AUTOLOAD": "1", **self.extra_env}
        self.proc = subprocess.Popen([sys.executable, str(WORKER), str(MEMORY_BYTES)],
                                     stdin=subprocess.PIPE, stdout=subprocess.PIPE,
                                     stderr=subprocess.DEVNULL, text=True, env=env)
        ready = self._read(120.0)
        assert ready == {"ready": True}, f"the fuzz worker did not start: {ready}"

    def _read(self, timeout: float) -> Any:
        assert self.proc is not None and self.proc.stdout is not None
        ready, _, _ = select.select([self.proc.stdout], [], [], timeout)
        if not ready:
            return None
        line = self.proc.stdout.readline()
        return json.loads(line) if line else {"died": self.proc.poll()}

    def run(self, case: Case) -> dict[str, Any]:
        """Run ``case``; ``{"code": "hang"}`` or ``{"code": "died"}`` when it breaks the
        time or memory bound."""
        if self.proc is None or self.proc.poll() is not None:
            self._start()
        assert self.proc is not None and self.proc.stdin is not None
        self.cases += 1
        self.proc.stdin.write(json.dumps({"dir": str(case.directory), "argv": case.argv,
                                          "env": case.env, "api": case.api}) + "\n")
        self.proc.stdin.flush()
        result = self._read(CASE_SECONDS)
        if result is None or "died" in result:
            code = "hang" if result is None else f"died ({result['died']})"
            self.close()
            self.outcomes[code] += 1
            return {"code": code, "stdout": "", "stderr": "", "seconds": CASE_SECONDS}
        self.outcomes[str(result["code"])] += 1
        self.slowest = max(self.slowest, result["seconds"])
        self.max_rss_kib = max(self.max_rss_kib, result.get("maxrss_kib", 0))
        return result

    def close(self) -> None:
        if self.proc is not None:
            self.proc.kill()
            self.proc.wait()
            self.proc = None


def snapshot(directory: Path) -> dict[str, str]:
    """Relative path → kind and content hash of everything under ``directory``."""
    out: dict[str, str] = {}
    for root, dirs, files in os.walk(directory):
        for name in dirs + files:
            path = Path(root) / name
            rel = path.relative_to(directory).as_posix()
            if path.is_symlink():
                out[rel] = f"link:{os.readlink(path)}"
            elif path.is_dir():
                out[rel] = "dir"
            elif path.is_file():
                out[rel] = hashlib.sha256(path.read_bytes()).hexdigest()
            else:
                out[rel] = "special"
    return out


def _names(case: Case) -> list[str]:
    names = [p.name for p in case.directory.iterdir()] + list(case.outputs) + case.names
    options = [a for a in case.argv if a.startswith("--")]
    # an option is named as '--seed' or as the field it sets ('format' for --format)
    names += options + [f"'{a[2:]}'" for a in options] + list(case.env)
    return [n for n in names if n] + ["environment"]


def check_contract(case: Case, before: dict[str, str], result: dict[str, Any]) -> None:
    """Assert the fuzz contract (module docstring) for one finished case."""
    where = case.describe()
    code, stderr = result["code"], result["stderr"]
    assert code in (0, 2), f"exit {code}\n{stderr}\n{where}"
    assert "Traceback" not in stderr, f"traceback\n{stderr}\n{where}"
    after = snapshot(case.directory)
    parts = [rel for rel in after if Path(rel).name.endswith(".part")]
    assert not parts, f"stray temporary files {parts}\n{where}"
    if code == 2:
        lines = [line for line in stderr.splitlines() if line.strip()]
        assert len(lines) == 1, f"{len(lines)} lines on stderr:\n{stderr}\n{where}"
        line = lines[0]
        assert line.startswith("error: "), f"not an error line: {line}\n{where}"
        assert any(name in line for name in _names(case)), \
            f"the error names no file, option or variable of the case: {line}\n{where}"
        assert after == before, f"a failed case changed its directory: " \
            f"{sorted(set(after.items()) ^ set(before.items()))[:6]}\n{where}"
        return
    changed = [rel for rel, digest in before.items() if after.get(rel) != digest]
    assert not changed, f"a successful case changed its inputs: {changed}\n{where}"
    new = [rel for rel in after if rel not in before]
    # an output, a file inside an output directory, a sidecar, or a missing folder on an
    # output's path (created by the overwrite policy, lidarsim_core.base.outputs)
    allowed = [rel for rel in new if any(rel == out or rel.startswith(out + "/") or
                                         rel == out + ".json" or out.startswith(rel + "/")
                                         for out in case.outputs)]
    assert sorted(new) == sorted(allowed), f"unexpected files {set(new) - set(allowed)}\n{where}"
    _check_outputs(case, new, result)


def _check_outputs(case: Case, new: list[str], result: dict[str, Any]) -> None:
    import numpy as np

    from lidarsim_core.io.sidecar import frame_is_complete

    command = case.argv[0]
    where = case.describe()
    new = [rel for rel in new if (case.directory / rel).is_file()]  # not the folders made
    if command == "simulate":
        clouds = [rel for rel in new if not rel.endswith(".json")]
        assert clouds, f"simulate succeeded without an output\n{where}"
        for rel in clouds:
            record = frame_is_complete(case.directory / rel, verify=True)
            assert record is not None, f"{rel} does not match its sidecar\n{where}"
    elif command == "pattern":
        (rel,) = new
        with np.load(case.directory / rel, allow_pickle=False) as data:
            direction, t = data["direction"], data["t"]
        assert direction.shape == (len(t), 3), where
        assert np.allclose(np.linalg.norm(direction, axis=1), 1.0), where
        assert np.all(np.diff(t) >= 0), where
    elif command == "coverage" and "--json" in case.argv:
        report = json.loads(result["stdout"])
        assert 0.0 <= report["coverage"] <= 1.0, where
    elif command == "dataset":
        root = case.directory / case.outputs[0]
        manifest = json.loads((root / "manifest.json").read_text())
        for seq in manifest["sequences"]:
            for frame in seq.get("frames", []):
                path = root / frame["file"]
                assert frame_is_complete(path, verify=True) is not None, f"{path}\n{where}"
