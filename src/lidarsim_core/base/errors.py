"""The exception hierarchy of lidarsim.

Every error that lidarsim raises on purpose derives from :class:`LidarsimError`, so callers
can catch one type. Errors caused by the user's input (files, fields, names) derive from
:class:`UserInputError`; the CLI prints them as one line and exits with code 2.
"""

from __future__ import annotations

from os import PathLike


class LidarsimError(Exception):
    """Root of every exception raised deliberately by lidarsim."""


class UserInputError(LidarsimError):
    """Something the user gave (a file, a field, a name) is wrong.

    Parameters
    ----------
    message
        What is wrong, in one sentence.
    source
        The file (or other origin, e.g. ``"<scenario>"``) the bad value came from.
    field
        Dotted path of the offending field inside ``source`` (e.g. ``"sensor.pose.position_m"``).
    """

    def __init__(self, message: str, *, source: str | PathLike[str] | None = None,
                 field: str | None = None) -> None:
        self.message = message
        self.source = None if source is None else str(source)
        self.field = field
        super().__init__(self._one_line())

    def _one_line(self) -> str:
        where = ""
        if self.source and self.field:
            where = f"{self.source}: field '{self.field}': "
        elif self.source:
            where = f"{self.source}: "
        elif self.field:
            where = f"field '{self.field}': "
        return where + " ".join(self.message.split())


class ConfigError(UserInputError):
    """A scenario, datasheet or option set is malformed or out of range."""


class MeshError(UserInputError):
    """A target mesh cannot be read or is unusable (missing, empty, non-finite)."""


class PatternFileError(UserInputError):
    """A scan-pattern table file is malformed."""


class UnknownNameError(UserInputError):
    """A plugin-provided name (backend, pattern, noise model, exporter, sensor...) is not installed."""


class OutputError(UserInputError):
    """An output path cannot be written (unknown format, existing file, unwritable place)."""


class PluginError(LidarsimError):
    """A plugin misbehaved: duplicate names, a failing registration or a failure at run time."""


class BackendError(LidarsimError):
    """A ray backend failed or is not usable in this environment."""


class MissingExtraError(UserInputError):
    """An optional package of an extra is not installed (or does not import)."""
