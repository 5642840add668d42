"""The ``lidarsim`` command line: the Typer app that every command module adds its commands to.

User errors (bad files, fields, names, paths) and failing plugins print one line and exit with
code 2; other failures print one line and exit with code 1; Ctrl-C (SIGINT) exits with 130 and
SIGTERM with 143, after removing any partly written file. ``--debug`` shows the traceback
instead of the one line (:mod:`.errors`).
"""

from __future__ import annotations

import typer

from .output import hide_flag_metavars, stdout_is_terminal

hide_flag_metavars()


app = typer.Typer(add_completion=False, no_args_is_help=True, pretty_exceptions_enable=False,
                  help="LiDAR point-cloud simulator for space in-orbit close-range operations.")


schema_app = typer.Typer(no_args_is_help=True, help="Print JSON schemas of the input files.")


app.add_typer(schema_app, name="schema")


#: ``debug``: ``--debug`` was given; ``own_process``: the app runs as the ``lidarsim``
#: process itself (the console script or ``python -m lidarsim_core``:
#: :func:`lidarsim_core.cli.main.main` without arguments), not called from Python with its
#: arguments, so that it may change what is process-wide (:func:`.progress.prepare_long_run`).
STATE = {"debug": False, "own_process": False}


def _print_version(value: bool) -> None:
    if value:
        from .._version import __version__

        typer.echo(f"lidarsim-core {__version__}")
        raise typer.Exit()


@app.callback()
def _root(debug: bool = typer.Option(False, "--debug", help="Show tracebacks on errors."),
          version: bool = typer.Option(False, "--version", callback=_print_version,
                                       is_eager=True, help="Print the version and exit.")
          ) -> None:
    STATE["debug"] = debug



def plain_help_when_piped() -> None:
    """``--help`` is rich (boxes, colour) at a terminal and Click's plain text when stdout is a
    pipe or a file: wrapped at the width, never cut with an ellipsis, no box characters."""
    mode = "rich" if stdout_is_terminal() else None
    for typer_app in (app, schema_app):
        typer_app.rich_markup_mode = mode  # read when the command tree is built, per run
        for info in typer_app.registered_commands:
            # the command list shows each command's first paragraph whole (wrapped), where
            # Click would cut it to 45 characters with "..."
            doc = info.help or (info.callback.__doc__ if info.callback else None) or ""
            if info.short_help is None and doc.strip():
                info.short_help = " ".join(doc.strip().split("\n\n")[0].split())
