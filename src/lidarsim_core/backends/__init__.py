"""Ray-casting backends (built-in plugins): ``numpy`` (reference) and ``embree`` (embreex)."""
