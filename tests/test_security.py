"""Security: configuration never runs code, no file is ever unpickled, plugins come only from
installed entry points or explicitly named modules, and output names stay where the user
pointed them.

Code that must never run writes a marker file; every test checks the marker is absent.
"""

from __future__ import annotations

import ast
import pickle
import sys
from pathlib import Path

import numpy as np
import pytest
from hypothesis import given, settings
from hypothesis import strategies as st

from lidarsim_core.base.errors import (
    ConfigError,
    OutputError,
    PatternFileError,
    UnknownNameError,
)

SRC = Path(__file__).resolve().parents[1] / "src" / "lidarsim_core"


def _tags(marker: Path) -> list[str]:
    return [f"!!python/object/apply:os.system ['touch {marker}']",
            f"!!python/object/apply:pathlib.Path.touch [!!python/object/apply:pathlib.Path "
            f"['{marker}']]",
            "!!python/name:os.getcwd", "!!python/module:os",
            f"!!python/object/new:pathlib.Path ['{marker}']"]


def _readers():
    from lidarsim_core.base.config_io import read_config_file
    from lidarsim_core.dataset.config import load_plan
    from lidarsim_core.scenario.datasheet import load_datasheet
    from lidarsim_core.scenario import load_scenario
    from lidarsim_core.trajectories.keyframes import load_keyframe_file

    return {"config": read_config_file, "scenario": load_scenario,
            "datasheet": load_datasheet, "dataset": load_plan, "keyframes": load_keyframe_file}


@pytest.mark.parametrize("reader", sorted(_readers()))
def test_yaml_tags_are_refused_and_never_run(tmp_path, reader):
    marker = tmp_path / "pwned"
    for i, tag in enumerate(_tags(marker)):
        path = tmp_path / f"evil{i}.yaml"
        path.write_text(f"seed: 1\nvalue: {tag}\n")
        with pytest.raises(ConfigError) as info:
            _readers()[reader](path)
        message = str(info.value)
        assert "\n" not in message and path.name in message
        assert "is not allowed: configuration files hold plain data only" in message
    assert not marker.exists()


@pytest.mark.parametrize("text, expected", [
    ("a: &a [1,1,1,1,1,1,1,1,1,1]\n" + "".join(
        f"{chr(98 + i)}: &{chr(98 + i)} [{', '.join([f'*{chr(97 + i)}'] * 10)}]\n"
        for i in range(8)), "expands to more than 1,000,000 values"),
    ("a: &a [1, *a]\n", "contains itself"),
], ids=["alias-bomb", "recursive-alias"])
def test_yaml_aliases_cannot_blow_up(tmp_path, text, expected):
    from lidarsim_core.base.config_io import read_config_file

    path = tmp_path / "bomb.yaml"
    path.write_text(text)
    with pytest.raises(ConfigError, match=expected):
        read_config_file(path)


def test_deep_nesting_is_one_line_not_a_crash(tmp_path):
    from lidarsim_core.base.config_io import read_config_file

    path = tmp_path / "deep.json"
    path.write_text('{"x": ' + "[" * 100000 + "]" * 100000 + "}")
    with pytest.raises(ConfigError, match="nested too deeply"):
        read_config_file(path)


def test_shared_yaml_anchors_still_work(tmp_path):
    """Aliases are refused only when they blow up: reusing a pose is fine."""
    from lidarsim_core.base.config_io import read_config_file

    path = tmp_path / "ok.yaml"
    path.write_text("a: &p {position_m: [1, 2, 3]}\nb: *p\nc:\n  <<: *p\n  extra: 1\n")
    data = read_config_file(path)
    assert data["b"] == {"position_m": [1, 2, 3]}
    assert data["c"] == {"position_m": [1, 2, 3], "extra": 1}


