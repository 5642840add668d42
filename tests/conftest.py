"""Shared fixtures. Entry-point plugins installed on the machine are switched off for the whole
test session so that they cannot change results (tests that exercise plugin loading turn them
on explicitly)."""

from __future__ import annotations

import os
import signal

os.environ.setdefault("LIDARSIM_DISABLE_PLUGIN_AUTOLOAD", "1")

# pytest-xdist's workers ignore SIGINT, and an ignored signal stays ignored in every process
# they start: the tests that interrupt a lidarsim run with Ctrl-C (SIGINT) need it delivered
if signal.getsignal(signal.SIGINT) is signal.SIG_IGN:
    signal.signal(signal.SIGINT, signal.default_int_handler)

import pytest  # noqa: E402

pytest_plugins = ["pytester"]


def pytest_report_header(config: pytest.Config) -> list[str]:
    """Say which ray backends the conformance suite runs here and which it skips, and why, and
    whether the compiled kernels are in use."""
    from lidarsim_core.plugins import get_registry

    lines = []
    for entry in get_registry().iter("ray_backend"):
        ok, why = entry.obj.is_available()
        lines.append(f"  {entry.name}: {'runs' if ok else 'SKIPPED: ' + why} ({entry.provider})")
    from lidarsim_core import kernels

    return ["ray backends (conformance suite):"] + lines + [
        f"compiled kernels: {kernels.describe()} (LIDARSIM_KERNELS={kernels.mode()})"]


@pytest.fixture
def fresh_registry():
    """Forget the cached registry before and after a test that changes plugin settings."""
    from lidarsim_core.plugins import reset_registry

    reset_registry()
    yield
    reset_registry()
