"""A plugin that looks a sensor up in the registry while the registry is being built
(bad-input corpus: this used to wait for itself forever)."""
from lidarsim_core.builtin_sensors import get_sensor
from lidarsim_core.hookspecs import hookimpl


@hookimpl
def lidarsim_register_sensors(register):
    sheet = get_sensor("livox-mid70-rose")
    register(sheet.model_copy(update={"model": "impostor"}))