def test_both_yaml_parsers_read_the_same_and_refuse_the_same(tmp_path):
    """Configuration is parsed by libyaml where PyYAML has it, and a document it refuses by
    PyYAML's own parser again (its messages): on every YAML file of the repository both give
    the same data, both refuse tags and repeated keys, and a malformed file gets PyYAML's
    message, with the line and column of the problem."""
    import yaml

    from lidarsim_core.base.config_io import _safe_loaders, read_config_file

    fast, plain = _safe_loaders()
    if getattr(yaml, "__with_libyaml__", False):
        assert fast is not plain and issubclass(fast, yaml.CSafeLoader)
    files = sorted(SRC.parents[1].glob("sensors/*.yaml")) + \
        sorted(SRC.parents[1].glob("examples/**/*.yaml"))
    assert len(files) >= 12
    for path in files:
        text = path.read_text(encoding="utf-8")
        assert yaml.load(text, Loader=fast) == yaml.load(text, Loader=plain), path
    marker = tmp_path / "pwned"
    for loader in (fast, plain):
        for text in ["a: 1\na: 2\n"] + [f"value: {tag}\n" for tag in _tags(marker)]:
            with pytest.raises(yaml.constructor.ConstructorError):
                yaml.load(text, Loader=loader)
    assert not marker.exists()
    path = tmp_path / "bad.yaml"
    path.write_text("a:\n\t- 1\n")
    with pytest.raises(ConfigError, match=r"line 2, column 1: found character '\\t' that "
                                          r"cannot start any token"):
        read_config_file(path)


class _Touch:
    """Unpickling this creates the marker file: proof that a pickle was loaded."""

    def __init__(self, marker: Path) -> None:
        self.marker = marker

    def __reduce__(self):
        return (Path.touch, (self.marker,))


def test_point_cloud_files_are_never_unpickled(tmp_path):
    from lidarsim_core.io.npz import read_npz

    marker = tmp_path / "pwned"
    path = tmp_path / "evil.npz"
    np.savez(path, x=np.array([_Touch(marker)], dtype=object),
             frame_json=np.array([_Touch(marker)], dtype=object))
    pickle.loads(pickle.dumps(_Touch(tmp_path / "control")))  # the payload does work...
    assert (tmp_path / "control").exists()
    from lidarsim_core.base.errors import ConfigError

    with pytest.raises(ConfigError, match="allow_pickle"):
        read_npz(path)
    assert not marker.exists()  # ...but lidarsim never ran it


def test_pattern_tables_are_never_unpickled(tmp_path):
    from lidarsim_core.patterns.table_io import read_pattern_table

    marker = tmp_path / "pwned"
    path = tmp_path / "evil.npy"
    np.save(path, np.array([_Touch(marker)], dtype=object), allow_pickle=True)
    with pytest.raises(PatternFileError, match="pickles are never loaded"):
        read_pattern_table(path)
    assert not marker.exists()


def _calls(tree: ast.AST):
    for node in ast.walk(tree):
        if isinstance(node, ast.Call):
            yield node, ast.unparse(node.func)


def test_the_source_has_no_unsafe_loading():
    """Static check of the package: no pickle/marshal/shelve, no eval/exec, YAML only through
    the safe loader, every NumPy load with allow_pickle=False."""
    problems = []
    for path in sorted(SRC.rglob("*.py")):
        tree = ast.parse(path.read_text(encoding="utf-8"))
        where = path.relative_to(SRC)
        for node in ast.walk(tree):
            names = []
            if isinstance(node, ast.Import):
                names = [a.name for a in node.names]
            elif isinstance(node, ast.ImportFrom):
                names = [node.module or ""]
            for name in names:
                if name.split(".")[0] in ("pickle", "marshal", "shelve", "dill", "cloudpickle"):
                    problems.append(f"{where}: imports {name}")
        for call, func in _calls(tree):
            if func in ("eval", "exec", "compile", "__import__"):
                problems.append(f"{where}:{call.lineno}: calls {func}()")
            if func.endswith(("unsafe_load", "full_load", "yaml.load_all")):
                problems.append(f"{where}:{call.lineno}: calls {func}()")
            if func == "yaml.load":
                loader = {k.arg: ast.unparse(k.value) for k in call.keywords}.get("Loader", "")
                if loader not in ("_safe_loaders()[0]", "_safe_loaders()[1]"):
                    problems.append(f"{where}:{call.lineno}: yaml.load with Loader={loader!r}")
            if func in ("np.load", "numpy.load"):
                kw = {k.arg: ast.unparse(k.value) for k in call.keywords}
                if kw.get("allow_pickle") != "False":
                    problems.append(f"{where}:{call.lineno}: np.load without allow_pickle=False")
    assert not problems, "\n".join(problems)


# ---- plugins -----------------------------------------------------------------------------
PLUGIN = '''
from pathlib import Path
Path({marker!r}).touch()

from lidarsim_core.hookspecs import hookimpl
from lidarsim_core.backends.numpy_backend import NumpyBackend


class Marked(NumpyBackend):
    """A backend from a module that is merely on sys.path."""

    name = "marked"


@hookimpl
def lidarsim_register_ray_backends(register):
    register(Marked)
'''


