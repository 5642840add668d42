"""Built-in parametric target models, generated in code so that demos need no mesh files."""

#: Modules registered as built-in plugins (see ``lidarsim_core.plugins.manager``).
BUILTIN_MODULES: tuple[str, ...] = ("builtin",)
