"""Optional packages of the ``eval`` extra, imported only when needed."""

from __future__ import annotations

import importlib
from typing import Any

from ..base.errors import UserInputError

EXTRA = "eval"


class MissingExtraError(UserInputError):
    """An optional package of an extra is not installed (or does not import)."""


def require(module: str, what: str = "lidarsim evaluate") -> Any:
    """Import ``module`` or raise :class:`MissingExtraError` naming the extra to install."""
    try:
        return importlib.import_module(module)
    except ImportError as exc:
        package = module.split(".")[0]
        detail = ""
        if getattr(exc, "name", None) not in (None, package, module):
            # installed but a shared library is missing (e.g. Open3D's libusb-1.0)
            detail = f" ({package} is installed but does not import: {exc})"
        raise MissingExtraError(f"{what} needs {package}, from the '{EXTRA}' extra: pip install "
                                f"'lidarsim-core[{EXTRA}]'{detail}") from None
