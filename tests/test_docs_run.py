"""Every code block of the README and of docs/ runs as written, in order, from a fresh folder,
and prints what the page shows after it (the rules: ``tests/doc_blocks.py``)."""

from __future__ import annotations

import doctest
import json
import shutil
import subprocess
import sys
from pathlib import Path

import pytest

sys.path.insert(0, str(Path(__file__).parent))
import doc_blocks  # noqa: E402

ROOT = Path(__file__).resolve().parents[1]
PAGES = [ROOT / "README.md"] + sorted((ROOT / "docs").glob("*.md"))
CHECKER = doctest.OutputChecker()
FLAGS = doctest.ELLIPSIS | doctest.NORMALIZE_WHITESPACE


def _runnable(page: Path) -> bool:
    return any(b.action.startswith("run-") for b in doc_blocks.blocks(page, ROOT))


def _run(page: Path, folder: Path) -> list[dict]:
    for name in ("examples", "plugins"):  # the folders of the clone the pages name
        shutil.copytree(ROOT / name, folder / name,
                        ignore=shutil.ignore_patterns("*.egg-info", "__pycache__", "build"))
    result = folder.parent / f"{folder.name}.json"
    proc = subprocess.run([sys.executable, str(Path(doc_blocks.__file__)), str(page),
                           str(folder), str(result)], capture_output=True, text=True,
                          timeout=3600)
    assert proc.returncode == 0, proc.stderr[-3000:]
    return json.loads(result.read_text())


def _check(page: Path, results: list[dict], root: Path = ROOT) -> None:
    failed = [r for r in results if not r["ok"]]
    assert not failed, f"{failed[0]['where']} fails as written:\n{failed[0]['error']}"
    shown = doc_blocks.blocks(page, root)
    assert len(results) == len(shown), "a block did not run"
    for i, (block, result) in enumerate(zip(shown, results)):
        if block.action != "output":
            continue
        before = next((b, r) for b, r in zip(reversed(shown[:i]), reversed(results[:i]))
                      if b.action != "show")
        assert before[0].action.startswith("run-"), \
            f"{block.where}: an output block must follow a block that runs"
        printed = before[1]["stdout"]
        assert CHECKER.check_output(block.text, printed, FLAGS), \
            (f"{block.where}: the page shows\n{block.text}\nbut {before[0].where} printed\n"
             f"{printed}")


@pytest.mark.slow
@pytest.mark.parametrize("page", [p for p in PAGES if _runnable(p)],
                         ids=lambda p: p.relative_to(ROOT).as_posix())
def test_page_runs_as_written(page, tmp_path):
    folder = tmp_path / "reader"
    folder.mkdir()
    _check(page, _run(page, folder))


# ---- the rules themselves (fast) ------------------------------------------------------------
def test_every_runnable_block_is_python_or_shell_and_titles_are_known(tmp_path):
    seen = set()
    for page in PAGES:
        for block in doc_blocks.blocks(page, ROOT):
            seen.add(block.action)
            if block.title is not None:
                assert block.title in doc_blocks.NOT_RUN_TITLES | {"output"} or \
                    "." in block.title, f"{block.where}: unknown title {block.title!r}"
    assert {"run-python", "run-bash", "output", "write", "show"} <= seen


#: Libraries that ``title="example"`` blocks may use: none of lidarsim's extras installs them.
NOT_INSTALLED_LIBRARIES = ("torch",)


def test_signatures_and_synopses_are_the_only_code_left_unrun():
    """A Python block not run is a signature or an example for a library lidarsim does not
    install; a shell block not run is a synopsis (it has a placeholder) or an install/test
    step."""
    for page in PAGES:
        for block in doc_blocks.blocks(page, ROOT):
            if block.language == "python" and block.title == "example":
                # code for a library lidarsim does not install, run by its page's own test
                assert any(f"import {lib}" in block.text for lib in NOT_INSTALLED_LIBRARIES), \
                    block.where
                continue
            if block.language == "python" and block.action == "show":
                assert block.title == "signature", block.where
                assert block.text.lstrip().startswith("def ") and \
                    block.text.rstrip().endswith("..."), block.where
            if block.language == "bash" and block.title == "install":
                assert any(w in block.text for w in ("pip install", "pytest", "mkdocs",
                                                     "python3 -m venv")), block.where


def test_the_runner_reports_failures_and_compares_output(tmp_path):
    page = tmp_path / "page.md"
    page.write_text(
        "```python\nx = 2\nprint(x * 21)\n```\n\n```text title=\"output\"\n42\n```\n\n"
        "```yaml title=\"sub/f.yaml\"\na: 1\n```\n\n"
        "```bash\ncat sub/f.yaml\n```\n\n```text title=\"output\"\na: ...\n```\n\n"
        "```python title=\"signature\"\ndef f(x: int) -> None: ...\n```\n\n"
        "```python\nprint(x)\n```\n\n```text title=\"output\"\n3\n```\n\n"
        "```bash\nfalse\n```\n")
    folder = tmp_path / "run"
    folder.mkdir()
    proc = subprocess.run([sys.executable, "-c", (
        "import json, sys; sys.path.insert(0, sys.argv[1]); import doc_blocks; "
        "from dataclasses import asdict; from pathlib import Path; "
        "r = doc_blocks.run_page(Path(sys.argv[2]), Path(sys.argv[3]), Path(sys.argv[4])); "
        "print(json.dumps([asdict(x) for x in r]))"),
        str(Path(doc_blocks.__file__).parent), str(page), str(tmp_path), str(folder)],
        capture_output=True, text=True, timeout=120)
    assert proc.returncode == 0, proc.stderr
    results = json.loads(proc.stdout.splitlines()[-1])
    assert [r["action"] for r in results] == ["run-python", "output", "write", "run-bash",
                                             "output", "show", "run-python", "output",
                                             "run-bash"]
    assert results[3]["stdout"] == "a: 1\n" and not results[-1]["ok"]
    assert (folder / "sub" / "f.yaml").read_text() == "a: 1\n"
    with pytest.raises(AssertionError, match="page.md:34 fails as written"):
        _check(page, results, tmp_path)
    with pytest.raises(AssertionError, match="page.md:30: the page shows"):
        _check(page, results[:-1] + [{**results[-1], "ok": True, "error": ""}], tmp_path)
