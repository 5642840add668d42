"""The package's layers stay honest (docs/architecture.md): no import circle between modules,
counting every import statement (module level, under ``TYPE_CHECKING`` and in functions), a
small top level, nothing below the simulation touching its private members, the
import-linter contracts kept, and every moved import path still working."""

from __future__ import annotations

import ast
import importlib
import re
import shutil
import subprocess
import sys
import warnings
from pathlib import Path

import pytest

import lidarsim_core

PACKAGE = Path(lidarsim_core.__file__).parent
ROOT = PACKAGE.parent.parent


def _modules() -> dict[str, tuple[Path, bool]]:
    out = {}
    for path in sorted(PACKAGE.rglob("*.py")):
        parts = ["lidarsim_core", *path.relative_to(PACKAGE).with_suffix("").parts]
        is_pkg = parts[-1] == "__init__"
        out[".".join(parts[:-1] if is_pkg else parts)] = (path, is_pkg)
    return out


def _graph() -> dict[str, set[str]]:
    """Module → the modules it imports, from every import statement in the source."""
    mods = _modules()
    graph: dict[str, set[str]] = {name: set() for name in mods}
    for name, (path, is_pkg) in mods.items():
        for node in ast.walk(ast.parse(path.read_text(encoding="utf-8"))):
            if isinstance(node, ast.Import):
                targets = [alias.name for alias in node.names]
            elif isinstance(node, ast.ImportFrom):
                if node.level:
                    base = name.split(".")[:None if is_pkg else -1]
                    base = base[:len(base) - node.level + 1]
                    module = ".".join(base + ([node.module] if node.module else []))
                else:
                    module = node.module or ""
                targets = [f"{module}.{a.name}" if f"{module}.{a.name}" in mods else module
                           for a in node.names]
            else:
                continue
            for target in targets:
                while target not in mods and "." in target:
                    target = target.rsplit(".", 1)[0]
                if target in mods and target != name:
                    graph[name].add(target)
    return graph


def _cycle(graph: dict[str, set[str]]) -> list[str] | None:
    """One import circle of ``graph`` (depth-first search), or None."""
    state: dict[str, int] = {}
    stack: list[str] = []

    def visit(node: str) -> list[str] | None:
        state[node] = 1
        stack.append(node)
        for nxt in sorted(graph[node]):
            if state.get(nxt) == 1:
                return stack[stack.index(nxt):] + [nxt]
            if nxt not in state:
                found = visit(nxt)
                if found:
                    return found
        stack.pop()
        state[node] = 2
        return None

    sys.setrecursionlimit(max(10000, sys.getrecursionlimit()))
    for node in sorted(graph):
        if node not in state:
            found = visit(node)
            if found:
                return found
    return None


def test_no_import_circle_between_modules():
    assert _cycle(_graph()) is None


def test_the_cycle_search_finds_a_circle():
    # the check above can fail: a circle of three is found, a chain is not
    assert _cycle({"a": {"b"}, "b": {"c"}, "c": {"a"}}) == ["a", "b", "c", "a"]
    assert _cycle({"a": {"b"}, "b": {"c"}, "c": set()}) is None


def test_nothing_the_simulation_imports_imports_it_back():
    graph = _graph()
    home = "lidarsim_core.pipeline.simulation"
    reached, todo = set(), [home]
    while todo:
        for nxt in graph[todo.pop()]:
            if nxt not in reached:
                reached.add(nxt)
                todo.append(nxt)
    assert home not in reached
    assert "lidarsim_core.pipeline.context" in reached  # the search does follow imports


def test_the_top_level_holds_at_most_six_modules():
    top = sorted(p.name for p in PACKAGE.glob("*.py"))
    assert len(top) <= 6, top


PRIVATE = re.compile(r"\b_?(?:sim|simulation)\._[A-Za-z]\w*")


def test_no_private_member_of_a_simulation_is_used_outside_its_module():
    home = PACKAGE / "pipeline" / "simulation.py"
    uses = [f"{path.relative_to(ROOT)}:{i}" for path in PACKAGE.rglob("*.py") if path != home
            for i, line in enumerate(path.read_text(encoding="utf-8").splitlines(), 1)
            if PRIVATE.search(line)]
    assert not uses


