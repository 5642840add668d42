"""The documentation: every hook documented with its real signature, the generated references
complete, the guides' examples working, and the site building with warnings as errors."""

from __future__ import annotations

import ast
import importlib.util
import os
import re
import runpy
import subprocess
import sys
import types
from pathlib import Path

import numpy as np
import pytest
import yaml

ROOT = Path(__file__).resolve().parents[1]
DOCS = ROOT / "docs"


def _hookspecs() -> dict[str, str]:
    """Hook name → signature as written in hookspecs.py, e.g. ``(register: Register) -> None``."""
    import lidarsim_core.hookspecs as specs

    tree = ast.parse(Path(specs.__file__).read_text())
    out = {}
    for node in tree.body:
        if isinstance(node, ast.FunctionDef) and any(
                ast.unparse(d) == "hookspec" for d in node.decorator_list):
            returns = f" -> {ast.unparse(node.returns)}" if node.returns else ""
            out[node.name] = f"({ast.unparse(node.args)}){returns}"
    return out


def _normalise(signature: str) -> str:
    return re.sub(r"\s+", "", signature)


def test_every_hook_is_documented_with_its_signature():
    import lidarsim_core.hookspecs as specs

    specs_src = _hookspecs()
    # the AST view agrees with what pluggy sees as specs
    marked = {n for n, f in vars(specs).items() if getattr(f, "lidarsim_spec", None) is not None}
    assert set(specs_src) == marked and len(marked) >= 7
    text = (DOCS / "plugins.md").read_text()
    documented = {m.group(1): m.group(2) for m in
                  re.finditer(r"^def (lidarsim_\w+)(\(.*?\)\s*->\s*[^:]+):", text, re.M)}
    missing = sorted(set(specs_src) - set(documented))
    assert not missing, f"hooks missing from docs/plugins.md: {missing}"
    stale = sorted(set(documented) - set(specs_src))
    assert not stale, f"docs/plugins.md documents hooks that do not exist: {stale}"
    for name, signature in specs_src.items():
        assert _normalise(documented[name]) == _normalise(signature), \
            f"{name}: documented {documented[name]!r}, hookspecs.py says {signature!r}"


def test_the_signature_check_catches_a_difference():
    spec = _hookspecs()["lidarsim_register_sensors"]
    assert _normalise(spec) == _normalise("(register: Register) -> None")
    assert _normalise(spec) != _normalise("(register, extra: int) -> None")


# ---- site structure ------------------------------------------------------------------------
def _nav_files() -> list[str]:
    def walk(node):
        if isinstance(node, str):
            yield node
        elif isinstance(node, list):
            for item in node:
                yield from walk(item)
        elif isinstance(node, dict):
            for value in node.values():
                yield from walk(value)

    config = yaml.safe_load((ROOT / "mkdocs.yml").read_text())
    return list(walk(config["nav"]))


def test_nav_lists_every_page_and_only_existing_ones():
    nav = _nav_files()
    pages = {p.relative_to(DOCS).as_posix() for p in DOCS.rglob("*.md")}
    assert sorted(pages - set(nav)) == [], "pages missing from the mkdocs.yml nav"
    assert sorted(set(nav) - pages) == [], "nav entries without a page"
    assert len(nav) == len(set(nav))


def test_images_in_the_docs_exist_and_are_pictures():
    from PIL import Image

    for page in DOCS.rglob("*.md"):
        for target in re.findall(r"!\[[^\]]*\]\(([^)]+\.png)\)", page.read_text()):
            path = (page.parent / target).resolve()
            assert path.is_file(), f"{page.name} shows a missing image {target}"
            with Image.open(path) as img:
                assert img.width >= 800 and img.height >= 500, target


# ---- generated references -----------------------------------------------------------------
@pytest.fixture(scope="module")
def gen():
    return runpy.run_path(str(DOCS / "gen_reference.py"), run_name="gen_reference_test")


