""".ci/check_backends.py: fails when embreex is importable but the Embree suite was skipped."""

from __future__ import annotations

import importlib.util
from pathlib import Path

import pytest

SCRIPT = Path(__file__).resolve().parents[1] / ".ci" / "check_backends.py"


@pytest.fixture
def check(monkeypatch):
    spec = importlib.util.spec_from_file_location("check_backends", SCRIPT)
    module = importlib.util.module_from_spec(spec)
    spec.loader.exec_module(module)
    monkeypatch.setattr(module, "embreex_importable", lambda: (True, ""))
    return module


def _report(tmp_path: Path, *cases: str) -> str:
    path = tmp_path / "junit.xml"
    body = "".join(
        f'<testcase classname="tests.test_backend_conformance.{cls}" name="t{i}">{inner}'
        "</testcase>" for i, (cls, inner) in enumerate(c.split("|") for c in cases))
    path.write_text(f"<testsuites><testsuite>{body}</testsuite></testsuites>")
    return str(path)


def test_passes_when_the_embree_suite_ran(check, tmp_path, capsys):
    assert check.main([_report(tmp_path, "TestConformance_embree|", "TestConformance_numpy|")]) == 0
    assert "1 Embree conformance tests passed" in capsys.readouterr().out


@pytest.mark.parametrize("cases", [
    ("TestConformance_embree|<skipped message=\"embreex is not installed\"/>",),
    ("TestConformance_numpy|",),  # the Embree class did not run at all
    ("TestConformance_embree|<failure message=\"x\"/>",),
])
def test_fails_when_embree_is_installed_but_skipped_missing_or_failing(check, tmp_path, cases):
    assert check.main([_report(tmp_path, *cases)]) == 1


def test_passes_without_embreex(check, monkeypatch, tmp_path):
    monkeypatch.setattr(check, "embreex_importable", lambda: (False, "ImportError: none"))
    assert check.main([_report(tmp_path, "TestConformance_numpy|")]) == 0
