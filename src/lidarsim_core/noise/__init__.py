"""Measurement-noise models (built-in plugins), applied as a chain named in the scenario."""

#: Modules registered as built-in plugins (see ``lidarsim_core.plugins.manager``).
BUILTIN_MODULES: tuple[str, ...] = ("gaussian", "range_models", "signal", "pointing", "outliers")
