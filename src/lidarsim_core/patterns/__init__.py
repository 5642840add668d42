"""Scan patterns: where each emitted pulse points and when it fires (built-in plugins)."""
