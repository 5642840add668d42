"""The ``lidarsim`` console script: every command module added to the app, then run as one
error boundary (``python -m lidarsim_core`` runs it too)."""

from __future__ import annotations

import sys
from typing import Any

import typer
from .output import markup_safe as escape

# isort: off
# every command module adds its commands to the app when imported (one module per command),
# in the order `lidarsim --help` lists them
from . import demo, simulate, listings  # noqa: F401
from . import patterns, poses, bench, report, dataset, mesh, view, evaluate  # noqa: F401
# isort: on
from .app import STATE, app, plain_help_when_piped
from .errors import fail_code, one_line
from .output import console


def _show_warning(message: Any, category: type[Warning], filename: str, lineno: int,
                  file: Any = None, line: str | None = None) -> None:
    """Warnings are one line on stderr, ``warning: ...``, like errors (no source location)."""
    console(stderr=True).print(f"[yellow]warning:[/] {escape(str(message))}")


def main(argv: list[str] | None = None) -> None:
    """Console-script entry point; exits the process with the command's status."""
    import warnings

    warnings.showwarning = _show_warning
    # the console script and ``python -m lidarsim_core`` give no arguments: the process is
    # the command's own (a caller passing its arguments keeps its process as it is)
    STATE["own_process"] = argv is None
    sys.exit(_run_app(argv))


def _run_app(argv: list[str] | None) -> int:
    from ..base.signals import sigterm_as_interrupt

    try:  # Typer >= 0.26 carries its own copy of Click
        from typer._click.exceptions import NoArgsIsHelpError, UsageError
    except ImportError:  # pragma: no cover - older Typer on Click
        from click.exceptions import NoArgsIsHelpError, UsageError  # type: ignore[no-redef]

    plain_help_when_piped()
    with sigterm_as_interrupt():
        try:
            # not standalone: a usage error (bad option value, unknown option) comes back here
            # and is printed as one line, like every other mistake
            code = app(args=argv, prog_name="lidarsim", standalone_mode=False)
        except NoArgsIsHelpError as exc:
            exc.show()
            return exc.exit_code
        except UsageError as exc:
            command = exc.ctx.command_path if exc.ctx is not None else "lidarsim"
            return fail_code(f"{command}: {one_line(exc.format_message())}", 2)
        except typer.Abort:
            return fail_code("interrupted; no partial output was kept", 130)
    return code if isinstance(code, int) else 0


