"""A plugin ray backend that fails when asked to cast (bad-input corpus)."""
from lidarsim_core.backends.numpy_backend import NumpyBackend
from lidarsim_core.hookspecs import hookimpl


class FlakyBackend(NumpyBackend):
    """Builds its structure, then fails on every cast."""

    name = "corpus-flaky"

    def intersect(self, prepared, origins, directions):
        raise RuntimeError("corpus backend lost the rays")


@hookimpl
def lidarsim_register_ray_backends(register):
    register(FlakyBackend)
