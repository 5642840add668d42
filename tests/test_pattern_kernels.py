"""Compiled scan patterns (lidarsim_core.kernels) agree with the NumPy reference to a few ulp."""

from __future__ import annotations

import numpy as np
import pytest

from lidarsim_core.plugins import get_registry
from lidarsim_core.plugins.resolve import get_sensor

pytest.importorskip("numba", reason="the compiled patterns need the 'fast' extra")


def _pattern(name: str):
    sheet = get_sensor(name)
    return get_registry().get("scan_pattern", sheet.scan_pattern.name).for_sensor(sheet)


@pytest.mark.parametrize("sensor", ["livox-mid70", "livox-avia", "livox-mid40"])
def test_risley_kernel_within_a_few_ulp_of_the_vector_snell_reference(sensor, monkeypatch):
    pattern = _pattern(sensor)
    # the start of a scan and rays a day into one (the rotor phases stay exact)
    index = np.concatenate([np.arange(20_000), 86_400 * 100_000 + np.arange(20_000)])
    fast = pattern.rays_for_indices(index)
    monkeypatch.setenv("LIDARSIM_KERNELS", "numpy")
    reference = pattern.rays_for_indices(index)
    np.testing.assert_array_equal(fast.t, reference.t)
    np.testing.assert_array_equal(fast.channel, reference.channel)
    assert np.abs(fast.direction - reference.direction).max() <= 8 * np.finfo(float).eps
    np.testing.assert_allclose(np.linalg.norm(fast.direction, axis=1), 1.0, atol=4e-16)


@pytest.mark.parametrize("sensor", ["velodyne-vlp16", "ouster-os1-64", "velodyne-hdl32e",
                                    "rvs-class-lissajous", "opromolla2015-space-lidar",
                                    "ball-vns-flash"])
def test_spinning_lissajous_raster_flash_kernels_match_numpy(sensor, monkeypatch):
    pattern = _pattern(sensor)
    index = np.concatenate([np.arange(30_000), 3600 * 2_000_000 + np.arange(30_000)])
    fast = pattern.rays_for_indices(index)
    monkeypatch.setenv("LIDARSIM_KERNELS", "numpy")
    reference = pattern.rays_for_indices(index)
    np.testing.assert_array_equal(fast.t, reference.t)  # the schedule: bit for bit
    np.testing.assert_array_equal(fast.channel, reference.channel)
    assert fast.channel.dtype == reference.channel.dtype
    assert np.abs(fast.direction - reference.direction).max() <= 8 * np.finfo(float).eps
