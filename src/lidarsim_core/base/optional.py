"""Optional dependencies, imported only when a feature needs them, through one guard that
names the extra to install."""

from __future__ import annotations

import importlib
from types import ModuleType
from typing import Any

from .errors import MissingExtraError, UserInputError


def require(module: str, *, extra: str, what: str,
            error: type[UserInputError] = MissingExtraError, **where: Any) -> ModuleType:
    """Import ``module``, or raise ``error`` saying what needs it and which extra to install.

    Parameters
    ----------
    module
        The module to import (``"laspy"``, ``"dask.distributed"``...).
    extra
        The ``lidarsim-core`` extra that installs it.
    what
        What needs it, the start of the message (``"writing LAS/LAZ"``).
    error
        The error to raise (a :class:`~lidarsim_core.base.errors.UserInputError`).
    where
        ``source`` and ``field`` of the error.

    Examples
    --------
    >>> require("math", extra="none", what="arithmetic").sqrt(4.0)
    2.0
    """
    try:
        return importlib.import_module(module)
    except ImportError as exc:
        package = module.split(".")[0]
        detail = ""
        if getattr(exc, "name", None) not in (None, package, module):
            # installed but a shared library is missing (e.g. Open3D's libusb-1.0)
            detail = f" ({package} is installed but does not import: {exc})"
        raise error(f"{what} needs {package}, from the '{extra}' extra: pip install "
                    f"'lidarsim-core[{extra}]'{detail}", **where) from None
