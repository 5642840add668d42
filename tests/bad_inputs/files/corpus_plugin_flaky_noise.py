"""A plugin noise model that fails in the middle of a run (bad-input corpus)."""
from lidarsim_core.hookspecs import hookimpl
from lidarsim_core.noise.base import NoiseModel


class Flaky(NoiseModel):
    """Raises on the first return it sees."""

    name = "corpus-flaky"

    def perturb_returns(self, returns, ctx):
        if len(returns):
            raise RuntimeError("corpus noise model gave up")
        return returns


@hookimpl
def lidarsim_register_noise_models(register):
    register(Flaky)
