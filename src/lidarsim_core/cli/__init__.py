"""The ``lidarsim`` command line: the app (:mod:`.app`), one module per command, the error
boundary (:mod:`.errors`), how the command line prints (:mod:`.output`) and its progress bars
(:mod:`.progress`); :mod:`.main` assembles them. Only this package imports typer and rich."""

from .app import app
from .main import main

__all__ = ["app", "main"]
