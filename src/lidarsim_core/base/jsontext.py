"""``json.dumps(obj, indent=1, sort_keys=True)``, the same text in a fraction of the time.

With an indent, Python's :mod:`json` encodes through its pure-Python generators (its C encoder
takes no indent before Python 3.13): ~95 µs for a frame's sidecar record, more than the
frame's checksum. :func:`indented_json` builds the same text by direct recursion, with the C
string escaper and the same number formatting, and falls back to :func:`json.dumps` for
anything but plain ``dict``/``list``/``tuple``/``str``/``int``/``float``/``bool``/``None``
(subclasses, non-string keys...), so the text is always what :func:`json.dumps` gives.
Tuples of strings (and of tuples of strings), which cannot change, are encoded once per value:
a caller that passes the parts that repeat from call to call so pays for them once.
"""

from __future__ import annotations

import json
from json.encoder import encode_basestring_ascii
from typing import Any, Callable

_INFINITY = float("inf")
#: Encoded tuples by ``(indent level, value)`` (a sidecar's column list is the same in every
#: frame of a sequence), at most :data:`_TUPLES_KEPT` of them.
_TUPLES: dict[tuple[int, tuple], str] = {}
_TUPLES_KEPT = 64


class _Unusual(Exception):
    """A value :func:`indented_json` leaves to :func:`json.dumps`."""


def _float(value: float) -> str:
    # json.encoder's floatstr with allow_nan=True
    if value != value:
        return "NaN"
    if value == _INFINITY:
        return "Infinity"
    if value == -_INFINITY:
        return "-Infinity"
    return float.__repr__(value)


def _none(value: None) -> str:
    return "null"


def _bool(value: bool) -> str:
    return "true" if value else "false"


_SCALARS: dict[type, Callable[[Any], str]] = {
    str: encode_basestring_ascii, float: _float, int: int.__repr__, bool: _bool,
    type(None): _none}


def _text_only(value: tuple) -> bool:
    """Whether ``value`` holds only strings and tuples of strings: the values a memo may key
    on (numbers may not: ``(1,)``, ``(1.0,)`` and ``(True,)`` are equal keys, their texts
    are not)."""
    for item in value:
        if type(item) is str:
            continue
        if type(item) is not tuple:
            return False
        for inner in item:
            if type(inner) is not str:
                return False
    return True


def _encode(value: Any, level: int, out: list[str]) -> None:
    kind = type(value)
    scalar = _SCALARS.get(kind)
    if scalar is not None:
        out.append(scalar(value))
        return
    if kind is dict:
        if not value:
            out.append("{}")
            return
        inner = "\n" + " " * (level + 1)
        if any(type(key) is not str for key in value):
            raise _Unusual  # json.dumps turns numbers and constants into strings first
        keys = sorted(value)
        first = True
        for key in keys:
            out.append(("{" if first else ",") + inner + encode_basestring_ascii(key) + ": ")
            first = False
            _encode(value[key], level + 1, out)
        out.append("\n" + " " * level + "}")
        return
    if kind is tuple and _text_only(value):  # immutable: encoded once per value and level
        text = _TUPLES.get((level, value))
        if text is None:
            part: list[str] = []
            _encode(list(value), level, part)
            text = "".join(part)
            if len(_TUPLES) >= _TUPLES_KEPT:
                _TUPLES.clear()
            _TUPLES[(level, value)] = text
        out.append(text)
        return
    if kind is list or kind is tuple:
        if not value:
            out.append("[]")
            return
        inner = "\n" + " " * (level + 1)
        close = "\n" + " " * level + "]"
        scalars = [_SCALARS.get(type(item)) for item in value]
        if None not in scalars:  # a list of strings or numbers: one join
            out.append("[" + inner + ("," + inner).join(
                [encode(item) for encode, item in zip(scalars, value)]) + close)
            return
        first = True
        for item in value:
            out.append("[" + inner if first else "," + inner)
            first = False
            _encode(item, level + 1, out)
        out.append(close)
        return
    raise _Unusual


def indented_json(obj: Any) -> str:
    """Exactly ``json.dumps(obj, indent=1, sort_keys=True)``.

    Raises
    ------
    TypeError, ValueError
        As :func:`json.dumps` would (it is called for anything this function does not
        encode itself).
    """
    out: list[str] = []
    try:
        _encode(obj, 0, out)
    except (_Unusual, RecursionError):
        return json.dumps(obj, indent=1, sort_keys=True)
    return "".join(out)