@pytest.fixture
def on_path(tmp_path, monkeypatch, fresh_registry):
    """A plugin module on sys.path that marks its import; it is no installed distribution."""
    marker = tmp_path / "imported"
    (tmp_path / "lidarsim_marker_plugin.py").write_text(PLUGIN.format(marker=str(marker)))
    monkeypatch.syspath_prepend(str(tmp_path))
    monkeypatch.setenv("LIDARSIM_DISABLE_PLUGIN_AUTOLOAD", "0")
    monkeypatch.delenv("LIDARSIM_PLUGINS", raising=False)
    yield marker
    sys.modules.pop("lidarsim_marker_plugin", None)


def test_modules_on_the_path_are_not_plugins_unless_named(on_path, monkeypatch):
    from helpers import scenario

    from lidarsim_core.pipeline import Simulation
    from lidarsim_core.plugins import build_registry, reset_registry

    registry = build_registry()
    assert "marked" not in registry.names("ray_backend")
    # a scenario naming the module (or the backend) loads nothing
    for name in ("marked", "lidarsim_marker_plugin", "lidarsim_marker_plugin.Marked"):
        with pytest.raises(UnknownNameError):
            Simulation(scenario({"model": "plate"}, backend=name))
    assert not on_path.exists()
    # naming the module explicitly is the one way in (like ``pytest -p``)
    monkeypatch.setenv("LIDARSIM_PLUGINS", "lidarsim_marker_plugin")
    reset_registry()
    assert build_registry().entry("ray_backend", "marked").provider == \
        "module lidarsim_marker_plugin"
    assert on_path.exists()


def test_pkg_pattern_paths_locate_packages_without_importing_them(tmp_path, monkeypatch):
    from lidarsim_core.patterns.table_io import resolve_table_path

    marker = tmp_path / "imported"
    package = tmp_path / "lidarsim_marker_pkg"
    (package / "sub").mkdir(parents=True)
    (package / "__init__.py").write_text(f"from pathlib import Path\nPath({str(marker)!r})"
                                         ".touch()\n")
    (package / "sub" / "__init__.py").write_text("")
    (package / "mode.csv").write_text("t_s,azimuth_deg,elevation_deg\n0,0,0\n")
    monkeypatch.syspath_prepend(str(tmp_path))
    try:
        assert resolve_table_path("pkg:lidarsim_marker_pkg/mode.csv") == package / "mode.csv"
        with pytest.raises(PatternFileError, match="top-level package"):
            resolve_table_path("pkg:lidarsim_marker_pkg.sub/mode.csv")
        with pytest.raises(PatternFileError, match="not installed"):
            resolve_table_path("pkg:lidarsim_no_such_pkg/mode.csv")
        assert not marker.exists()
    finally:
        sys.modules.pop("lidarsim_marker_pkg", None)


# ---- output paths ------------------------------------------------------------------------
fields = st.sampled_from(["frame", "seed", "frame.real", "frame[0]", "", "0", "frame.__class__",
                          "out"])
specs = st.text(alphabet="0123456789d/\\<>^.x-+ ,_=#%", max_size=6)


@settings(max_examples=300, deadline=None)
@given(fields, st.one_of(st.none(), specs), st.sampled_from(["", "!r", "!s"]),
       st.sampled_from(["out", "a/b", "/tmp/x", "../up"]))
def test_frame_templates_cannot_leave_the_directory(field, spec, conversion, directory):
    from lidarsim_core.io.paths import frame_paths

    template = f"{directory}/cloud_{{{field}{conversion}{'' if spec is None else ':' + spec}}}.ply"
    try:
        paths = frame_paths(template, range(12))
    except OutputError as exc:
        assert "\n" not in str(exc)
        return
    assert field == "frame" and conversion == ""
    assert all(p.parent == Path(directory) for p in paths), paths
    assert all(p.name.startswith("cloud_") and p.name.endswith(".ply") for p in paths)
    assert len(set(paths)) == 12  # one file per frame


def test_dataset_sequence_names_cannot_leave_the_dataset():
    from lidarsim_core.dataset.config import SequenceSpec

    for name in ("../outside", "a/b", "/abs", ".hidden", "..", "a\\b"):
        with pytest.raises(ValueError):
            SequenceSpec(scenario=Path("s.yaml"), name=name)
