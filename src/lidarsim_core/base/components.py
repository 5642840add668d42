"""Base class shared by every plugin component (pattern, noise model, backend, exporter, ...).

A component is a class with a ``name``, a pydantic ``Options`` model and a constructor that
takes validated options. :meth:`Component.from_config` turns a user's ``{name, options}`` into
an instance and reports bad options with the field that is wrong.
"""

from __future__ import annotations

import inspect
from typing import Any, ClassVar, Mapping

from pydantic import BaseModel, ConfigDict, ValidationError

from .errors import ConfigError
from .validation import first_validation_error


class ComponentOptions(BaseModel):
    """Base of every component's options: unknown keys are rejected, models are immutable,
    and infinities and NaN are refused (no option is meaningful at infinity)."""

    model_config = ConfigDict(extra="forbid", frozen=True, allow_inf_nan=False)


class Component:
    """Base of all plugin components.

    Subclasses set :attr:`name` and :attr:`Options` and accept an ``Options`` instance in
    ``__init__``.
    """

    name: ClassVar[str] = ""
    Options: ClassVar[type[ComponentOptions]] = ComponentOptions

    def __init__(self, options: ComponentOptions | None = None) -> None:
        self.options = options if options is not None else self.Options()

    @classmethod
    def summary(cls) -> str:
        """First paragraph of the class docstring on one line, for listings (whole: a
        sentence that runs on to a second line is not cut)."""
        doc = inspect.getdoc(cls) or ""
        return " ".join(doc.split("\n\n")[0].split())

    @classmethod
    def from_config(cls, options: Mapping[str, Any] | None, *, source: str | None = None,
                    field: str = "options") -> "Component":
        """Validate ``options`` against :attr:`Options` and build an instance.

        Raises
        ------
        ConfigError
            Naming ``source`` and the dotted field when an option is unknown or invalid.
        """
        try:
            opts = cls.Options.model_validate(dict(options or {}))
        except ValidationError as exc:
            where, msg = first_validation_error(exc, field, cls.Options)
            raise ConfigError(f"{cls.name}: {msg}", source=source, field=where) from None
        return cls(opts)

    def __repr__(self) -> str:
        return f"{type(self).__name__}({self.options!r})"