def _model_paths(model, prefix=""):
    """Every dotted field path of a pydantic model, as the reference names them."""
    from pydantic import BaseModel

    def nested(annotation):
        import typing
        args = typing.get_args(annotation)
        if isinstance(annotation, type) and issubclass(annotation, BaseModel):
            yield "", annotation
        for a in args:
            for suffix, m in nested(a):
                is_list = typing.get_origin(annotation) in (list, tuple)
                yield ("[]" if is_list else "") + suffix, m

    for name, field in model.model_fields.items():
        yield prefix + name
        for suffix, sub in nested(field.annotation):
            yield from _model_paths(sub, f"{prefix}{name}{suffix}.")


def _table_rows_ok(markdown: str) -> None:
    for block in re.split(r"\n\s*\n", markdown):
        lines = [ln for ln in block.splitlines() if ln.startswith("|")]
        if lines:
            cells = {len(re.split(r"(?<!\\)\|", ln)) for ln in lines}
            assert len(cells) == 1, f"ragged table:\n{block}"


def test_scenario_reference_has_every_field_and_component(gen):
    from lidarsim_core.plugins import get_registry
    from lidarsim_core.scenario import Scenario
    from lidarsim_core.scenario import PoseConfig

    page = gen["scenario_reference"]()
    for path in _model_paths(Scenario):
        if ".pose." not in path:  # pose fields have their own table
            assert f"`{path}`" in page, path
    for path in _model_paths(PoseConfig):
        assert f"`{path}`" in page, path
    registry = get_registry()
    for kind in ("trajectory", "noise_model", "ray_backend", "target_model", "exporter"):
        for entry in registry.iter(kind):
            assert f"### `{entry.name}`" in page, (kind, entry.name)
            for option in entry.obj.Options.model_fields:
                assert f"`{option}`" in page or f".{option}`" in page, (entry.name, option)
    _table_rows_ok(page)


def test_datasheet_reference_has_every_field_and_pattern(gen):
    from lidarsim_core.plugins import get_registry
    from lidarsim_core.scenario.datasheet import SensorDatasheet

    page = gen["datasheet_reference"]()
    for path in _model_paths(SensorDatasheet):
        assert f"`{path}`" in page, path
    for entry in get_registry().iter("scan_pattern"):
        assert f"### `{entry.name}`" in page
    assert "`fov_type` | `circular` / `rectangular` / `panoramic` | required" in page
    _table_rows_ok(page)


def test_sensor_catalogue_has_one_row_per_datasheet_file(gen):
    from lidarsim_core.scenario.datasheet import load_datasheet

    page = gen["sensor_catalogue"]()
    files = sorted((ROOT / "sensors").glob("*.yaml"))
    rows = [ln for ln in page.splitlines() if ln.startswith("| [`")]
    assert len(rows) == len(files) >= 10
    for file in files:
        sheet = load_datasheet(file)
        row = next(r for r in rows if r.startswith(f"| [`{sheet.name}`]"))
        assert f"{sheet.fov_h_deg:g}°" in row and f"{sheet.point_rate_hz:,.0f}" in row
        assert f"## {sheet.name}\n" in page
    assert "| 70.4° circular | 0.05–130 | 100,000 | 20 mm | 0.1° | `rose` |" in page
    _table_rows_ok(page)


def test_type_names_are_readable(gen):
    from typing import Literal

    name = gen["type_name"]
    assert name(float | None) == "number or null"
    assert name(list[str]) == "list[string]"
    assert name(Literal["a", "b"]) == "`a` / `b`"
    assert name(tuple[float, float, float]) == "tuple[number, number, number]"


# ---- the guides' examples work ------------------------------------------------------------
def _plugin_examples() -> dict[str, str]:
    text = (DOCS / "plugins.md").read_text()
    return {m.group(1): m.group(2) for m in
            re.finditer(r"```python\n# example: (\w+)\n(.*?)```", text, re.S)}


