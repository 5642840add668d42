"""Pydantic validation errors as one line naming the file and the field, with a suggestion for
a mistyped key.
"""

from __future__ import annotations

from pathlib import Path
from typing import Any

from pydantic import BaseModel, ValidationError

from .errors import ConfigError


def _annotations_at(annotation: Any, loc: tuple[Any, ...]) -> list[Any]:
    """The type annotations found at location ``loc`` (a pydantic error location) inside
    ``annotation``: every alternative of a union is followed."""
    import types
    import typing

    origin = typing.get_origin(annotation)
    args = typing.get_args(annotation)
    if origin in (typing.Union, types.UnionType):
        return [a for arg in args if arg is not type(None) for a in _annotations_at(arg, loc)]
    if origin is typing.Annotated:
        return _annotations_at(args[0], loc)
    if not loc:
        return [annotation]
    head, rest = loc[0], loc[1:]
    if isinstance(annotation, type) and issubclass(annotation, BaseModel):
        field = annotation.model_fields.get(head) if isinstance(head, str) else None
        if field is not None:
            return _annotations_at(field.annotation, rest)
        # a union member's tag in the location (e.g. 'MeshFile'): look through it
        return _annotations_at(annotation, rest) if isinstance(head, str) else []
    if origin in (list, tuple, set, frozenset) and isinstance(head, int) and args:
        if origin is tuple and not (len(args) == 2 and args[1] is Ellipsis):
            return _annotations_at(args[head], rest) if head < len(args) else []
        return _annotations_at(args[0], rest)
    if origin is dict and len(args) == 2:
        return _annotations_at(args[1], rest)
    return []


def _keys_at(model: type[BaseModel] | None, loc: tuple[Any, ...]) -> list[str]:
    """The keys a mapping at ``loc`` of ``model`` accepts (every union alternative's)."""
    if model is None:
        return []
    keys: list[str] = []
    for ann in _annotations_at(model, loc):
        if isinstance(ann, type) and issubclass(ann, BaseModel):
            keys += [k for k in ann.model_fields if k not in keys]
    return keys


def _fixed_length(model: type[BaseModel] | None, loc: tuple[Any, ...]) -> int | None:
    """The length of a fixed-length tuple at ``loc`` of ``model`` (None if not one)."""
    import typing

    if model is None:
        return None
    for ann in _annotations_at(model, loc):
        args = typing.get_args(ann)
        if typing.get_origin(ann) is tuple and args and not (len(args) == 2 and
                                                            args[1] is Ellipsis):
            return len(args)
    return None


def _dotted(prefix: str, loc: tuple[Any, ...]) -> str:
    return ".".join(p for p in (prefix, ".".join(str(x) for x in loc)) if p)


def _suggestion(key: str, candidates: list[str]) -> str:
    import difflib

    match = difflib.get_close_matches(key, candidates, n=1, cutoff=0.6)
    if not match:  # a unit suffix off (position_mm for position_m), or a prefix
        stem = key.rsplit("_", 1)[0]
        match = [c for c in candidates if c.rsplit("_", 1)[0] == stem][:1]
    return f" (did you mean '{match[0]}'?)" if match else ""


def first_validation_error(exc: ValidationError, prefix: str = "",
                           model: type[BaseModel] | None = None) -> tuple[str, str]:
    """Return ``(dotted_field, message)`` for the most useful error of a pydantic
    ``ValidationError``, with a suggestion where one helps.

    * A misspelled key (``targts:``) is reported as the unknown key with the known one it
      resembles (``did you mean 'targets'?``), before the "Field required" it causes; so is a
      wrong unit suffix (``position_mm`` → ``position_m``). ``model`` (the model validated)
      gives the keys each mapping accepts.
    * A fixed-length list of the wrong length says so: ``needs 3 values, got 2``.
    """
    errors = exc.errors()
    for err in errors:  # an unknown key that resembles a known one explains the rest
        if err.get("type") == "extra_forbidden" and err.get("loc"):
            parent, key = tuple(err["loc"][:-1]), str(err["loc"][-1])
            missing = [str(e["loc"][-1]) for e in errors if e.get("type") == "missing"
                       and tuple(e.get("loc", ())[:-1]) == parent
                       and isinstance(e["loc"][-1], str)]
            hint = _suggestion(key, missing + _keys_at(model, parent))
            if hint:
                return _dotted(prefix, err["loc"]), f"unknown key '{key}'{hint}"
    err = errors[0]
    loc = tuple(err.get("loc", ()))
    field = _dotted(prefix, loc)
    msg = err.get("msg", str(exc))
    kind = err.get("type")
    if kind == "extra_forbidden":
        key = str(loc[-1]) if loc else ""
        known = _keys_at(model, loc[:-1])
        msg = f"unknown key '{key}'" + (f"; known keys: {', '.join(known)}" if known else "")
    elif kind == "missing" and loc and isinstance(loc[-1], int)             and isinstance(err.get("input"), (list, tuple)):
        need = _fixed_length(model, loc[:-1])
        field = _dotted(prefix, loc[:-1])
        got = len(err["input"])
        msg = f"needs {need} values, got {got}" if need else             f"needs more than {got} values, got {got}"
    elif kind in ("too_long", "too_short") and "actual_length" in (err.get("ctx") or {}):
        ctx = err["ctx"]
        need = _fixed_length(model, loc)
        bound = ctx.get("max_length" if kind == "too_long" else "min_length")
        msg = (f"needs {need} values, got {ctx['actual_length']}" if need else
               f"needs {'at most' if kind == 'too_long' else 'at least'} {bound} values, got "
               f"{ctx['actual_length']}")
    elif kind == "value_error":
        msg = msg.removeprefix("Value error, ")
    return field or prefix or "<root>", msg


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
