"""Example third-party lidarsim plugin: a vendor's datasheet and its spiral scan pattern."""

__version__ = "0.1.0"
