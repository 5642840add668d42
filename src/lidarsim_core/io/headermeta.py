"""Frame metadata in text headers (PLY comments, PCD ``#`` lines), split over short lines.

Header-based readers have line limits: RPly (the PLY reader inside Open3D and CloudCompare)
aborts the whole process on a header line over ~1 KB, and Open3D's PCD reader reads header
lines in 1 KB pieces. So the compact JSON of the frame metadata is written as consecutive
lines ``<prefix><piece>`` of at most :data:`PIECE_CHARS` characters each; concatenating the
pieces of every ``<prefix>`` line in order gives the JSON back.

The JSON is ASCII-only (``ensure_ascii``) and its spaces, which compact JSON has only inside
strings, are written as the escape ``\\u0020``: a piece is never empty, never has leading or
trailing white space (which some readers strip from comments) and no byte needs decoding.
"""

from __future__ import annotations

import json
from pathlib import Path
from typing import Any, Iterable

from ..base.errors import ConfigError

#: Characters of JSON per header line (the whole line stays under ~200 characters).
PIECE_CHARS = 160


def metadata_lines(metadata: dict[str, Any], prefix: str) -> list[str]:
    """The header lines holding ``metadata``: ``prefix`` + a piece of its compact JSON."""
    text = json.dumps(metadata, sort_keys=True, separators=(",", ":"), ensure_ascii=True)
    text = text.replace(" ", "\\u0020")
    return [prefix + text[i:i + PIECE_CHARS] for i in range(0, len(text), PIECE_CHARS)]


def metadata_from_lines(lines: Iterable[str], prefix: str, *, source: str | Path,
                        field: str) -> dict[str, Any] | None:
    """Join the pieces of every line starting with ``prefix``; ``None`` if there is none.

    Also reads files that hold the whole JSON on one line, as earlier versions wrote.

    Raises
    ------
    ConfigError
        If the pieces are not JSON (naming ``source`` and the header ``field``).
    """
    pieces = [line[len(prefix):].strip() for line in lines if line.startswith(prefix)]
    if not pieces:
        return None
    try:
        return json.loads("".join(pieces))
    except ValueError as exc:
        raise ConfigError(f"the lidarsim-frame comments are not JSON ({exc})", source=source,
                          field=field) from None
