"""Generate the documentation's derived text from the code itself, into files committed in the repo.

The pages read the same in the repository and on the site; ``tests/test_docs.py`` fails when
any of them is out of date. After changing a model, a plugin, a datasheet or an example, run::

    python docs/gen_reference.py            # rewrite what is stale
    python docs/gen_reference.py --check    # only say what is stale (exit 1)

It writes the reference pages

* ``reference/scenario.md`` — every scenario field, from :class:`lidarsim_core.scenario.Scenario`,
  and the options of every built-in trajectory, noise model, ray backend, target model and
  exporter, from their ``Options`` models;
* ``reference/datasheet.md`` — every datasheet field, from
  :class:`lidarsim_core.scenario.datasheet.SensorDatasheet`, and the options of every scan pattern;
* ``reference/sensors.md`` — the built-in sensor catalogue, one row per file in ``sensors/``;

puts before each ``::: module`` directive of ``api.md`` the module's summary and its public
names with their first docstring paragraph (read from the source), so the API page reads in
the repository too; and renders code from the examples into the guides: a fenced block
right after a line ``<!-- code from examples/paper_experiment.py:sensor -->`` is replaced by
the lines between ``# [start:sensor]`` and ``# [end:sensor]`` of that file (the example runs
in the tests, so the code the tutorial shows runs too).

Only built-in plugins are documented: third-party entry points are switched off here.
"""

from __future__ import annotations

import os
import re
import types
import typing
from pathlib import Path
from typing import Any, Iterator

os.environ["LIDARSIM_DISABLE_PLUGIN_AUTOLOAD"] = "1"

from pydantic import BaseModel  # noqa: E402
from pydantic_core import PydanticUndefined  # noqa: E402

ROOT = Path(__file__).resolve().parents[1]

#: Component kinds documented with the scenario, with their section titles and where they go.
SCENARIO_KINDS = (
    ("trajectory", "Trajectories", "`sensor.trajectory` / `targets[].trajectory`: "
                                   "`{kind: NAME, ...options}`"),
    ("noise_model", "Noise models", "`noise: [{name: NAME, options: {...}}]`"),
    ("ray_backend", "Ray backends", "`backend: {name: NAME, options: {...}}`"),
    ("target_model", "Target models", "`targets[].mesh: {model: NAME, options: {...}}`"),
    ("exporter", "Exporters (output formats)", "chosen by the output file's suffix or "
                                               "`--format NAME`"),
)


# ---- type and value formatting ------------------------------------------------------------
def type_name(annotation: Any) -> str:
    """A short, readable name of a field's type (``or`` instead of ``|`` for tables)."""
    origin = typing.get_origin(annotation)
    args = typing.get_args(annotation)
    if origin in (typing.Union, types.UnionType):
        names = list(dict.fromkeys(type_name(a) for a in args if a is not type(None)))
        return " or ".join(names) + (" or null" if type(None) in args else "")
    if origin is typing.Literal:
        return " / ".join(f"`{a}`" for a in args)
    if origin in (list, tuple, dict):
        inner = ", ".join("…" if a is Ellipsis else type_name(a) for a in args)
        return f"{origin.__name__}[{inner}]" if inner else origin.__name__
    if origin is typing.Annotated:
        return type_name(args[0])
    if isinstance(annotation, type):
        if issubclass(annotation, BaseModel):
            return "mapping"
        return {"str": "string", "int": "integer", "float": "number", "bool": "boolean",
                "PosixPath": "path", "Path": "path", "WindowsPath": "path"}.get(
                    annotation.__name__, annotation.__name__)
    return str(annotation).replace("typing.", "")


def default_text(field: Any) -> str:
    """The default of a pydantic field as shown in the tables ("required" when none)."""
    if field.is_required():
        return "required"
    value = field.default_factory() if field.default_factory is not None else field.default
    if value is PydanticUndefined:
        return "required"
    if isinstance(value, BaseModel):
        value = value.model_dump(exclude_defaults=True) or value.model_dump()
    if value is None:
        return "—"
    if isinstance(value, str):
        return f"`{value}`" if value else '`""`'
    return f"`{value!r}`" if not isinstance(value, (list, tuple, dict)) or value else f"`{value}`"


