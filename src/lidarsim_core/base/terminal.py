"""Text from files and the environment made safe for a terminal.

A name read from a scenario, a datasheet, a mesh, a plugin option or an environment variable
may carry control characters: ``\\x1b[2J`` clears the screen, ``\\r`` overwrites the line,
``\\u202e`` reverses what follows. :func:`terminal_safe` shows every such character as a
Python escape (``\\x1b``, ``\\r``, ``\\u202e``) and leaves every other character as it is, so a
message stays one line and says exactly what the file holds. The command line passes every
error line, table cell, listing and progress description through it.
"""

from __future__ import annotations

import unicodedata

#: Unicode categories shown as escapes: controls (C0, DEL, C1), format characters (bidi
#: overrides, zero-width joiners), line/paragraph separators, surrogates and unassigned code
#: points.
_ESCAPED_CATEGORIES = frozenset({"Cc", "Cf", "Zl", "Zp", "Cs", "Co", "Cn"})


def _escape(char: str) -> str:
    code = ord(char)
    if code <= 0xFF:
        return f"\\x{code:02x}"
    if code <= 0xFFFF:
        return f"\\u{code:04x}"
    return f"\\U{code:08x}"


def terminal_safe(text: object) -> str:
    """``str(text)`` with every control, format or separator character shown as an escape.

    Examples
    --------
    >>> terminal_safe("panel\\x1b[2J")
    'panel\\\\x1b[2J'
    >>> terminal_safe("Envisat — tip")
    'Envisat — tip'
    """
    text = str(text)
    if text.isprintable():  # the common case: nothing to do
        return text
    return "".join(_escape(c) if (c != " " and unicodedata.category(c) in
                                  _ESCAPED_CATEGORIES) else c for c in text)
