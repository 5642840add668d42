"""The plugin system: built-ins, entry points with provenance, broken and duplicate plugins,
switching autoload off, explicitly named modules."""

from __future__ import annotations

import subprocess
import sys
import textwrap
from pathlib import Path

import pytest

import lidarsim_core as ls
from lidarsim_core.base.errors import PluginError, UnknownNameError
from lidarsim_core.plugins import (
    PluginLoadWarning,
    build_plugin_manager,
    build_registry,
)

GOOD_PLUGIN = '''
from lidarsim_core.hookspecs import hookimpl
from lidarsim_core.noise.base import NoiseModel


class Bias(NoiseModel):
    """Adds a constant range bias."""

    name = "test-bias"

    def perturb_returns(self, returns, ctx):
        returns.range_measured = returns.range_measured + 1.0
        return returns


@hookimpl
def lidarsim_register_noise_models(register):
    register(Bias)
'''


def make_distribution(site: Path, dist: str, module: str, source: str, version: str = "1.2.3"):
    """A real installed distribution (dist-info with an entry point) inside ``site``."""
    (site / f"{module}.py").write_text(textwrap.dedent(source))
    info = site / f"{dist.replace('-', '_')}-{version}.dist-info"
    info.mkdir()
    (info / "METADATA").write_text(f"Metadata-Version: 2.1\nName: {dist}\nVersion: {version}\n")
    (info / "entry_points.txt").write_text(f"[lidarsim]\n{module} = {module}\n")


@pytest.fixture
def site(tmp_path, monkeypatch, fresh_registry):
    monkeypatch.syspath_prepend(str(tmp_path))
    monkeypatch.setenv("LIDARSIM_DISABLE_PLUGIN_AUTOLOAD", "0")
    yield tmp_path
    for name in [m for m in sys.modules if m.startswith("lidarsim_test_")]:
        del sys.modules[name]


def test_builtins_are_registered_with_provenance():
    registry = build_registry()
    entry = registry.entry("ray_backend", "numpy")
    assert "built-in" in entry.provider and "lidarsim-core" in entry.provider
    assert set(registry.names("noise_model")) >= {"angular", "range"}


def test_entry_point_plugin_is_loaded_with_its_distribution(site):
    make_distribution(site, "lidarsim-test-bias", "lidarsim_test_bias", GOOD_PLUGIN)
    registry = build_registry()
    entry = registry.entry("noise_model", "test-bias")
    assert entry.provider == "lidarsim-test-bias 1.2.3"
    # and it is usable from a scenario by name
    from helpers import scenario

    ls.plugins._registry = registry
    cloud = ls.simulate(scenario({"model": "plate", "options": {"size_m": [20, 20]}},
                                 {"position_m": [5, 0, 0]}, noise=["test-bias"]))
    assert (cloud["range"] - cloud["range_true"] == 1.0).all()


def test_autoload_can_be_switched_off_and_plugins_blocked(site, monkeypatch):
    make_distribution(site, "lidarsim-test-bias", "lidarsim_test_bias", GOOD_PLUGIN)
    monkeypatch.setenv("LIDARSIM_DISABLE_PLUGIN_AUTOLOAD", "1")
    assert "test-bias" not in build_registry().names("noise_model")
    monkeypatch.setenv("LIDARSIM_DISABLE_PLUGIN_AUTOLOAD", "0")
    monkeypatch.setenv("LIDARSIM_BLOCK_PLUGINS", "lidarsim-test-bias")
    assert "test-bias" not in build_registry().names("noise_model")


def test_broken_plugin_becomes_a_warning_naming_its_distribution(site):
    make_distribution(site, "lidarsim-test-broken", "lidarsim_test_broken",
                      "raise RuntimeError('boom at import')\n", version="0.0.1")
    with pytest.warns(PluginLoadWarning, match=r"lidarsim-test-broken 0\.0\.1.*boom at import"):
        registry = build_registry()
    assert "numpy" in registry.names("ray_backend")  # everything else still works


def test_plugin_raising_while_registering_is_named(site):
    make_distribution(site, "lidarsim-test-raiser", "lidarsim_test_raiser", '''
        from lidarsim_core.hookspecs import hookimpl

        @hookimpl
        def lidarsim_register_scan_patterns(register):
            raise ValueError("cannot register")
    ''')
    with pytest.raises(PluginError, match=r"lidarsim_test_raiser.*lidarsim-test-raiser 1\.2\.3"
                                          r".*cannot register"):
        build_registry()


def test_duplicate_names_are_an_error_naming_both_providers(site):
    make_distribution(site, "lidarsim-test-dup", "lidarsim_test_dup", '''
        from lidarsim_core.hookspecs import hookimpl
        from lidarsim_core.backends.numpy_backend import NumpyBackend

        class Impostor(NumpyBackend):
            """Same name as the built-in."""
            name = "numpy"

        @hookimpl
        def lidarsim_register_ray_backends(register):
            register(Impostor)
    ''')
    with pytest.raises(PluginError) as info:
        build_registry()
    message = str(info.value)
    assert "ray_backend 'numpy' is registered twice" in message
    assert "built-in" in message and "lidarsim-test-dup 1.2.3" in message


def test_explicitly_named_module_is_registered(site, monkeypatch):
    (site / "lidarsim_test_named.py").write_text(GOOD_PLUGIN)
    monkeypatch.setenv("LIDARSIM_DISABLE_PLUGIN_AUTOLOAD", "1")
    monkeypatch.setenv("LIDARSIM_PLUGINS", "lidarsim_test_named")
    assert build_registry().entry("noise_model", "test-bias").provider == \
        "module lidarsim_test_named"
    monkeypatch.setenv("LIDARSIM_PLUGINS", "lidarsim_test_missing_module")
    with pytest.raises(PluginError, match="lidarsim_test_missing_module"):
        build_plugin_manager()


def test_unknown_name_lists_what_is_installed():
    with pytest.raises(UnknownNameError, match=r"unknown ray backend 'embre'.*did you mean "
                                               r"'embree'.*installed: embree, numpy"):
        build_registry().get("ray_backend", "embre")


def test_import_is_light():
    code = ("import sys, lidarsim_core; "
            "heavy = [m for m in ('pyvista', 'vtk', 'embreex', 'laspy', 'dask', 'trimesh', "
            "'matplotlib', 'numba', 'llvmlite') if m in sys.modules]; print(','.join(heavy))")
    out = subprocess.run([sys.executable, "-c", code], capture_output=True, text=True,
                         check=True).stdout.strip()
    assert out == ""
    # even building the registry must not import the optional heavy packages
    code = code.replace("lidarsim_core;", "lidarsim_core; lidarsim_core.get_registry();")
    out = subprocess.run([sys.executable, "-c", code], capture_output=True, text=True,
                         check=True).stdout.strip()
    assert "embreex" not in out and "pyvista" not in out and "vtk" not in out
    assert "numba" not in out


def test_every_hook_is_documented():
    from lidarsim_core import hookspecs
    from lidarsim_core.plugins.registry import KINDS

    hooks = {name for name in dir(hookspecs) if name.startswith("lidarsim_")}
    assert hooks == set(KINDS.values())
    for name in hooks:
        doc = getattr(hookspecs, name).__doc__ or ""
        assert "Parameters" in doc and "register" in doc, name
