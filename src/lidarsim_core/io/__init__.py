"""Point-cloud exporters (built-in plugins) and atomic file writing."""
