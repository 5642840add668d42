"""Reading configuration files (YAML, TOML, JSON) safely, with errors that name the file.

YAML is read with a ``yaml.SafeLoader`` only (plain data: no tags that build Python objects),
and a key repeated within one mapping is an error in every format: configuration never executes
code and never silently drops a value.
"""

from __future__ import annotations

import json
import tomllib
from pathlib import Path
from typing import Any

from pydantic import BaseModel, ValidationError

from .components import first_validation_error
from .errors import ConfigError

CONFIG_SUFFIXES = (".yaml", ".yml", ".toml", ".json")


def read_text_file(path: Path, what: str = "file") -> str:
    """The UTF-8 text of ``path``; a :class:`ConfigError` naming the file and saying ``what``
    it is when it is missing or unreadable."""
    try:
        return path.read_text(encoding="utf-8")
    except FileNotFoundError:
        raise ConfigError(f"{what} not found", source=path) from None
    except (OSError, UnicodeDecodeError) as exc:
        raise ConfigError(f"cannot read {what}: {exc}", source=path) from None


def read_json_file(path: Path, what: str) -> Any:
    """The JSON value in ``path``, with the errors of :func:`read_text_file`, and one for
    malformed JSON."""
    text = read_text_file(path, what)
    try:
        return json.loads(text)
    except json.JSONDecodeError as exc:
        raise ConfigError(f"cannot read {what}: {exc}", source=path) from None


def read_config_file(path: str | Path) -> dict[str, Any]:
    """Parse a YAML/TOML/JSON file into a mapping.

    Raises
    ------
    ConfigError
        If the file is missing, unreadable, malformed, not a mapping, or of an unknown suffix.
    """
    path = Path(path)
    suffix = path.suffix.lower()
    if suffix not in CONFIG_SUFFIXES:
        raise ConfigError(f"unsupported configuration format '{suffix or '(none)'}'; use one of "
                          f"{', '.join(CONFIG_SUFFIXES)}", source=path)
    data = parse_config_text(read_text_file(path), suffix, source=path)
    return data


def parse_config_text(text: str, suffix: str, *, source: str | Path = "<string>") -> dict[str, Any]:
    """Parse configuration ``text`` in the format given by ``suffix`` (``.yaml``, ``.toml``, ``.json``)."""
    try:
        if suffix in (".yaml", ".yml"):
            import yaml

            try:
                data = yaml.load(text, Loader=_safe_loader())  # a SafeLoader: plain data only
            except yaml.YAMLError as exc:
                mark = getattr(exc, "problem_mark", None)
                where = f" at line {mark.line + 1}, column {mark.column + 1}" if mark else ""
                problem = getattr(exc, "problem", None) or str(exc).splitlines()[0]
                if problem.startswith("could not determine a constructor for the tag"):
                    tag = problem.rsplit(" ", 1)[-1]
                    raise ConfigError(f"YAML tag {tag}{where} is not allowed: configuration "
                                      "files hold plain data only", source=source) from None
                raise ConfigError(f"malformed YAML{where}: {problem}", source=source) from None
        elif suffix == ".toml":
            data = tomllib.loads(text)
        else:
            data = json.loads(text, object_pairs_hook=_unique_json_keys(source),
                              parse_constant=_no_json_constant(source))
    except tomllib.TOMLDecodeError as exc:
        raise ConfigError(f"malformed TOML: {exc}", source=source) from None
    except json.JSONDecodeError as exc:
        raise ConfigError(f"malformed JSON: {exc}", source=source) from None
    except RecursionError:
        raise ConfigError("values are nested too deeply", source=source) from None
    if data is None:
        raise ConfigError("file is empty", source=source)
    if not isinstance(data, dict):
        raise ConfigError(f"top level must be a mapping, not {type(data).__name__}", source=source)
    _check_expanded_size(data, source)
    return data


#: Most values (scalars, lists and mappings, counted as often as YAML aliases repeat them) a
#: configuration file may hold: a few lines of aliases could otherwise stand for billions.
MAX_CONFIG_VALUES = 1_000_000


def _check_expanded_size(data: Any, source: str | Path) -> None:
    sizes: dict[int, int] = {}
    open_: set[int] = set()

    def count(node: Any) -> int:
        if not isinstance(node, (dict, list)):
            return 1
        key = id(node)
        if key in sizes:  # shared through an alias: counted again, computed once
            return sizes[key]
        if key in open_:
            raise ConfigError("a YAML alias contains itself (the value would be infinite)",
                              source=source)
        open_.add(key)
        total = 1 + sum(count(item) for item in (node.values() if isinstance(node, dict)
                                                 else node))
        open_.discard(key)
        if total > MAX_CONFIG_VALUES:
            raise ConfigError(f"the file expands to more than {MAX_CONFIG_VALUES:,} values "
                              "(YAML aliases repeating large collections)", source=source)
        sizes[key] = total
        return total

    try:
        count(data)
    except RecursionError:
        raise ConfigError("values are nested too deeply", source=source) from None


_LOADER: Any = None


def _safe_loader() -> Any:
    """``yaml.SafeLoader`` that also rejects a key repeated in one mapping (PyYAML would keep
    the last value silently)."""
    global _LOADER
    if _LOADER is not None:
        return _LOADER
    import yaml
    from yaml.constructor import ConstructorError, SafeConstructor

    class UniqueKeySafeLoader(yaml.SafeLoader):
        pass

    def construct_mapping(loader: Any, node: Any, deep: bool = False) -> Any:
        seen: set[Any] = set()
        for key_node, _ in node.value:
            if key_node.tag == "tag:yaml.org,2002:merge":
                continue  # '<<' merges may be overridden by explicit keys
            key = loader.construct_object(key_node, deep=True)
            try:
                duplicate = key in seen
            except TypeError:
                continue  # unhashable: PyYAML reports it below
            if duplicate:
                raise ConstructorError(None, None, f"duplicate key '{key}'",
                                       key_node.start_mark)
            seen.add(key)
        return SafeConstructor.construct_mapping(loader, node, deep=deep)

    UniqueKeySafeLoader.add_constructor(yaml.resolver.BaseResolver.DEFAULT_MAPPING_TAG,
                                        construct_mapping)
    _LOADER = UniqueKeySafeLoader
    return _LOADER


def _unique_json_keys(source: str | Path) -> Any:
    def pairs(items: list[tuple[str, Any]]) -> dict[str, Any]:
        out: dict[str, Any] = {}
        for key, value in items:
            if key in out:
                raise ConfigError(f"malformed JSON: duplicate key '{key}'", source=source)
            out[key] = value
        return out

    return pairs


def _no_json_constant(source: str | Path) -> Any:
    def reject(name: str) -> Any:
        raise ConfigError(f"malformed JSON: '{name}' is not a JSON number", source=source)

    return reject


def validate_model(model: type[BaseModel], data: Any, *, source: str | Path | None,
                   prefix: str = "", context: dict[str, Any] | None = None) -> Any:
    """Validate ``data`` against a pydantic ``model``, turning the first error into a one-line
    :class:`ConfigError` that names ``source`` and the dotted field."""
    try:
        return model.model_validate(data, context=context)
    except ValidationError as exc:
        field, msg = first_validation_error(exc, prefix, model)
        # a check across fields ('<root>') names its fields in the message itself
        raise ConfigError(msg, source=source, field=None if field == "<root>" else field) \
            from None
