"""Optional packages of the ``eval`` extra, imported only when needed."""

from __future__ import annotations

from typing import Any

from ..base import optional
from ..base.errors import MissingExtraError

__all__ = ["EXTRA", "MissingExtraError", "require"]

EXTRA = "eval"


def require(module: str, what: str = "lidarsim evaluate") -> Any:
    """Import ``module`` of the ``eval`` extra (:func:`lidarsim_core.base.optional.require`)."""
    return optional.require(module, extra=EXTRA, what=what)
