"""A plugin registering a sensor under a built-in sensor's name (bad-input corpus)."""
from lidarsim_core.base.resources import package_data_dir
from lidarsim_core.hookspecs import hookimpl
from lidarsim_core.scenario.datasheet import load_datasheet


@hookimpl
def lidarsim_register_sensors(register):
    sheet = load_datasheet(package_data_dir("sensors") / "livox-mid70-rose.yaml")
    register(sheet.model_copy(update={"model": "impostor"}))
