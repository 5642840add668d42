"""Reading configuration files (YAML, TOML, JSON) safely, with errors that name the file.

YAML is read with a ``yaml.SafeLoader`` only (plain data: no tags that build Python objects),
and a key repeated within one mapping is an error in every format: configuration never executes
code and never silently drops a value.
"""

from __future__ import annotations

import errno
import json
import os
import stat
import tomllib
from pathlib import Path
from typing import Any

from .errors import ConfigError, UserInputError
from .oserrors import describe_os_error

CONFIG_SUFFIXES = (".yaml", ".yml", ".toml", ".json")

#: Largest number of bytes one read may ask for, whatever a limit is raised to (a limit of
#: ``1e300`` must not become a request Python cannot even express).
MAX_READ_BYTES = 2 ** 62


def check_input_file(path: str | Path, what: str = "file", *, limit_name: str = "config_bytes",
                     error: type[UserInputError] = ConfigError,
                     source: str | Path | None = None, field: str | None = None) -> int:
    """Check that ``path`` is a regular file lidarsim may read, and return its size.

    Refused with one line naming the file (or ``source`` and ``field``) and saying what it is
    instead: missing, a dangling or looping symbolic link, a directory, a named pipe (FIFO),
    a device (``/dev/zero``), a socket, unreadable, or larger than the ``limit_name`` limit of
    :mod:`lidarsim_core.base.limits`. Nothing is opened, so a FIFO or device never blocks.
    """
    from .limits import LIMITS, limit

    path = Path(path)
    where = {"source": source, "field": field} if source is not None else {"source": path}
    prefix = f"{path}: " if field is not None else ""
    if "\0" in str(path):  # no file system allows it; os.stat would raise a bare ValueError
        raise error(f"{prefix}the path contains a NUL character", **where)
    try:
        info = os.stat(path)
    except OSError as exc:
        if exc.errno == errno.ENOENT and os.path.islink(path):
            reason = "is a dangling symbolic link (its target does not exist)"
        elif exc.errno == errno.ENOENT:
            reason = f"{what} not found"
        else:
            reason = f"cannot read {what}: {describe_os_error(exc)}"
        raise error(prefix + reason, **where) from None
    mode = info.st_mode
    kind = None
    if stat.S_ISDIR(mode):
        kind = "a directory"
    elif stat.S_ISFIFO(mode):
        kind = "a named pipe (FIFO)"
    elif stat.S_ISCHR(mode) or stat.S_ISBLK(mode):
        kind = "a device"
    elif stat.S_ISSOCK(mode):
        kind = "a socket"
    elif not stat.S_ISREG(mode):
        kind = "not a regular file"
    if kind is not None:
        raise error(f"{prefix}is {kind}, not a {what}" if kind[0] == "a" else
                    f"{prefix}{kind}", **where)
    from .outputs import note_input

    note_input(path, info)  # an output may never replace it (lidarsim_core.base.outputs)
    bound = limit(limit_name)
    if info.st_size > bound:
        raise error(f"{prefix}{what} is {info.st_size:,} bytes, over the limit of "
                    f"{bound:,.0f} (set {LIMITS[limit_name].env} to raise it)", **where)
    return info.st_size


def read_bytes_file(path: str | Path, what: str = "file", *, limit_name: str = "config_bytes",
                    error: type[UserInputError] = ConfigError,
                    source: str | Path | None = None, field: str | None = None) -> bytes:
    """The bytes of ``path``, read through :func:`check_input_file` and never more than the
    limit (a file that grows while it is read is refused too)."""
    from .limits import limit

    size = check_input_file(path, what, limit_name=limit_name, error=error, source=source,
                            field=field)
    # never ask for the bound itself (a 4 GiB buffer for a 1 KB manifest): the file's own size
    # plus one byte, which tells a file that grew while it was read
    bound = int(min(limit(limit_name), MAX_READ_BYTES))
    where = {"source": source, "field": field} if source is not None else {"source": path}
    prefix = f"{path}: " if field is not None else ""
    try:
        with open(path, "rb") as stream:
            data = stream.read(min(size, bound) + 1)
    except OSError as exc:
        raise error(f"{prefix}cannot read {what}: {describe_os_error(exc)}", **where) from None
    if len(data) > size:
        raise error(f"{prefix}{what} grew beyond its {size:,} bytes while it was read",
                    **where)
    return data


def read_text_file(path: Path, what: str = "file", *, encoding: str = "utf-8",
                   error: type[UserInputError] = ConfigError) -> str:
    """The text of ``path`` through the bounded reader (:func:`check_input_file`); a
    :class:`ConfigError` naming the file and saying ``what`` it is when it is missing,
    unreadable, not a regular file, too large or not UTF-8."""
    data = read_bytes_file(path, what, error=error)
    try:
        return data.decode(encoding)
    except UnicodeDecodeError as exc:
        raise error(f"cannot read {what}: not UTF-8 text (byte {exc.start:,} is "
                    f"0x{data[exc.start]:02x})", source=path) from None