def _registry_with(code: str, name: str):
    from lidarsim_core.plugins import build_plugin_manager, build_registry

    module = types.ModuleType(f"docs_example_{name}")
    exec(compile(code, f"docs/plugins.md ({name})", "exec"), module.__dict__)
    manager = build_plugin_manager()
    manager.register_plugin(module, module.__name__, "docs example")
    return build_registry(manager), module


def _scenario(**changes):
    from helpers import datasheet

    from lidarsim_core.scenario import scenario_from_dict

    data = {"seed": 3, "sensor": {"datasheet": datasheet()},
            "targets": [{"name": "t", "mesh": {"model": "plate", "options": {"size_m": [20, 20]}},
                         "pose": {"position_m": [10, 0, 0]}}],
            "scan": {"duration_s": 0.1}, "backend": "numpy", "noise": []}
    data.update(changes)
    return scenario_from_dict(data)


def test_plugin_guide_has_an_example_for_every_component_kind():
    assert set(_plugin_examples()) == {"scan_pattern", "noise_model", "exporter", "target_model",
                                       "trajectory"}


def test_plugin_guide_scan_pattern_example_works():
    from helpers import datasheet

    from lidarsim_core.patterns.geometry import off_axis_angle
    from lidarsim_core.pipeline import Simulation

    registry, _ = _registry_with(_plugin_examples()["scan_pattern"], "pattern")
    sheet = datasheet(scan_pattern={"name": "doc-circle", "options": {"turn_period_s": 0.02}})
    sim = Simulation(_scenario(sensor={"datasheet": sheet}), registry=registry)
    rays = sim.pattern.rays(0.0, 0.02)
    np.testing.assert_allclose(np.degrees(off_axis_angle(rays.direction)), 0.9 * 20.0)
    assert sim.pattern.inside_fov(rays.direction).all() and len(sim.run_frame(0)) > 0


def test_plugin_guide_noise_model_example_works():
    from lidarsim_core.pipeline import Simulation

    registry, _ = _registry_with(_plugin_examples()["noise_model"], "noise")
    scen = _scenario(noise=[{"name": "doc-growing-range",
                             "options": {"sigma_m": 0.01, "sigma_per_m": 0.001}}])
    cloud = Simulation(scen, registry=registry).run_frame(0)
    err = cloud["range"] - cloud["range_true"]
    expected = np.sqrt(np.mean((0.01 + 0.001 * cloud["range_true"]) ** 2))
    assert err.std() == pytest.approx(expected, rel=5 / np.sqrt(2 * len(err)))


def test_plugin_guide_exporter_example_works(tmp_path):
    from lidarsim_core.pipeline import Simulation

    registry, module = _registry_with(_plugin_examples()["exporter"], "exporter")
    cloud = Simulation(_scenario(), registry=registry).run_frame(0)
    exporter = module.XyzExporter()
    with open(tmp_path / "c.xyz", "wb") as stream:
        exporter.write(cloud, stream)
    np.testing.assert_array_equal(np.loadtxt(tmp_path / "c.xyz"), cloud.xyz)
    assert registry.entries["exporter"]["doc-xyz"].obj.suffixes == (".xyz",)


def test_plugin_guide_target_model_example_works():
    from lidarsim_core.pipeline import Simulation

    registry, _ = _registry_with(_plugin_examples()["target_model"], "target")
    scen = _scenario(targets=[{"name": "p", "mesh": {"model": "doc-two-panels",
                                                     "options": {"width_m": 2.0}},
                               "pose": {"position_m": [8, 0, -1]}}])
    cloud = Simulation(scen, registry=registry).run_frame(0)
    labels = set(cloud.part_labels())
    assert labels == {"p/left", "p/right"}
    np.testing.assert_allclose(cloud["x_true"], 8.0, atol=1e-9)  # both panels lie at x = 8 m


