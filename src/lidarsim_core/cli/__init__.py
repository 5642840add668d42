"""The ``lidarsim`` command line: the app (:mod:`.app`), one module per command, and how the
command line prints (:mod:`.output`). Only this package imports typer and rich."""

from .app import app, main

__all__ = ["app", "main"]