def _cell(text: str) -> str:
    return " ".join(text.split()).replace("|", "\\|")


def _nested_models(annotation: Any) -> Iterator[tuple[str, type[BaseModel]]]:
    """``(suffix, model)`` for pydantic models inside a type: ``""`` direct, ``"[]"`` in a list."""
    origin = typing.get_origin(annotation)
    args = typing.get_args(annotation)
    if isinstance(annotation, type) and issubclass(annotation, BaseModel):
        yield "", annotation
    elif origin in (typing.Union, types.UnionType, typing.Annotated):
        for a in args:
            yield from _nested_models(a)
    elif origin in (list, tuple):
        for a in args:
            if a is not Ellipsis:
                for suffix, model in _nested_models(a):
                    yield "[]" + suffix, model


def field_rows(model: type[BaseModel], prefix: str = "", *,
               stop: tuple[type[BaseModel], ...] = ()) -> list[tuple[str, str, str, str]]:
    """``(dotted name, type, default, description)`` of every field of ``model``, recursively.

    Models in ``stop`` are listed as one field (they have their own table). The alternatives
    of a tagged union (models told apart by a literal field such as ``type`` or ``mode``) are
    listed one after the other: the tag with every value it takes, then each alternative's
    fields, their meaning starting with the tag value they belong to.
    """
    rows: dict[tuple[str, str], tuple[str, str, str, str]] = {}
    for name, field in model.model_fields.items():
        path = f"{prefix}{name}"
        nested = [(suffix, m) for suffix, m in _nested_models(field.annotation)]
        meaning = field.description or (_summary(nested[0][1]) if nested else "")
        rows.setdefault((path, ""), (path, type_name(field.annotation), default_text(field),
                                     meaning))
        tag = _union_tag([m for _, m in nested]) if len(nested) > 1 else None
        for suffix, sub in nested:
            if sub in stop:
                continue
            if tag is None:
                # models that share field names (alternatives of an untagged union) share rows
                for row in field_rows(sub, f"{path}{suffix}.", stop=stop):
                    rows.setdefault((row[0], ""), row)
                continue
            values = [v for _, m in nested for v in _literal_values(m, tag)]
            tag_path = f"{path}{suffix}.{tag}"
            chosen = _default_tag(typing.Annotated[(field.annotation, *field.metadata)]
                                  if field.metadata else field.annotation)
            rows.setdefault((tag_path, ""), (
                tag_path, " / ".join(f"`{v}`" for v in dict.fromkeys(values)),
                f"`{chosen}`" if chosen is not None else "required",
                f"Which kind of {name.rstrip('s')}: one of the alternatives below."))
            value = "/".join(str(v) for v in _literal_values(sub, tag))
            for row in field_rows(sub, f"{path}{suffix}.", stop=stop):
                if row[0] == tag_path:
                    continue
                where = f"With `{tag}: {value}`" + (f": {row[3]}" if row[3] else ".")
                rows.setdefault((row[0], value), (row[0], row[1], row[2], where))
    return list(rows.values())


def _literal_values(model: type[BaseModel], name: str) -> list[Any]:
    field = model.model_fields.get(name)
    if field is None or typing.get_origin(field.annotation) is not typing.Literal:
        return []
    return list(typing.get_args(field.annotation))


def _default_tag(annotation: Any) -> str | None:
    """The alternative a union's callable discriminator picks when the tag is left out (None
    when the tag is required)."""
    from pydantic import Discriminator

    for arg in typing.get_args(annotation):
        if isinstance(arg, Discriminator) and callable(arg.discriminator):
            return arg.discriminator({})
        found = _default_tag(arg) if typing.get_args(arg) else None
        if found is not None:
            return found
    return None


def _union_tag(models: list[type[BaseModel]]) -> str | None:
    """The field that tells the alternatives ``models`` apart: a literal in every one of
    them, with different values (None for an untagged union)."""
    if len(set(models)) < 2:
        return None
    for name in models[0].model_fields:
        values = [tuple(_literal_values(m, name)) for m in models]
        if all(values) and len(set(values)) == len(values):
            return name
    return None


