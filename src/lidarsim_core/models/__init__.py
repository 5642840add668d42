"""Built-in parametric target models, generated in code so that demos need no mesh files."""
