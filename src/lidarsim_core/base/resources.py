"""Files shipped with the package (the sensor catalogue), in a wheel or in a source checkout.
"""

from __future__ import annotations

from pathlib import Path


def package_data_dir(name: str) -> Path:
    """Directory ``name`` shipped inside the wheel, or at the checkout's top level in development."""
    package = Path(__file__).resolve().parents[1]  # lidarsim_core/
    inside = package / name
    if inside.is_dir():
        return inside
    return package.parents[1] / name