def table(rows: list[tuple[str, str, str, str]]) -> str:
    """A Markdown table of field rows."""
    lines = ["| field | type | default | meaning |", "|---|---|---|---|"]
    lines += [f"| `{p}` | {_cell(t)} | {_cell(d)} | {_cell(m)} |" for p, t, d, m in rows]
    return "\n".join(lines)


def _summary(obj: Any) -> str:
    doc = (obj.__doc__ or "").strip()
    return " ".join(doc.split("\n\n")[0].split()) if doc else ""


def component_sections(kind: str, level: str = "###") -> str:
    """One section per registered built-in component of ``kind``: summary and options table."""
    from lidarsim_core.plugins import get_registry

    out = []
    for entry in get_registry().iter(kind):
        cls = entry.obj
        rows = field_rows(cls.Options)
        body = table(rows) if rows else "No options."
        extra = ""
        if kind == "exporter":
            extra = f" Suffixes: {', '.join(f'`{s}`' for s in cls.suffixes)}."
        out.append(f"{level} `{entry.name}`\n\n{_summary(cls)}{extra}\n\n{body}\n")
    return "\n".join(out)


# ---- pages ------------------------------------------------------------------------------------
def scenario_reference() -> str:
    """The scenario reference page."""
    from lidarsim_core.scenario import PoseConfig
    from lidarsim_core.scenario import Scenario

    parts = [
        "# Scenario reference\n",
        "Generated from `lidarsim_core.scenario.Scenario` and the built-in plugins' `Options` "
        "models (`python docs/gen_reference.py`). Unknown keys are errors; a wrong value is "
        "reported as one line naming the file and the dotted field (e.g. "
        "`targets.0.pose.position_m`). The JSON schema: `lidarsim schema scenario`. "
        "For a guided tour see [Scenario files](../scenario.md).\n",
        "## Fields\n",
        table(field_rows(Scenario, stop=(PoseConfig,))),
        "\n`pose` fields are in [Poses](#poses); a `trajectory` is `{kind: NAME, ...options}` "
        "with the options of [that trajectory](#trajectories).\n",
        "## Poses\n",
        "A pose maps body → scene: `x_scene = R · x_body + position_m`.\n",
        table(field_rows(PoseConfig)),
    ]
    for kind, title, where in SCENARIO_KINDS:
        parts.append(f"\n## {title}\n\nUsed as {where}.\n")
        parts.append(component_sections(kind))
    return "\n".join(parts) + "\n"


def datasheet_reference() -> str:
    """The datasheet reference page."""
    from lidarsim_core.scenario.datasheet import SensorDatasheet

    return "\n".join([
        "# Datasheet reference\n",
        "Generated from `lidarsim_core.scenario.datasheet.SensorDatasheet` and the built-in scan "
        "patterns' `Options` models (`python docs/gen_reference.py`). JSON schema: "
        "`lidarsim schema sensor`. Every value carries its unit in its name; every datasheet "
        "names its `sources`, and values that are estimates are listed in "
        "`estimated_fields`. See the [vendor guide](../vendor_guide.md) to write one.\n",
        "## Fields\n",
        table(field_rows(SensorDatasheet)),
        "\n## Scan patterns\n\nA datasheet's `scan_pattern: {name: NAME, options: {...}}`; a "
        "scenario can override options with `sensor.pattern_options`.\n",
        component_sections("scan_pattern"),
    ]) + "\n"


def _fov(sheet: Any) -> str:
    if sheet.fov_type == "circular":
        return f"{sheet.fov_h_deg:g}° circular"
    centre = f", centre {sheet.fov_v_center_deg:+g}°" if sheet.fov_v_center_deg else ""
    return f"{sheet.fov_h_deg:g}° × {sheet.fov_v_deg:g}° {sheet.fov_type}{centre}"


def catalogue_sheets() -> list[Any]:
    """Every datasheet in the repository's ``sensors/`` directory, by name."""
    from lidarsim_core.scenario.datasheet import load_datasheet

    return sorted((load_datasheet(p) for p in (ROOT / "sensors").glob("*.yaml")),
                  key=lambda s: s.name)


