"""Built-in plugin: the sensor catalogue shipped in ``sensors/``; and the sensor look-up API.
"""

from __future__ import annotations

from typing import Any

from ..base.resources import package_data_dir
from ..hookspecs import hookimpl


@hookimpl
def lidarsim_register_sensors(register: Any) -> None:
    """Register every datasheet in the built-in catalogue directory."""
    register(package_data_dir("sensors"))
