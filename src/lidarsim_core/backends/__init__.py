"""Ray-casting backends (built-in plugins): ``numpy`` (reference) and ``embree`` (embreex)."""

#: Modules registered as built-in plugins (see ``lidarsim_core.plugins.manager``).
BUILTIN_MODULES: tuple[str, ...] = ("numpy_backend", "embree_backend")