def sensor_catalogue() -> str:
    """The built-in sensor catalogue page."""
    sheets = catalogue_sheets()
    lines = [
        "# Built-in sensor catalogue\n",
        f"Generated from the {len(sheets)} datasheets in `sensors/` by "
        "`python docs/gen_reference.py` (`lidarsim sensors` prints the same list, with "
        "plugins' sensors). σ are 1σ precisions. Each sensor's section below gives its sources and the values that are "
        "estimates rather than datasheet figures.\n",
        "| name | sensor | FOV | range (m) | points/s | σ range | σ angle | pattern |",
        "|---|---|---|---|---|---|---|---|",
    ]
    for s in sheets:
        lines.append(
            f"| [`{s.name}`](#{s.name.replace('.', '')}) | {_cell(f'{s.manufacturer} {s.model}')} "
            f"| {_fov(s)} | {s.range_min_m:g}–{s.range_max_m:g} | {s.point_rate_hz:,.0f} | "
            f"{1000 * s.range_precision_m:g} mm | {s.angular_precision_deg:g}° | "
            f"`{s.scan_pattern.name}` |")
    lines.append("")
    for s in sheets:
        lines.append(f"## {s.name}\n")
        if s.description:
            lines.append(_cell(s.description) + "\n")
        facts = [f"{s.manufacturer} {s.model}", _fov(s), f"{s.point_rate_hz:,.0f} points/s"]
        if s.wavelength_nm:
            facts.append(f"{s.wavelength_nm:g} nm")
        if s.beam_divergence_deg:
            facts.append(f"divergence {s.beam_divergence_deg[0]:g}° × "
                         f"{s.beam_divergence_deg[1]:g}°")
        lines.append("; ".join(facts) + ".\n")
        if s.estimated_fields:
            lines.append("Estimated, not datasheet figures: "
                         + ", ".join(f"`{f}`" for f in s.estimated_fields) + ".\n")
        lines.append("Sources:\n")
        for src in s.sources:
            title = f"<{src.url}> — {src.title}" if src.url else src.title
            note = f": {src.note}" if src.note else ""
            lines.append(f"* {_cell(title + note)}")
        lines.append("")
    return "\n".join(lines) + "\n"


# ---- the Python API page: what each module holds, readable in the repository -----------------
#: A generated summary, placed before each ``::: module`` directive of ``docs/api.md``.
_API_BLOCK = re.compile(r"<!-- api: [\w.]+ \(generated\) -->\n.*?<!-- /api -->\n\n", re.S)
_API_DIRECTIVE = re.compile(r"^::: (?P<module>[\w.]+)$", re.M)


def _module_file(module: str) -> Path:
    base = ROOT / "src" / Path(*module.split("."))
    return base / "__init__.py" if base.is_dir() else base.with_suffix(".py")


def _first_paragraph(doc: str | None) -> str:
    text = " ".join((doc or "").strip().split("\n\n")[0].split())
    return re.sub(r":(?:class|func|mod|meth|attr|data|exc):`~?([^`]+)`", r"`\1`", text)


def _public_definitions(module: str, depth: int = 0) -> tuple[str, list[tuple[str, str, str]]]:
    """The module docstring's first paragraph and ``(name, kind, summary)`` of its public
    names (``__all__`` when it has one, else its public classes and functions), read from
    the source (nothing is imported)."""
    import ast

    tree = ast.parse(_module_file(module).read_text(encoding="utf-8"))
    defined = {n.name: n for n in tree.body
               if isinstance(n, (ast.ClassDef, ast.FunctionDef, ast.AsyncFunctionDef))}
    exported = next((ast.literal_eval(n.value) for n in tree.body if isinstance(n, ast.Assign)
                     and any(getattr(t, "id", None) == "__all__" for t in n.targets)), None)
    names = list(exported) if exported is not None else [n for n in defined
                                                         if not n.startswith("_")]
    imported = {}
    package = module if _module_file(module).name == "__init__.py" else module.rpartition(".")[0]
    for node in tree.body:
        if isinstance(node, ast.ImportFrom) and node.level:
            base = package.rsplit(".", node.level - 1)[0] if node.level > 1 else package
            source = f"{base}.{node.module}" if node.module else base
            for alias in node.names:
                imported[alias.asname or alias.name] = (source, alias.name)
    items = []
    for name in names:
        node = defined.get(name)
        if node is not None:
            kind = "class" if isinstance(node, ast.ClassDef) else "function"
            items.append((name, kind, _first_paragraph(ast.get_docstring(node))))
        elif name in imported and depth < 3:
            source, original = imported[name]
            found = {n: (k, d) for n, k, d in _definitions_of(source, depth + 1)}
            kind, summary = found.get(original, ("", ""))
            items.append((name, kind, summary))
        else:
            items.append((name, "", ""))
    return _first_paragraph(ast.get_docstring(tree)), items