def test_plugin_guide_trajectory_example_works():
    registry, _ = _registry_with(_plugin_examples()["trajectory"], "trajectory")
    cls = registry.get("trajectory", "doc-zspin")
    traj = cls.from_config({"position_m": [1, 2, 3], "rate_deg_s": 90.0})
    poses = traj.poses_at(np.array([0.0, 1.0]))
    np.testing.assert_allclose(poses.position, [[1, 2, 3], [1, 2, 3]])
    np.testing.assert_allclose(poses.rotation[1].apply([1.0, 0.0, 0.0]), [0.0, 1.0, 0.0],
                               atol=1e-12)


def test_vendor_guide_datasheet_and_scenario_work(tmp_path):
    from lidarsim_core.pipeline import Simulation
    from lidarsim_core.scenario.datasheet import load_datasheet
    from lidarsim_core.scenario import load_scenario

    blocks = _blocks(DOCS / "vendor_guide.md", "yaml")
    (tmp_path / "my-lidar.yaml").write_text(blocks[0])
    sheet = load_datasheet(tmp_path / "my-lidar.yaml")
    assert sheet.name == "acme-ml30" and sheet.estimated_fields == ["angular_precision_deg"]
    (tmp_path / "run").mkdir()
    (tmp_path / "run" / "scenario.yaml").write_text(blocks[1])
    scen = load_scenario(tmp_path / "run" / "scenario.yaml").with_updates(
        scan={"duration_s": 0.05}, backend={"name": "numpy"})
    cloud = Simulation(scen).run_frame(0)
    assert cloud.frame.sensor == "acme-ml30" and len(cloud) > 20


# ---- the site builds ----------------------------------------------------------------------
def _docs_tools_installed() -> bool:
    return all(importlib.util.find_spec(m) is not None
               for m in ("mkdocs", "material", "mkdocstrings_handlers"))


@pytest.mark.skipif(not _docs_tools_installed(), reason="the docs extra is not installed")
def test_site_builds_with_warnings_as_errors(tmp_path):
    env = {**os.environ, "NO_MKDOCS_2_WARNING": "1", "DISABLE_MKDOCS_2_WARNING": "true"}
    res = subprocess.run([sys.executable, "-m", "mkdocs", "build", "--strict", "--site-dir",
                          str(tmp_path / "site")], cwd=ROOT, env=env, capture_output=True,
                         text=True, timeout=600)
    assert res.returncode == 0, res.stdout[-3000:] + res.stderr[-3000:]
    site = tmp_path / "site"
    assert (site / "reference" / "sensors" / "index.html").is_file()
    api = (site / "api" / "index.html").read_text()
    assert "lidarsim_core.pipeline.Simulation" in api and "run_frame" in api


# ---- the docs read as Markdown in the repository -------------------------------------------
def _markdown_pages() -> list[Path]:
    return [ROOT / "README.md", *sorted(DOCS.rglob("*.md"))]


def _links(text: str) -> list[str]:
    """Targets of inline Markdown links and images, outside fenced code blocks."""
    text = re.sub(r"^```.*?^```", "", text, flags=re.S | re.M)
    text = re.sub(r"`[^`\n]*`", "", text)
    return re.findall(r"\]\(([^)\s]+)(?:\s+\"[^\"]*\")?\)", text)


def test_no_page_has_include_markers_or_broken_relative_links():
    problems = []
    for page in _markdown_pages():
        text = page.read_text(encoding="utf-8")
        if "--8<--" in text or re.search(r"\{%\s*include", text):
            problems.append(f"{page.relative_to(ROOT)}: snippet-include marker")
        for target in _links(text):
            if re.match(r"^[a-z][a-z0-9+.-]*:", target) or target.startswith("#"):
                continue  # external link or anchor on the same page
            path = target.split("#", 1)[0]
            if not (page.parent / path).exists():
                problems.append(f"{page.relative_to(ROOT)}: broken link {target}")
    assert problems == []


def test_the_link_check_catches_a_broken_link():
    assert _links("see [x](reference/none.md#a) and `[y](z.md)`\n```\n[q](w.md)\n```\n") == \
        ["reference/none.md#a"]


