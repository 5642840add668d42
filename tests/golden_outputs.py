"""The reference outputs whose bytes must not move: their SHA-256, recomputed and compared by
``tests/test_golden_outputs.py``.

Run as a script to print the hashes of the current code and the class of CPU they belong to
(``python tests/golden_outputs.py``); ``tests/data/golden_hashes.json`` holds them per class
(:func:`bits_class`): for AVX-512 x86-64, those of the commit before the package-layout change
(issue 21); for AVX2 x86-64, those of 00fecf3, the first commit run on such a CPU. Any change
that moves a bit of these outputs says so by failing that test.

Why per class: NumPy picks at run time, per CPU, the SIMD build of its float64 functions, and
the outputs go through them (the record's azimuth, elevation and incidence angle, the
materials' intensity). The same commit wrote 50 of the 53 files differently on an AVX-512 Xeon
and on an AVX2 EPYC; that NumPy's AVX-512 builds (``X86_V4``) are the cause is inferred, as they
cannot run on the EPYC, where its AVX2 and baseline builds wrote the same bytes.
"""

from __future__ import annotations

import hashlib
import json
import os
import platform
import subprocess
import sys
import tempfile
from pathlib import Path

ROOT = Path(__file__).resolve().parent.parent
TUMBLING = ROOT / "examples" / "scenarios" / "envisat_tumbling_hold.yaml"
#: NumPy's float64 functions that the outputs go through and that NumPy builds for several
#: instruction sets, choosing one per CPU when it starts.
UFUNCS = ("arctan2", "arccos", "arcsin", "arctan", "hypot", "exp", "log", "sin", "cos", "power")
#: Builds measured to write the same bytes, named as one: on an AVX2 EPYC, every reference
#: output was the same with NumPy's AVX2 builds and with its baseline ones
#: (``NPY_DISABLE_CPU_FEATURES=X86_V3``).
SAME_BYTES = {"X86_V3": "X86_V3 or baseline", "baseline(X86_V2)": "X86_V3 or baseline"}
#: The classes with references (what :func:`bits_class` returns on such CPUs).
AVX512_X86_64 = "x86_64: NumPy float64 functions on X86_V4"
AVX2_X86_64 = "x86_64: NumPy float64 functions on X86_V3 or baseline"


def bits_class() -> str:
    """The class of CPU whose bits the outputs of this machine are: the processor's
    architecture and the instruction sets of NumPy's builds of :data:`UFUNCS` chosen here
    (``numpy.lib.introspect.opt_func_info``; :data:`SAME_BYTES` named as one; NumPy's version
    where it has no such function, a class no reference is recorded for)."""
    import numpy as np

    try:
        from numpy.lib.introspect import opt_func_info
    except ImportError:
        return f"{platform.machine()}: NumPy {np.__version__}"
    info = opt_func_info(func_name="^(" + "|".join(UFUNCS) + ")$", signature="^float64")
    targets = sorted({SAME_BYTES.get(entry["current"], entry["current"])
                      for signatures in info.values() for entry in signatures.values()})
    return f"{platform.machine()}: NumPy float64 functions on {', '.join(targets)}"


def _lidarsim(*args: str) -> None:
    env = dict(os.environ, LIDARSIM_DISABLE_PLUGIN_AUTOLOAD="1")
    subprocess.run([sys.executable, "-m", "lidarsim_core", *args], check=True, env=env,
                   stdout=subprocess.DEVNULL, cwd=ROOT)


def _hashes(folder: Path) -> dict[str, str]:
    # the dataset's lock file is the run's bookkeeping, not an output
    return {p.relative_to(folder).as_posix(): hashlib.sha256(p.read_bytes()).hexdigest()
            for p in sorted(folder.rglob("*"))
            if p.is_file() and p.name != ".lidarsim-dataset.lock"}


def golden_hashes() -> dict[str, str]:
    """SHA-256 of every reference output, keyed by its path in a scratch folder: the demo's
    clouds with and without errors (PLY and NPZ with sidecars), the 20-frame tumbling dataset
    (every file and the manifest), that scenario as one ROS 2 bag, and its poses file."""
    import lidarsim_core as ls

    with tempfile.TemporaryDirectory() as tmp:
        out = Path(tmp)
        for label, noisy in (("with_errors", True), ("without_errors", False)):
            cloud = ls.simulate(ls.demo_scenario(noise=noisy))
            for suffix in (".ply", ".npz"):
                cloud.save(out / "demo" / f"cloud_{label}{suffix}")
        _lidarsim("dataset", str(TUMBLING), "--out", str(out / "dataset"))
        _lidarsim("simulate", str(TUMBLING), "--out", str(out / "bag" / "run.mcap"))
        _lidarsim("poses", str(TUMBLING), "--out", str(out / "poses" / "poses.json"))
        return _hashes(out)


if __name__ == "__main__":
    print(json.dumps({bits_class(): golden_hashes()}, indent=1, sort_keys=True))
