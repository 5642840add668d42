"""Point-cloud exporters (built-in plugins) and atomic file writing."""

#: Modules registered as built-in plugins (see ``lidarsim_core.plugins.manager``).
BUILTIN_MODULES: tuple[str, ...] = ("ply", "npz", "pcd", "las", "csv_exporter")