def read_json_file(path: Path, what: str) -> Any:
    """The JSON value in ``path``, with the errors of :func:`read_text_file`, and one for
    malformed JSON."""
    text = read_text_file(path, what)
    try:
        return json.loads(text)
    except json.JSONDecodeError as exc:
        raise ConfigError(f"cannot read {what}: {exc}", source=path) from None
    except RecursionError:
        raise ConfigError(f"cannot read {what}: values are nested too deeply",
                          source=path) from None


def read_config_file(path: str | Path, what: str = "file") -> dict[str, Any]:
    """Parse a YAML/TOML/JSON file into a mapping.

    Raises
    ------
    ConfigError
        If the file is missing, unreadable, malformed, not a mapping, or of an unknown suffix.
    """
    path = Path(path)
    suffix = path.suffix.lower()
    check_input_file(path, what)  # a device, FIFO or directory is named as such first
    if suffix not in CONFIG_SUFFIXES:
        raise ConfigError(f"unsupported configuration format '{suffix or '(none)'}'; use one of "
                          f"{', '.join(CONFIG_SUFFIXES)}", source=path)
    data = parse_config_text(read_text_file(path, what), suffix, source=path)
    return data


def parse_config_text(text: str, suffix: str, *, source: str | Path = "<string>") -> dict[str, Any]:
    """Parse configuration ``text`` in the format given by ``suffix`` (``.yaml``, ``.toml``, ``.json``)."""
    try:
        if suffix in (".yaml", ".yml"):
            import yaml

            try:
                data = _load_yaml(text)  # a SafeLoader: plain data only
            except yaml.YAMLError as exc:
                raise _yaml_error(exc, source=source) from None
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


def _yaml_error(exc: Exception, *, source: str | Path | None, field: str | None = None
                ) -> ConfigError:
    mark = getattr(exc, "problem_mark", None)
    where = f" at line {mark.line + 1}, column {mark.column + 1}" if mark else ""
    problem = getattr(exc, "problem", None) or str(exc).splitlines()[0]
    if problem.startswith("could not determine a constructor for the tag"):
        tag = problem.rsplit(" ", 1)[-1]
        return ConfigError(f"YAML tag {tag}{where} is not allowed: configuration files hold "
                           "plain data only", source=source, field=field)
    return ConfigError(f"malformed YAML{where}: {problem}", source=source, field=field)


def parse_option_value(text: str, *, field: str) -> Any:
    """A ``KEY=VALUE`` command-line value read as YAML with the same safe loader as files
    (plain data only; malformed values and tags are one line naming ``field``)."""
    import yaml

    try:
        value = _load_yaml(text)
    except yaml.YAMLError as exc:
        raise _yaml_error(exc, source=None, field=field) from None
    except RecursionError:
        raise ConfigError("value is nested too deeply", field=field) from None
    _check_expanded_size({"value": value}, field)
    return value


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


_LOADERS: tuple[Any, Any] | None = None


def _load_yaml(text: str) -> Any:
    """``text`` through the safe loader (:func:`_safe_loaders`): libyaml's parser where PyYAML
    was built with it (the sensor catalogue's twelve datasheets, which every new process
    reads before its first frame: 11.5 ms against 105 ms with PyYAML's parser on the 2-core
    VM); a document it refuses is parsed again by PyYAML's own parser, whose error names the
    place and the character more precisely (libyaml's marks may point past the problem), so
    the messages stay PyYAML's."""
    import yaml

    if _safe_loaders()[0] is not _safe_loaders()[1]:
        try:
            return yaml.load(text, Loader=_safe_loaders()[0])
        except yaml.YAMLError:
            pass  # raised again below, in PyYAML's words
    return yaml.load(text, Loader=_safe_loaders()[1])


def _safe_loaders() -> tuple[Any, Any]:
    """``yaml.SafeLoader`` that also rejects a key repeated in one mapping (PyYAML would keep
    the last value silently), on libyaml's parser (``CSafeLoader``; the same loader when
    PyYAML has no libyaml) and on PyYAML's own."""
    global _LOADERS
    if _LOADERS is not None:
        return _LOADERS
    import yaml
    from yaml.constructor import ConstructorError, SafeConstructor

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

    def unique_keys(base: Any) -> Any:
        loader = type("UniqueKeySafeLoader", (base,), {})
        loader.add_constructor(yaml.resolver.BaseResolver.DEFAULT_MAPPING_TAG,
                               construct_mapping)
        return loader

    plain = unique_keys(yaml.SafeLoader)
    fast = getattr(yaml, "CSafeLoader", None)
    _LOADERS = (plain if fast is None else unique_keys(fast), plain)
    return _LOADERS


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
