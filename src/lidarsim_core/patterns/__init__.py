"""Scan patterns: where each emitted pulse points and when it fires (built-in plugins)."""

#: Modules registered as built-in plugins (see ``lidarsim_core.plugins.manager``).
BUILTIN_MODULES: tuple[str, ...] = ("rose", "risley", "raster", "lissajous", "spinning",
                                    "flash", "table")