def test_generated_pages_and_example_code_are_current(gen):
    stale = [p.relative_to(ROOT).as_posix() for p in gen["stale_files"]()]
    assert stale == [], f"out of date (run: python docs/gen_reference.py): {stale}"


def test_the_tutorial_shows_every_section_of_its_script(gen):
    text = (DOCS / "tutorial_paper.md").read_text(encoding="utf-8")
    script = (ROOT / "examples" / "paper_experiment.py").read_text(encoding="utf-8")
    sections = re.findall(r"^# \[start:([\w-]+)\]$", script, re.M)
    assert len(sections) >= 6
    for section in sections:
        body = gen["example_section"]("examples/paper_experiment.py", section)
        assert f"<!-- code from examples/paper_experiment.py:{section} -->\n```python\n{body}```" \
            in text, section
    # the renderer replaces a stale copy
    stale = text.replace(gen["example_section"]("examples/paper_experiment.py", "sensor"),
                         "print('old')\n")
    assert gen["render_includes"](stale) == text


def test_shell_commands_call_lidarsim_one_way():
    """The README uses .venv/bin/ (nothing is activated yet); the quickstart activates the venv
    and every page after it calls bare commands."""
    quick = (DOCS / "quickstart.md").read_text(encoding="utf-8")
    assert "source .venv/bin/activate" in quick
    for page in sorted(DOCS.glob("*.md")):
        for block in re.findall(r"```bash\n(.*?)```", page.read_text(encoding="utf-8"), re.S):
            for line in block.splitlines():
                if page.name == "quickstart.md" and line.startswith(
                        ("python3 -m venv", ".venv/bin/pip install", "source .venv")):
                    continue
                assert ".venv/bin/" not in line, f"{page.name}: {line}"


def _blocks(page: Path, lang: str) -> list[str]:
    return re.findall(rf"```{lang}[^\n]*\n(.*?)```", page.read_text(encoding="utf-8"), re.S)


def test_quickstart_code_runs_as_written(tmp_path):
    """The quickstart's scenario, its shell commands (with the venv's ``lidarsim`` on PATH) and
    its Python block, run in a fresh directory beside a copy of ``examples/``."""
    import shutil

    page = DOCS / "quickstart.md"
    shutil.copytree(ROOT / "examples", tmp_path / "examples")
    scenario = next(b for b in _blocks(page, "yaml") if b.startswith("seed:"))
    (tmp_path / "my_scenario.yaml").write_text(scenario.replace("duration_s: 1.0",
                                                                "duration_s: 0.1"))
    bash = [b for b in _blocks(page, "bash") if "lidarsim simulate" in b]
    assert len(bash) == 2
    env = {**os.environ, "PATH": f"{Path(sys.executable).parent}{os.pathsep}"
                                 f"{os.environ.get('PATH', '')}", "COLUMNS": "80"}
    for block in bash:
        block = block.replace("lidarsim report run --out run/report",
                              "lidarsim report run --out run/report --no-3d")
        res = subprocess.run(["bash", "-euo", "pipefail", "-c", block], cwd=tmp_path, env=env,
                             capture_output=True, text=True, timeout=300)
        assert res.returncode == 0, block + res.stdout + res.stderr
    assert (tmp_path / "cloud.npz").is_file() and (tmp_path / "run" / "cloud.npz").is_file()
    assert (tmp_path / "run" / "report" / "report.html").is_file() or \
        "viz" in res.stdout + res.stderr
    python = _blocks(page, "python")
    assert len(python) == 1 and "ls.simulate(scenario)" in python[0]
    code = python[0].replace('ls.load_scenario("examples/envisat_mid70.yaml")',
                             'ls.load_scenario("examples/envisat_mid70.yaml").with_updates('
                             'scan={"duration_s": 0.1})')
    res = subprocess.run([sys.executable, "-c", code], cwd=tmp_path, env=env,
                         capture_output=True, text=True, timeout=300)
    assert res.returncode == 0, res.stderr
    assert (tmp_path / "cloud.ply").stat().st_size > 1000