@pytest.mark.skipif(shutil.which("lint-imports", path=str(Path(sys.executable).parent)) is None,
                    reason="import-linter is not installed (extra 'test')")
def test_the_import_linter_contracts_are_kept():
    tool = shutil.which("lint-imports", path=str(Path(sys.executable).parent))
    result = subprocess.run([tool, "--no-cache"], cwd=ROOT, capture_output=True, text=True)
    assert result.returncode == 0, result.stdout[-3000:]
    assert "0 broken" in result.stdout


def test_every_moved_module_imports_under_its_old_path_with_a_warning():
    from lidarsim_core import _compat

    for old, new in _compat.MOVED.items():
        sys.modules.pop(f"lidarsim_core.{old}", None)
        with pytest.warns(DeprecationWarning, match=f"lidarsim_core.{new}"):
            module = importlib.import_module(f"lidarsim_core.{old}")
        target = importlib.import_module(f"lidarsim_core.{new}")
        # the moved module keeps its own name for pickles, spawned workers, relative imports
        assert target.__spec__.name == f"lidarsim_core.{new}"
        for name in _compat.SPLIT.get(old, {}):
            home = importlib.import_module(f"lidarsim_core.{_compat.SPLIT[old][name]}")
            assert getattr(module, name) is getattr(home, name), (old, name)
        public = [n for n in vars(target) if not n.startswith("_")]
        for name in public:
            assert getattr(module, name) is getattr(target, name), (old, name)


@pytest.mark.parametrize("statement, new", [
    ("from lidarsim_core.components import ComponentOptions",
     "from lidarsim_core.base.components import ComponentOptions"),
    ("from lidarsim_core.datasheet import load_datasheet",
     "from lidarsim_core.scenario.datasheet import load_datasheet"),
    ("from lidarsim_core.poses import PoseConfig", "from lidarsim_core.scenario import PoseConfig"),
    ("from lidarsim_core.poses import Poses", "from lidarsim_core.geometry.poses import Poses"),
    ("from lidarsim_core.patterns.coverage import pattern_for",
     "from lidarsim_core.plugins import pattern_for"),
    ("from lidarsim_core.patterns.coverage import fov_coverage",
     "from lidarsim_core.patterns.fov import fov_coverage"),
    ("from lidarsim_core.stages.sun import SunConfig",
     "from lidarsim_core.scenario.sun import SunConfig"),
    ("from lidarsim_core.targets import TargetModel",
     "from lidarsim_core.scene.targets import TargetModel"),
    ("from lidarsim_core.demo import demo_scenario", "from lidarsim_core.scenario import demo_scenario"),
    ("from lidarsim_core.errors import ConfigError", "from lidarsim_core.base.errors import ConfigError"),
    ("from lidarsim_core.io.sidecar import read_sidecar",
     "from lidarsim_core.io.sidecar import read_sidecar"),
])
def test_documented_old_imports_give_the_new_objects(statement, new):
    old_ns: dict = {}
    new_ns: dict = {}
    with warnings.catch_warnings():
        warnings.simplefilter("ignore", DeprecationWarning)
        exec(statement, old_ns)
    exec(new, new_ns)
    name = statement.rsplit(" ", 1)[1]
    assert old_ns[name] is new_ns[name]


def test_hook_specs_keep_their_path_and_marker():
    from lidarsim_core.hookspecs import hookimpl, hookspec

    assert hookimpl.project_name == hookspec.project_name == "lidarsim"


def test_point_cloud_shortcuts_are_attached_for_the_public_names():
    code = ("import lidarsim_core as ls; c = ls.PointCloud; "
            "print(hasattr(c, 'save'), hasattr(c, 'range_image'))")
    out = subprocess.run([sys.executable, "-c", code], capture_output=True, text=True, check=True)
    assert out.stdout.split() == ["True", "True"]
