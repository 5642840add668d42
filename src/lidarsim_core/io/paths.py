"""Output file names with a ``{frame}`` field, checked so they stay where the user pointed.

``cloud_{frame:04d}.ply`` names one file per frame. Only the field ``frame`` is allowed, with
an optional integer format made of a zero flag, a width and ``d`` (``{frame}``, ``{frame:04d}``,
``{frame:6}``): no other field, attribute or index access, conversion, or fill character, so a
template can neither read anything but the frame number nor put a path separator, ``..`` or an
absolute path into the name it produces.
"""

from __future__ import annotations

import re
import string
from pathlib import Path
from typing import Iterable

from ..base.errors import OutputError

_SPEC = re.compile(r"^0?[0-9]{0,3}d?$")


def has_frame_field(path: str | Path) -> bool:
    """Whether ``path`` contains a ``{...}`` replacement field (after ``{{`` escapes)."""
    try:
        return any(name is not None for _, name, _, _ in string.Formatter().parse(str(path)))
    except ValueError:
        return True  # malformed braces: let :func:`frame_paths` explain


def frame_paths(template: str | Path, frames: Iterable[int]) -> list[Path]:
    """The output path of every frame in ``frames`` from a ``{frame}`` template.

    Raises
    ------
    OutputError
        If the template has another field, a format other than ``[0][width][d]``, unbalanced
        braces, or a field in a directory part of the path.
    """
    text = str(template)
    try:
        fields = [(name, spec, conv) for _, name, spec, conv in string.Formatter().parse(text)
                  if name is not None]
    except ValueError as exc:
        raise OutputError(f"malformed '{{frame}}' template: {exc}", source=text) from None
    for name, spec, conv in fields:
        if name != "frame":
            raise OutputError(f"only '{{frame}}' may appear in an output name, not "
                              f"'{{{name}}}'", source=text)
        if conv or not _SPEC.match(spec or ""):
            raise OutputError(f"'{{frame}}' takes only a zero-padded width such as "
                              f"{{frame:04d}}, not '{{{name}{'!' + conv if conv else ''}"
                              f"{':' + spec if spec else ''}}}'", source=text)
    if has_frame_field(Path(text).parent):
        raise OutputError("'{frame}' may appear in the file name only, not in a directory",
                          source=text)
    return [Path(text.format(frame=int(f))) for f in frames]
