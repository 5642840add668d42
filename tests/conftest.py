"""Shared fixtures. Entry-point plugins installed on the machine are switched off for the whole
test session so that they cannot change results (tests that exercise plugin loading turn them
on explicitly)."""

from __future__ import annotations

import os

os.environ.setdefault("LIDARSIM_DISABLE_PLUGIN_AUTOLOAD", "1")

import pytest  # noqa: E402


@pytest.fixture
def fresh_registry():
    """Forget the cached registry before and after a test that changes plugin settings."""
    from lidarsim_core.plugins import reset_registry

    reset_registry()
    yield
    reset_registry()
