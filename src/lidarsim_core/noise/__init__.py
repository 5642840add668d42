"""Measurement-noise models (built-in plugins), applied as a chain named in the scenario."""
