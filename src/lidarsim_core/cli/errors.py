"""The command line's one error boundary: every failure becomes one line and an exit code, and
the options every command shares are checked at the edge."""

from __future__ import annotations

from typing import Any, Callable

import typer

from ..base.errors import LidarsimError, UserInputError
from .app import STATE
from .output import console


def fail(message: str, code: int) -> None:
    from rich.text import Text

    from ..base.terminal import terminal_safe

    # a Text is never parsed for markup: file names, keys and values are printed verbatim,
    # with control characters shown as escapes (a name holding ESC [2J clears no screen)
    console(stderr=True).print(Text.assemble(("error:", "bold red"), " ",
                                             terminal_safe(message)), soft_wrap=True)
    raise typer.Exit(code)


def one_line(exc: BaseException) -> str:
    return " ".join(str(exc).split())


def check_seed_option(seed: int | None, flag: str = "--seed") -> None:
    """Refuse a seed option outside 0 to 2^64 - 1 (a larger one would alias a smaller)."""
    from ..base.errors import ConfigError
    from ..base.limits import MAX_SEED

    if seed is not None and not 0 <= seed <= MAX_SEED:
        raise ConfigError(f"{flag} {seed} is outside 0..{MAX_SEED} (2^64 - 1)", field=flag)


def check_number_option(value: float | None, flag: str, *, minimum: float | None = None,
                        maximum: float | None = None, positive: bool = False) -> None:
    """Refuse a number option that is NaN or infinite, not > 0 (``positive``), below
    ``minimum`` or above ``maximum``: options are checked at the edge like configuration
    fields."""
    import math

    from ..base.errors import ConfigError

    if value is None:
        return
    if not math.isfinite(value):
        raise ConfigError(f"{flag} must be a finite number, got {value}", field=flag)
    if positive and not value > 0:
        raise ConfigError(f"{flag} must be > 0, got {value:g}", field=flag)
    if minimum is not None and value < minimum:
        raise ConfigError(f"{flag} must be >= {minimum:g}, got {value:g}", field=flag)
    if maximum is not None and value > maximum:
        raise ConfigError(f"{flag} must be <= {maximum:g}, got {value:g}", field=flag)


def run_guarded(func: Callable[[], Any]) -> Any:
    """Run a command body, turning lidarsim errors into one line and an exit code.

    Exit codes: 2 for a user error or a failing plugin (:class:`UserInputError`,
    :class:`~lidarsim_core.base.errors.PluginError`: fix the input or the installed plugins), 1 for
    any other failure, 130 after Ctrl-C (SIGINT), 143 after SIGTERM.
    """
    from ..base.errors import PluginError
    from ..base.numerics import quiet_numerics
    from ..base.outputs import tracking_inputs
    from ..base.oserrors import os_error_line
    from ..base.signals import SIGTERM_EXIT_CODE, Terminated, interrupt_behind

    try:
        try:
            with quiet_numerics(), tracking_inputs():  # outputs never replace inputs
                return func()
        except Exception as exc:  # an interrupt surfacing through a compiled kernel
            interrupt = interrupt_behind(exc)
            if interrupt is None:
                raise
            raise interrupt from None
    except typer.Exit:
        raise
    except (UserInputError, PluginError) as exc:
        if STATE["debug"]:
            raise
        fail(one_line(exc), 2)
    except LidarsimError as exc:
        if STATE["debug"]:
            raise
        fail(one_line(exc), 1)
    except OSError as exc:  # a path the user gave cannot be read or written (ENOSPC, EROFS...)
        if STATE["debug"]:
            raise
        fail(one_line(os_error_line(exc)), 2)
    except Terminated as exc:  # a command that keeps finished work says so in the message
        fail(f"terminated (SIGTERM); {str(exc) or 'no partial output was kept'}",
              SIGTERM_EXIT_CODE)
    except KeyboardInterrupt as exc:
        fail(f"interrupted; {str(exc) or 'no partial output was kept'}", 130)
    except Exception as exc:  # an unexpected bug: short line unless --debug
        if STATE["debug"]:
            raise
        fail(f"internal error: {type(exc).__name__}: {one_line(exc)} (rerun with --debug "
              "for the traceback)", 1)


def fail_code(message: str, code: int) -> int:
    try:
        fail(message, code)
    except typer.Exit as stop:
        return stop.exit_code
    return code
