"""Fail when embreex is importable but the Embree conformance suite did not run.

Usage::

    python .ci/check_backends.py [JUNIT_XML]

With a JUnit XML report of a pytest run that included ``tests/test_backend_conformance.py``,
the report is inspected; without one, that test module's Embree class is run here. The check
fails (exit 1) if embreex imports but the ``TestConformance_embree`` tests are missing, skipped
or failing; it passes with a notice when embreex is not installed.
"""

from __future__ import annotations

import subprocess
import sys
import tempfile
import xml.etree.ElementTree as ET
from pathlib import Path

EMBREE_CLASS = "TestConformance_embree"
ROOT = Path(__file__).resolve().parents[1]


def embreex_importable() -> tuple[bool, str]:
    """Whether ``import embreex`` works, and the error if not."""
    try:
        import embreex  # noqa: F401
    except Exception as exc:  # any import failure means the backend cannot run
        return False, f"{type(exc).__name__}: {exc}"
    return True, ""


def embree_outcomes(report: Path) -> dict[str, list[str]]:
    """Test names of the Embree conformance class in a JUnit report, by outcome."""
    outcomes: dict[str, list[str]] = {"passed": [], "skipped": [], "failed": []}
    for case in ET.parse(report).getroot().iter("testcase"):
        if not case.get("classname", "").endswith(EMBREE_CLASS):
            continue
        name = case.get("name", "?")
        if case.find("skipped") is not None:
            skip = case.find("skipped")
            outcomes["skipped"].append(f"{name}: {skip.get('message', '')}")
        elif case.find("failure") is not None or case.find("error") is not None:
            outcomes["failed"].append(name)
        else:
            outcomes["passed"].append(name)
    return outcomes


def run_suite(report: Path) -> None:
    """Run the Embree conformance class, writing a JUnit report."""
    subprocess.run([sys.executable, "-m", "pytest", "-q", "-p", "no:cacheprovider",
                    str(ROOT / "tests" / "test_backend_conformance.py"), "-k", EMBREE_CLASS,
                    f"--junitxml={report}"], cwd=ROOT, check=False)


def main(argv: list[str]) -> int:
    ok, why = embreex_importable()
    if not ok:
        print(f"check_backends: embreex is not importable ({why}); Embree suite not required")
        return 0
    with tempfile.TemporaryDirectory() as tmp:
        report = Path(argv[0]) if argv else Path(tmp) / "embree.xml"
        if not argv:
            run_suite(report)
        if not report.is_file():
            print(f"check_backends: FAIL: no JUnit report at {report}")
            return 1
        outcomes = embree_outcomes(report)
    if not any(outcomes.values()):
        print(f"check_backends: FAIL: embreex is installed but no {EMBREE_CLASS} test ran")
        return 1
    if outcomes["skipped"]:
        print(f"check_backends: FAIL: embreex is installed but {len(outcomes['skipped'])} Embree "
              "conformance tests were skipped:")
        for line in outcomes["skipped"][:10]:
            print(f"  {line}")
        return 1
    if outcomes["failed"]:
        print(f"check_backends: FAIL: {len(outcomes['failed'])} Embree conformance tests failed: "
              f"{', '.join(outcomes['failed'][:10])}")
        return 1
    print(f"check_backends: ok: {len(outcomes['passed'])} Embree conformance tests passed")
    return 0


if __name__ == "__main__":
    sys.exit(main(sys.argv[1:]))
