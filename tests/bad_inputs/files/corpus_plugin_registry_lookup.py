"""A plugin that looks a sensor up in the registry while the registry is being built
(bad-input corpus: this used to wait for itself forever)."""
from lidarsim_core.hookspecs import hookimpl
from lidarsim_core.plugins.resolve import get_sensor


@hookimpl
def lidarsim_register_sensors(register):
    sheet = get_sensor("livox-mid70-rose")
    register(sheet.model_copy(update={"model": "impostor"}))
