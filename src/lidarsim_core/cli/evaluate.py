"""The ``lidarsim evaluate`` command: score a pose estimator on a dataset (docs/evaluate.md)."""

from __future__ import annotations

from pathlib import Path
from typing import Any, List, Optional

import typer

from .app import app
from .errors import run_guarded
from .output import console


def parse_options(items: list[str]) -> dict[str, Any]:
    """``["k=v", ...]`` → ``{k: v}`` with each value read as a YAML scalar or flow list
    (``2``, ``0.5``, ``true``, ``[1.0, 0.3]``)."""
    import yaml

    from ..base.errors import ConfigError

    options: dict[str, Any] = {}
    for item in items:
        key, sep, value = item.partition("=")
        if not sep or not key.strip():
            raise ConfigError(f"'{item}' is not KEY=VALUE", field="--option")
        try:
            options[key.strip()] = yaml.safe_load(value) if value.strip() else ""
        except yaml.YAMLError:
            raise ConfigError(f"'{item}': the value is not a number, word or [list]",
                              field="--option") from None
    return options


@app.command()
def evaluate(dataset: Path = typer.Argument(..., help="Dataset directory made by "
                                                      "'lidarsim dataset'."),
             estimator: str = typer.Option(..., "--estimator", "-e", help="Pose estimator: "
                                           "icp, fpfh_ransac_icp, gt_noise, or a plugin's."),
             out: Path = typer.Option(..., "--out", "-o", help="Output directory (new, empty, "
                                      "or one this same command started: it then resumes)."),
             option: List[str] = typer.Option([], "--option", help="Estimator option KEY=VALUE "
                                              "(repeatable), e.g. --option voxel_m=0.3."),
             split: Optional[str] = typer.Option(None, help="Only this split: train, val or "
                                                 "test."),
             target: Optional[str] = typer.Option(None, help="Target whose pose is estimated "
                                                  "(default: each sequence's first)."),
             symmetry: List[str] = typer.Option([], "--symmetry", help="A symmetry of the "
                                                "target in its body frame, AXIS:ORDER or "
                                                "AXIS:ORDER@CX,CY,CZ, e.g. z:4, x:inf, "
                                                "z:2@0.5,0,0 (repeatable)."),
             segment: bool = typer.Option(False, help="Give the estimator only the target's "
                                          "points (oracle segmentation by the true labels)."),
             seed: int = typer.Option(0, min=0, max=2 ** 31 - 1, help="Seed of randomised "
                                      "estimators."),
             range_bins: str = typer.Option("0,10,20,50,100,200,500", help="Edges of the "
                                            "summary's range bins (m)."),
             within: str = typer.Option("0.05,2", help="Thresholds 'METRES,DEGREES' of the "
                                        "summary's within_rate."),
             quiet: bool = typer.Option(False, "--quiet", "-q", help="No progress bar, no "
                                        "summary."),
             no_verify: bool = typer.Option(False, "--no-verify", help="Skip recomputing "
                                            "every frame file's SHA-256 against the "
                                            "manifest (faster; paths and poses are still "
                                            "checked)."),
             ) -> None:
    """Score a pose estimator on every frame of a dataset: estimates, metrics, summary, plots,
    HTML report."""
    run_guarded(lambda: _evaluate(dataset, estimator, out, option, split, target, symmetry,
                                  segment, seed, range_bins, within, quiet,
                                  verify=not no_verify))


def _evaluate(dataset: Path, estimator: str, out: Path, option: list[str], split: str | None,
              target: str | None, symmetry: list[str], segment: bool, seed: int,
              range_bins: str, within: str, quiet: bool, *, verify: bool = True) -> None:
    from ..base.errors import ConfigError
    from ..evaluate import evaluate_dataset, parse_symmetry
    from .progress import EvaluateBar

    symmetries = []
    for spec in symmetry:
        named, sym = parse_symmetry(spec)
        if named is not None and target is not None and named != target:
            raise ConfigError(f"symmetry '{spec}' names target '{named}' but --target is "
                              f"'{target}'", field="--symmetry")
        symmetries.append(sym)
    try:
        bins = [float(v) for v in range_bins.split(",") if v.strip()]
    except ValueError:
        raise ConfigError(f"'{range_bins}' is not a comma-separated list of numbers",
                          field="--range-bins") from None
    try:
        thresholds = tuple(float(v) for v in within.split(","))
    except ValueError:
        thresholds = ()
    if len(thresholds) != 2:
        raise ConfigError(f"'{within}' is not 'METRES,DEGREES'", field="--within")
    result = evaluate_dataset(dataset, out, estimator, parse_options(option), split=split,
                              target=target, symmetries=symmetries, segment=segment, seed=seed,
                              range_bins_m=bins, within=thresholds,  # type: ignore[arg-type]
                              quiet=quiet, display=EvaluateBar(), verify=verify)
    if quiet:
        return
    overall = result.summary["overall"]
    t, r, s = (overall[m]["median"] for m in ("translation_error_m", "rotation_error_deg",
                                               "speed_score"))
    median = "no valid estimate" if t is None else \
        f"median errors {t:.4g} m, {r:.4g}°, SPEED score {s:.4g}; " \
        f"{overall['within_rate'] * 100:.3g} % within {thresholds[0]:g} m and {thresholds[1]:g}°"
    from .output import markup_safe

    console().print(
        f"evaluate {markup_safe(estimator)}: {result.frames_total} frames ({result.frames_evaluated} run, "
        f"{result.frames_skipped} already done), {overall['successes']} with an estimate; "
        f"{median} → {markup_safe(result.out / 'report.html')}")
