"""The shipped ray-backend conformance suite, run on every registered backend, and shown to fail
on deliberately broken backends registered through the plugin system."""

from __future__ import annotations

import re

import pytest

from lidarsim_core.plugins import get_registry
from lidarsim_core.testing.backends import BackendConformance

# one test class per registered backend: TestConformance_numpy, TestConformance_embree, ...
for _name in get_registry().names("ray_backend"):
    _cls_name = "TestConformance_" + re.sub(r"\W", "_", _name)
    globals()[_cls_name] = type(_cls_name, (BackendConformance,),
                                {"backend_name": _name, "__module__": __name__})


# A third-party style plugin: the NumPy backend with one deliberate flaw chosen by an option.
TOY_PLUGIN = '''
from typing import Literal

import numpy as np

from lidarsim_core.backends.base import Hits
from lidarsim_core.backends.numpy_backend import NumpyBackend, NumpyOptions
from lidarsim_core.hookspecs import hookimpl


class ToyOptions(NumpyOptions):
    flaw: Literal["none", "farthest", "float32", "no_epsilon", "facing_normals",
                  "culling"] = "none"


class ToyBackend(NumpyBackend):
    """The NumPy backend with a deliberate flaw."""

    name = "toy"
    Options = ToyOptions

    def intersect(self, prepared, origins, directions):
        flaw = self.options.flaw
        if flaw == "float32":
            origins = origins.astype(np.float32).astype(np.float64)
            directions = directions.astype(np.float32).astype(np.float64)
        eps = 0.0 if flaw == "no_epsilon" else self.options.epsilon_m
        d, f, n = prepared.intersect(origins, directions, t_min=eps)
        if flaw == "float32":
            d = d.astype(np.float32).astype(np.float64)
        if flaw == "farthest":  # keep going through every surface, report the last one
            start = origins + np.nan_to_num(d)[:, None] * directions
            active = f >= 0
            while active.any():
                idx = np.flatnonzero(active)
                d2, f2, n2 = prepared.intersect(start[idx], directions[idx], t_min=eps)
                j, more = idx[f2 >= 0], f2 >= 0
                d[j] += d2[more]
                f[j], n[j] = f2[more], n2[more]
                start[j] += d2[more, None] * directions[j]
                active[:] = False
                active[j] = True
        cos = np.einsum("ij,ij->i", n, directions)
        if flaw == "facing_normals":
            n = np.where((cos > 0)[:, None], -n, n)
        if flaw == "culling":
            back = cos > 0
            d[back], f[back], n[back] = np.nan, -1, np.nan
        return Hits(d, f.astype(np.int64), n)


@hookimpl
def lidarsim_register_ray_backends(register):
    register(ToyBackend)
'''

TOY_TESTS = '''
from lidarsim_core.testing.backends import BackendConformance

class TestToyCorrect(BackendConformance):
    backend_name = "toy"

''' + "".join(f'''
class TestToy_{flaw}(BackendConformance):
    backend_name = "toy"
    backend_options = {{"flaw": "{flaw}"}}
''' for flaw in ("farthest", "float32", "no_epsilon", "facing_normals", "culling"))

# Tests each flaw must fail (among others).
MUST_FAIL = {
    "farthest": {"test_canonical_scene[closest]", "test_canonical_scene[sphere_outside]",
                 "test_satellite_matches_brute_force", "test_agrees_with_other_backends"},
    "float32": {"test_canonical_scene[small_far]", "test_canonical_scene[far_coordinates]",
                "test_canonical_scene[plane_grazing]", "test_satellite_matches_brute_force"},
    "no_epsilon": {"test_canonical_scene[epsilon]"},
    "facing_normals": {"test_canonical_scene[plane_normal]", "test_canonical_scene[inside_closed]",
                       "test_canonical_scene[sphere_inside]"},
    "culling": {"test_canonical_scene[inside_closed]", "test_canonical_scene[sphere_inside]",
                "test_canonical_scene[open_mesh]", "test_canonical_scene[plane_normal]"},
}


def test_suite_fails_deliberately_broken_backends(pytester: pytest.Pytester,
                                                  monkeypatch: pytest.MonkeyPatch) -> None:
    pytester.makepyfile(toy_backends=TOY_PLUGIN, test_toys=TOY_TESTS)
    monkeypatch.setenv("LIDARSIM_PLUGINS", "toy_backends")
    monkeypatch.setenv("LIDARSIM_DISABLE_PLUGIN_AUTOLOAD", "1")
    result = pytester.runpytest_subprocess("-p", "no:cacheprovider", "-q", "-rfE")
    failed: dict[str, set[str]] = {}
    for line in result.outlines:
        match = re.match(r"(?:FAILED|ERROR) test_toys\.py::(\w+)::(\S+)", line)
        if match:
            failed.setdefault(match.group(1), set()).add(match.group(2))
    outcomes = result.parseoutcomes()
    assert "TestToyCorrect" not in failed, (
        "the correct toy backend must pass the whole suite", failed.get("TestToyCorrect"))
    assert outcomes.get("passed", 0) >= 30  # the correct toy ran the suite
    for flaw, expected in MUST_FAIL.items():
        missing = expected - failed.get(f"TestToy_{flaw}", set())
        assert not missing, f"flaw '{flaw}' was not caught by {sorted(missing)}"


def test_suite_skips_unavailable_backend_with_its_reason(pytester: pytest.Pytester,
                                                         monkeypatch: pytest.MonkeyPatch) -> None:
    pytester.makepyfile(test_unavailable='''
from lidarsim_core.backends.numpy_backend import NumpyBackend
from lidarsim_core.testing.backends import BackendConformance

class Unavailable(NumpyBackend):
    name = "unavailable"

    @classmethod
    def is_available(cls):
        return False, "needs the frobnicator"

class TestUnavailable(BackendConformance):
    backend_class = Unavailable
''')
    monkeypatch.setenv("LIDARSIM_DISABLE_PLUGIN_AUTOLOAD", "1")
    result = pytester.runpytest_subprocess("-p", "no:cacheprovider", "-q", "-rs",
                                           "-k", "empty_ray_set or canonical_scene")
    outcomes = result.parseoutcomes()
    assert outcomes.get("skipped", 0) >= 2 and "passed" not in outcomes
    result.stdout.fnmatch_lines(["*'unavailable' is not available: needs the frobnicator*"])
