"""The process the fuzzer runs its cases in: bounded memory, one case at a time.

Started by :class:`fuzz.harness.Worker` as ``python worker.py MEMORY_BYTES``. It caps its
address space with ``resource.setrlimit`` (a case that tries to allocate too much fails with a
MemoryError inside this process, never on the machine), then reads one JSON case per line on
stdin (``{"dir", "argv", "env"}``), runs ``lidarsim ARGV`` in process (the real entry point,
with its usage-error handling) in ``dir`` with ``env`` added (or, for a reader case with
``"api"``, the Python reader it names: ``read``, ``mesh`` or ``dataset``), and writes one JSON result per
line to the protocol stream: the exit code, stdout, stderr, wall time and peak memory. An
exception that escapes the command line is reported with its traceback. The parent enforces
the time bound (it kills the worker when a case hangs).

``LIDARSIM_FUZZ_DISABLE=module:function`` replaces that function by one that does nothing,
to show that the fuzzer finds what a removed validator lets through (see docs/reliability.md).
"""

from __future__ import annotations

import contextlib
import io
import json
import os
import resource
import sys
import time
import traceback
import warnings


def _disable(spec: str) -> None:
    import importlib

    for item in filter(None, spec.split(",")):
        module_name, _, name = item.partition(":")
        module = importlib.import_module(module_name)
        setattr(module, name, lambda *args, **kwargs: None)
        # modules that imported the function by name get the no-op too
        for other in list(sys.modules.values()):
            if other is not None and getattr(other, "__name__", "").startswith("lidarsim_core") \
                    and getattr(other, name, None) is not None and other is not module:
                if callable(getattr(other, name)) and getattr(getattr(other, name),
                                                              "__module__", "") == module_name:
                    setattr(other, name, lambda *args, **kwargs: None)


def _api(name: str, argv: list[str]) -> None:
    """The Python API readers a reader case calls (``{"api": NAME}``): a user error prints one
    ``error:`` line and exits 2, as the command line does."""
    from lidarsim_core.base.errors import UserInputError
    from lidarsim_core.base.terminal import terminal_safe

    try:
        if name == "read":
            import lidarsim_core as ls

            cloud = ls.read(argv[0])
            lengths = {len(values) for values in cloud.columns.values()}
            assert len(lengths) == 1, f"columns of different lengths {lengths}"
            assert lengths == {len(cloud)}, "the cloud's length is not its columns'"
        elif name == "mesh":
            import numpy as np

            from lidarsim_core.scene.mesh import load_mesh_file

            mesh = load_mesh_file(argv[0])
            assert len(mesh.faces) and np.all(np.isfinite(mesh.vertices))
            assert mesh.faces.min() >= 0 and mesh.faces.max() < len(mesh.vertices)
        elif name == "dataset":
            from lidarsim_core.evaluate.data import open_dataset, read_frame_columns

            sequences, _ = open_dataset(argv[0])
            for seq in sequences:
                index = seq.target_index(None)
                for entry in seq.frames:
                    read_frame_columns(entry.path)
                    seq.truth(entry.frame, index, 0.0)
        else:
            raise ValueError(f"unknown api case {name}")
    except UserInputError as exc:
        sys.stderr.write("error: " + terminal_safe(" ".join(str(exc).split())) + "\n")
        raise SystemExit(2) from None
    raise SystemExit(0)


def main() -> None:
    memory = int(sys.argv[1])
    resource.setrlimit(resource.RLIMIT_AS, (memory, memory))
    protocol = os.fdopen(os.dup(sys.stdout.fileno()), "w", buffering=1)
    os.environ.setdefault("LIDARSIM_DISABLE_PLUGIN_AUTOLOAD", "1")
    import lidarsim_core.pipeline  # noqa: F401  (imported before a case's clock starts)
    from lidarsim_core import cli

    if os.environ.get("LIDARSIM_FUZZ_DISABLE"):
        _disable(os.environ["LIDARSIM_FUZZ_DISABLE"])
    home = os.getcwd()
    protocol.write(json.dumps({"ready": True}) + "\n")
    for line in sys.stdin:
        case = json.loads(line)
        saved = {key: os.environ.get(key) for key in case["env"]}
        os.environ.update(case["env"])
        out, err = io.StringIO(), io.StringIO()
        code: object = None
        started = time.perf_counter()
        os.chdir(case["dir"])
        try:
            with contextlib.redirect_stdout(out), contextlib.redirect_stderr(err), \
                    warnings.catch_warnings():
                # every warning a user would see is shown, every time
                warnings.simplefilter("always")
                warnings.simplefilter("ignore", DeprecationWarning)
                warnings.simplefilter("ignore", PendingDeprecationWarning)
                try:
                    if case.get("api"):
                        _api(case["api"], case["argv"])
                    else:
                        cli.main(case["argv"])
                except SystemExit as stop:
                    code = stop.code if isinstance(stop.code, int) else 1
        except BaseException:  # noqa: BLE001 - reported to the parent as a contract breach
            code = "exception"
            err.write(traceback.format_exc())
        finally:
            os.chdir(home)
            for key, value in saved.items():
                if value is None:
                    os.environ.pop(key, None)
                else:
                    os.environ[key] = value
        protocol.write(json.dumps({
            "code": code, "stdout": out.getvalue()[-1_000_000:], "stderr": err.getvalue()[-4000:],
            "seconds": time.perf_counter() - started,
            "maxrss_kib": resource.getrusage(resource.RUSAGE_SELF).ru_maxrss}) + "\n")


if __name__ == "__main__":
    main()
