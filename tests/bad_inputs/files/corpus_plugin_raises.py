"""A plugin whose registration hook raises (bad-input corpus)."""
from lidarsim_core.hookspecs import hookimpl


@hookimpl
def lidarsim_register_scan_patterns(register):
    raise ValueError("corpus plugin cannot register")
