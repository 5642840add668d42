"""How the command line prints: for people at a terminal, and for pipes and scripts.

One convention for every command (the one of git, pip and PDAL):

* a table is a rich table at a terminal, and plain text aligned with spaces when stdout is not
  a terminal (a pipe, a file), with no box characters and no colour; the columns that hold
  names a user types (sensor names, plugin names, part labels) are never cut or wrapped at
  any width; other cells may wrap at a terminal;
* every command that prints a table has ``--json`` for scripts;
* prose lines are never broken by the program: at a terminal the terminal wraps them;
* progress bars go to stderr, only when stderr is a terminal, and vanish when done.
"""

from __future__ import annotations

import sys
from dataclasses import dataclass
from typing import Any, Iterable, Sequence

from ..base.terminal import terminal_safe


def console(stderr: bool = False):
    """A rich console that never inserts line breaks into printed text (``soft_wrap``)."""
    from rich.console import Console

    return Console(stderr=stderr, highlight=False, soft_wrap=True)


def markup_safe(text: object) -> str:
    """``text`` ready for a rich f-string: control characters shown as escapes
    (:func:`~lidarsim_core.base.terminal.terminal_safe`) and square brackets escaped, so a
    name from a file is printed as it is and never drives the terminal or rich's markup."""
    from rich.markup import escape

    return escape(terminal_safe(text))


def stdout_is_terminal() -> bool:
    """Whether stdout is an interactive terminal (not a pipe or a file)."""
    try:
        return sys.stdout.isatty()
    except (AttributeError, ValueError):
        return False


@dataclass(frozen=True)
class Column:
    """A table column: its header, alignment, whether its cells must stay whole, and whether
    a terminal too narrow for the whole table may leave it out (``--json`` and pipes always
    have every column)."""

    header: str
    right: bool = False
    whole: bool = False
    optional: bool = False


#: Exit code after the reader of a pipe went away (``lidarsim plugins | head``): 128 + SIGPIPE,
#: what a shell reports for ``ls | head``.
BROKEN_PIPE_EXIT = 141


def write_stdout(text: str) -> None:
    """Print ``text`` and a newline on stdout; a closed pipe ends the command quietly."""
    try:
        sys.stdout.write(text + "\n")
        sys.stdout.flush()
    except BrokenPipeError:
        import os

        import typer

        # the rest of the output has nowhere to go: silence the final flush and stop
        os.dup2(os.open(os.devnull, os.O_WRONLY), sys.stdout.fileno())
        raise typer.Exit(BROKEN_PIPE_EXIT) from None


def plain_table(columns: Sequence[Column], rows: Iterable[Sequence[Any]]) -> str:
    """Rows aligned in columns with two spaces between them, headers first (for pipes)."""
    cells = [[c.header for c in columns]] + [[terminal_safe(v) for v in row] for row in rows]
    widths = [max(len(row[i]) for row in cells) for i in range(len(columns))]
    lines = []
    for row in cells:
        padded = [value.rjust(w) if col.right else value.ljust(w)
                  for value, w, col in zip(row, widths, columns)]
        lines.append("  ".join(padded).rstrip())
    return "\n".join(lines)


def print_table(columns: Sequence[Column], rows: Iterable[Sequence[Any]], *,
                title: str | None = None) -> None:
    """Print a table: rich at a terminal, :func:`plain_table` otherwise (every cell through
    :func:`~lidarsim_core.base.terminal.terminal_safe`)."""
    rows = [[terminal_safe(v) for v in row] for row in rows]
    if not stdout_is_terminal():
        write_stdout((title + "\n" if title else "") + plain_table(columns, rows))
        return
    from rich.table import Table
    from rich.text import Text

    out = console()
    shown = _fitting_columns(columns, rows, out.width)
    table = Table(show_edge=False, title=title)
    for i in shown:
        col = columns[i]
        if col.whole:
            width = max([len(col.header)] + [len(str(r[i])) for r in rows])
            table.add_column(col.header, justify="right" if col.right else "left",
                             no_wrap=True, min_width=width)
        else:
            table.add_column(col.header, justify="right" if col.right else "left")
    for row in rows:
        table.add_row(*(Text(str(row[i])) for i in shown))  # cells verbatim: never markup
    out.print(table, soft_wrap=False)
    hidden = [c.header for i, c in enumerate(columns) if i not in shown]
    if hidden:
        out.print(Text(f"({len(hidden)} columns left out at this width: {', '.join(hidden)}; "
                       "--json or a wider terminal shows them)", style="dim"))


def _fitting_columns(columns: Sequence[Column], rows: list[list[Any]], width: int
                     ) -> list[int]:
    """Indices of the columns to show at a terminal ``width`` wide: optional ones are left
    out, last first, while the table's natural width exceeds it."""
    natural = [max([len(c.header)] + [len(str(r[i])) for r in rows]) + 3
               for i, c in enumerate(columns)]
    shown = list(range(len(columns)))
    for i in reversed(range(len(columns))):
        if sum(natural[j] for j in shown) <= width:
            break
        if columns[i].optional:
            shown.remove(i)
    return shown


def print_json(data: Any) -> None:
    """Print ``data`` as indented JSON on stdout."""
    import json

    write_stdout(json.dumps(data, indent=2, allow_nan=False))


class RayProgress:
    """A transient progress bar of rays cast, on stderr when it is a terminal.

    Parameters
    ----------
    total
        Rays the step will cast.
    label
        What is being done (e.g. ``frame 3``).
    """

    def __init__(self, total: int, label: str) -> None:
        self.total = total
        self.label = label
        self._progress: Any = None
        self._task: Any = None

    def __enter__(self) -> "RayProgress":
        out = console(stderr=True)
        if out.is_terminal:
            from rich.markup import escape
            from rich.progress import (
                BarColumn,
                MofNCompleteColumn,
                Progress,
                TextColumn,
                TimeElapsedColumn,
                TimeRemainingColumn,
            )

            self._progress = Progress(
                TextColumn(f"[bold]{escape(terminal_safe(self.label))}[/] rays"), BarColumn(), MofNCompleteColumn(),
                TimeElapsedColumn(), TextColumn("ETA"), TimeRemainingColumn(),
                console=out, transient=True)
            self._progress.start()
            self._task = self._progress.add_task(self.label, total=self.total)
        return self

    def advance(self, rays: int) -> None:
        """``rays`` more rays were cast."""
        if self._progress is not None:
            self._progress.update(self._task, advance=rays)

    def __exit__(self, *exc: object) -> None:
        if self._progress is not None:
            self._progress.stop()


def hide_flag_metavars() -> None:
    """Typer's help shows ``<bool>`` after on/off flags (``--debug <bool>``), as if they took a
    value; flags take none, so their type is left out of the help."""
    from typer.core import TyperOption

    if getattr(TyperOption.display_type_rich, "_lidarsim_flags", False):
        return
    original = TyperOption.display_type_rich

    def display_type_rich(self: Any, ctx: Any) -> str | None:
        return None if self.is_flag else original(self, ctx)

    display_type_rich._lidarsim_flags = True  # type: ignore[attr-defined]
    TyperOption.display_type_rich = display_type_rich  # type: ignore[method-assign]
