"""A plugin exporter that fails halfway through a file (bad-input corpus)."""
from lidarsim_core.hookspecs import hookimpl
from lidarsim_core.io.base import Exporter


class BrokenExporter(Exporter):
    """Writes a header, then fails."""

    name = "corpus-broken"
    suffixes = (".brk",)

    def write_points(self, points, stream):
        stream.write(b"corpus header\n" * 100)
        raise OSError("corpus exporter ran out of ideas")


@hookimpl
def lidarsim_register_exporters(register):
    register(BrokenExporter)
