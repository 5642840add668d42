"""The code blocks of the documentation, found and run as a reader would run them.

A page's fenced blocks run in order, in one fresh folder per page (with a copy of the
repository's ``examples/`` and ``plugins/``, the folders the pages name), the venv's
``lidarsim`` first on ``PATH``:

* ``python`` blocks run in one namespace per page, as in one interactive session (a block may
  use what an earlier block of the page defined);
* ``bash``/``sh`` blocks run with ``bash -euo pipefail``;
* other languages (yaml, toml, text, ...) are shown, not run.

The fence's ``title`` says what else a block is (the rule, never a list of blocks):

``title="output"``
    What the block before it prints; compared with what it printed (``...`` stands for any
    text, runs of white space are one space).
``title="signature"``
    A signature (a hook, a function): shown, not run.
``title="synopsis"``
    Command forms with placeholders (``DIR``, ``[--option]``): shown, not run.
``title="install"``
    Installs, builds or tests lidarsim itself (``pip install``, ``pytest``, ``mkdocs``): not
    run, since the blocks run inside such an installation (``.ci/run`` runs these).
``title="example"``
    Code for a library lidarsim does not install (PyTorch in docs/training.md): shown, not
    run here; the page's own test runs it where that library is installed.
``title="<file name>"`` (a name with a suffix, e.g. ``title="my_scenario.yaml"``)
    The file's text: written to that path of the page's folder before the blocks after it
    run (a Python or shell block with a file title is written, not run).

Run as a script (``python doc_blocks.py PAGE FOLDER RESULT.json``) it executes one page and
writes what each block printed; ``tests/test_docs_run.py`` drives it.
"""

from __future__ import annotations

import contextlib
import io
import json
import os
import re
import subprocess
import sys
import textwrap
import time
import traceback
import types
from dataclasses import asdict, dataclass
from pathlib import Path

RUN_LANGUAGES = {"python": "python", "py": "python", "bash": "bash", "sh": "bash",
                 "shell": "bash"}
NOT_RUN_TITLES = {"signature", "synopsis", "install", "example"}
_FENCE = re.compile(r"^(?P<indent>[ \t]*)(?P<fence>```+|~~~+)(?P<info>.*)$")


@dataclass
class Block:
    """One fenced code block of a page."""

    page: str
    line: int          # 1-based line of the opening fence
    language: str
    title: str | None
    text: str

    @property
    def action(self) -> str:
        """``run-python``, ``run-bash``, ``write`` (a file), ``output`` or ``show``."""
        if self.title == "output":
            return "output"
        if self.title and self.title not in NOT_RUN_TITLES and "." in self.title:
            return "write"
        if self.title in NOT_RUN_TITLES or self.language not in RUN_LANGUAGES:
            return "show"
        return f"run-{RUN_LANGUAGES[self.language]}"

    @property
    def where(self) -> str:
        return f"{self.page}:{self.line}"


def _title(info: str) -> str | None:
    match = re.search(r"""title=(?:"([^"]*)"|'([^']*)'|(\S+))""", info)
    if match is None:
        return None
    return next(g for g in match.groups() if g is not None)


def blocks(path: Path, root: Path) -> list[Block]:
    """The fenced blocks of the Markdown file ``path``, in order."""
    lines = path.read_text(encoding="utf-8").splitlines()
    out: list[Block] = []
    i = 0
    while i < len(lines):
        match = _FENCE.match(lines[i])
        if match is None:
            i += 1
            continue
        fence, info = match["fence"], match["info"].strip()
        end = i + 1
        while end < len(lines) and not re.match(rf"^[ \t]*{re.escape(fence)}\s*$", lines[end]):
            end += 1
        body = textwrap.dedent("\n".join(lines[i + 1:end]))
        language = info.split()[0].lower() if info else ""
        language = language.split("{")[0]
        out.append(Block(path.relative_to(root).as_posix(), i + 1, language, _title(info),
                         body + "\n" if body else ""))
        i = end + 1
    return out


@dataclass
class Result:
    """What one block did."""

    where: str
    action: str
    ok: bool
    stdout: str
    error: str
    seconds: float


def run_page(page: Path, root: Path, folder: Path, *, timeout_s: float = 900.0
             ) -> list[Result]:
    """Run the blocks of ``page`` in ``folder`` (see the module docstring); stops at the first
    block that fails."""
    os.chdir(folder)
    sys.argv = [""]  # as in an interactive session
    module = types.ModuleType("__main__")  # what the page's Python blocks define lives here
    module.__dict__["__builtins__"] = __builtins__
    sys.modules["__main__"] = module
    env = {**os.environ, "PATH": f"{Path(sys.executable).parent}{os.pathsep}"
                                 f"{os.environ.get('PATH', '')}"}
    results: list[Result] = []
    for block in blocks(page, root):
        action = block.action
        started = time.perf_counter()
        stdout, error = "", ""
        if action == "write":
            target = folder / block.title
            target.parent.mkdir(parents=True, exist_ok=True)
            target.write_text(block.text, encoding="utf-8")
        elif action == "run-python":
            buffer = io.StringIO()
            try:
                with contextlib.redirect_stdout(buffer):
                    exec(compile(block.text, block.where, "exec"), module.__dict__)
            except BaseException:  # noqa: BLE001 - reported with the block's place
                error = traceback.format_exc(limit=-4)
            stdout = buffer.getvalue()
        elif action == "run-bash":
            try:
                res = subprocess.run(["bash", "-euo", "pipefail", "-c", block.text], cwd=folder,
                                     env=env, capture_output=True, text=True,
                                     timeout=timeout_s)
                stdout = res.stdout
                if res.returncode != 0:
                    error = f"exit {res.returncode}: {res.stderr[-3000:]}"
            except subprocess.TimeoutExpired:
                error = f"timed out after {timeout_s:g} s"
        results.append(Result(block.where, action, not error, stdout, error,
                              time.perf_counter() - started))
        if error:
            break
    return results


def main(argv: list[str]) -> int:
    page, folder, result = (Path(a).resolve() for a in argv)
    root = Path(__file__).resolve().parents[1]
    results = run_page(page, root, folder)
    result.write_text(json.dumps([asdict(r) for r in results], indent=1), encoding="utf-8")
    return 0


if __name__ == "__main__":
    sys.exit(main(sys.argv[1:]))