def _definitions_of(module: str, depth: int) -> list[tuple[str, str, str]]:
    try:
        return _public_definitions(module, depth)[1]
    except (OSError, SyntaxError):
        return []


def api_summary(module: str) -> str:
    """The Markdown summary of ``module`` put before its ``::: module`` directive."""
    doc, items = _public_definitions(module)
    lines = [f"<!-- api: {module} (generated) -->", f"**`{module}`**: {doc}" if doc else
             f"**`{module}`**", ""]
    for name, kind, summary in items:
        label = f"class `{name}`" if kind == "class" else (
            f"`{name}()`" if kind == "function" else f"`{name}`")
        lines.append(f"* {label}" + (f": {summary}" if summary else ""))
    return "\n".join(lines + ["<!-- /api -->", "", ""])


def render_api(markdown: str) -> str:
    """``markdown`` (``docs/api.md``) with a summary of every ``::: module`` before it: the
    page reads as a list of the public names in the repository, and mkdocstrings renders the
    full reference on the site."""
    markdown = _API_BLOCK.sub("", markdown)
    return _API_DIRECTIVE.sub(lambda m: api_summary(m["module"]) + m[0], markdown)


PAGES = {
    "reference/scenario.md": scenario_reference,
    "reference/datasheet.md": datasheet_reference,
    "reference/sensors.md": sensor_catalogue,
}


#: ``<!-- code from FILE:SECTION -->`` followed by a fenced code block.
_INCLUDE = re.compile(r"(<!-- code from (?P<file>[^:\s]+):(?P<section>[\w-]+) -->\n"
                      r"```(?P<lang>\w*)\n)(?P<body>.*?)(^```$)", re.S | re.M)


def example_section(file: str, section: str) -> str:
    """The lines of ``file`` (relative to the repository) between ``# [start:SECTION]`` and
    ``# [end:SECTION]``."""
    text = (ROOT / file).read_text(encoding="utf-8")
    match = re.search(rf"^# \[start:{re.escape(section)}\]\n(.*?)^# \[end:{re.escape(section)}\]$",
                      text, re.S | re.M)
    if match is None:
        raise KeyError(f"{file}: no section {section!r} (# [start:{section}] ... "
                       f"# [end:{section}])")
    return match.group(1)


def render_includes(markdown: str) -> str:
    """``markdown`` with every ``<!-- code from FILE:SECTION -->`` block filled from FILE."""
    return _INCLUDE.sub(lambda m: m.group(1) + example_section(m["file"], m["section"])
                        + m.group(6), markdown)


def expected_files() -> dict[Path, str]:
    """Every generated file (absolute path) with the text it must hold."""
    out = {ROOT / "docs" / path: build() for path, build in PAGES.items()}
    for page in sorted((ROOT / "docs").glob("*.md")):
        text = page.read_text(encoding="utf-8")
        if _INCLUDE.search(text):
            out[page] = render_includes(text)
    api = ROOT / "docs" / "api.md"
    out[api] = render_api(api.read_text(encoding="utf-8"))
    return out


def stale_files() -> list[Path]:
    """The generated files whose committed text differs from what the code gives."""
    return [path for path, text in expected_files().items()
            if not path.is_file() or path.read_text(encoding="utf-8") != text]


def main(argv: list[str] | None = None) -> int:
    import sys

    args = sys.argv[1:] if argv is None else argv
    stale = stale_files()
    if "--check" in args:
        for path in stale:
            print(f"out of date: {path.relative_to(ROOT)} (run: python docs/gen_reference.py)")
        return 1 if stale else 0
    expected = expected_files()
    for path in stale:
        path.parent.mkdir(parents=True, exist_ok=True)
        path.write_text(expected[path], encoding="utf-8")
        print(f"wrote {path.relative_to(ROOT)}")
    return 0


if __name__ == "__main__":
    raise SystemExit(main())
