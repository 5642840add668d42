"""BOP's ADD, ADD-S, ADD(-S) accuracy and MSSD and the SPEED+ scores: every one against its
closed form on synthetic estimates with known offsets, then in ``lidarsim evaluate``'s files."""

from __future__ import annotations

import csv
import itertools
import json
import math
from pathlib import Path

import numpy as np
import pytest
from scipy.spatial.transform import Rotation

from lidarsim_core.evaluate import SymmetryGroup, evaluate_dataset
from lidarsim_core.evaluate.metrics import pose_errors
from lidarsim_core.evaluate.scores import SCORES, TargetScorer, diameter, speedplus_scores
from lidarsim_core.evaluate.symmetry import Symmetry

from test_evaluate import dataset  # noqa: F401  (the module's small dataset fixture)

#: A box 4 × 4 × 2 m centred on the body origin: four-fold about z.
BOX = np.array(list(itertools.product([-2.0, 2.0], [-2.0, 2.0], [-1.0, 1.0])))
BOX_DIAMETER = math.sqrt(4 ** 2 + 4 ** 2 + 2 ** 2)  # the space diagonal, 6 m
TRUTH_Q = Rotation.from_euler("xyz", [20, -35, 70], degrees=True)
TRUTH_T = np.array([12.0, -3.0, 4.0])


def _pose(rotation: Rotation, t) -> np.ndarray:
    out = np.eye(4)
    out[:3, :3] = rotation.as_matrix()
    out[:3, 3] = t
    return out


def _errors(est_rotation: Rotation, est_t, scorer, group=None):
    return pose_errors(est_rotation.as_quat(), est_t, TRUTH_Q.as_quat(), TRUTH_T, group, scorer)


def test_diameter_is_the_largest_vertex_distance():
    assert diameter(BOX) == pytest.approx(BOX_DIAMETER, abs=1e-12)
    rng = np.random.default_rng(3)
    cloud = rng.normal(size=(300, 3))
    brute = max(np.linalg.norm(a - b) for a in cloud for b in cloud)
    assert diameter(cloud) == pytest.approx(brute, abs=1e-12)


def test_pure_translation_scores_its_length():
    scorer = TargetScorer(BOX)
    d = np.array([0.03, -0.04, 0.12])  # |d| = 0.13 m
    out = _errors(TRUTH_Q, TRUTH_T + d, scorer)
    assert out["add_m"] == pytest.approx(0.13, abs=1e-12)
    assert out["mssd_m"] == pytest.approx(0.13, abs=1e-12)
    assert out["adds_m"] <= out["add_m"] + 1e-12  # the closest vertex is at most that far
    # ADD-S of a translation shorter than half the vertex spacing is the translation too
    assert out["adds_m"] == pytest.approx(0.13, abs=1e-12)


def test_accuracy_at_ten_percent_of_the_diameter():
    scorer = TargetScorer(BOX)
    direction = np.array([1.0, 2.0, 2.0]) / 3.0
    below = _errors(TRUTH_Q, TRUTH_T + 0.099 * BOX_DIAMETER * direction, scorer)
    above = _errors(TRUTH_Q, TRUTH_T + 0.101 * BOX_DIAMETER * direction, scorer)
    assert below["add_s_correct"] == 1.0 and above["add_s_correct"] == 0.0


def test_rotation_about_an_axis_through_the_origin():
    """ADD of a turn θ about the body's z axis: mean 2 r sin(θ/2), r the distance of each vertex
    from the axis; MSSD the largest of them."""
    scorer = TargetScorer(BOX)
    theta = math.radians(25.0)
    est = TRUTH_Q * Rotation.from_rotvec([0.0, 0.0, theta])
    out = _errors(est, TRUTH_T, scorer)
    r = np.hypot(BOX[:, 0], BOX[:, 1])
    assert out["add_m"] == pytest.approx(np.mean(2 * r * math.sin(theta / 2)), abs=1e-12)
    assert out["mssd_m"] == pytest.approx(np.max(2 * r * math.sin(theta / 2)), abs=1e-12)


def test_turn_about_a_symmetry_axis_scores_zero_with_add_s_not_with_add():
    """A 90° turn of the four-fold box about z: ADD-S is 0 (every vertex lands on a vertex)
    while ADD is √2 r = 4 m; MSSD is 0 with the symmetry declared, 4 m without."""
    group = SymmetryGroup.from_symmetries([Symmetry(axis=(0, 0, 1), order=4)])
    est = TRUTH_Q * Rotation.from_rotvec([0.0, 0.0, math.pi / 2])
    symmetric = _errors(est, TRUTH_T, TargetScorer(BOX, group), group)
    plain = _errors(est, TRUTH_T, TargetScorer(BOX))
    r = math.hypot(2.0, 2.0)
    for out in (symmetric, plain):
        assert out["adds_m"] == pytest.approx(0.0, abs=1e-9)
        assert out["add_m"] == pytest.approx(math.sqrt(2.0) * r, abs=1e-12)
    assert symmetric["mssd_m"] == pytest.approx(0.0, abs=1e-9)
    assert plain["mssd_m"] == pytest.approx(math.sqrt(2.0) * r, abs=1e-12)
    # the accuracy uses ADD-S for the declared-symmetric target, ADD otherwise
    assert symmetric["add_s_correct"] == 1.0 and plain["add_s_correct"] == 0.0
    assert symmetric["mssd_recall"] == 1.0 and plain["mssd_recall"] == 0.0
    # and SPEED's terms score the equivalent pose: nothing to correct
    assert symmetric["speedplus_score"] == 0.0 and plain["speedplus_q_rad"] > 1.5


def test_axisymmetric_ring_scores_any_turn_about_its_axis_within_bops_step():
    ring = np.array([[math.cos(a), math.sin(a), z] for a in np.radians(np.arange(0, 360, 1.0))
                     for z in (-0.5, 0.5)])
    group = SymmetryGroup.from_symmetries([Symmetry(axis=(0, 0, 1), order="inf")])
    scorer = TargetScorer(ring, group)
    est = TRUTH_Q * Rotation.from_rotvec([0.0, 0.0, math.radians(37.0)])
    out = _errors(est, TRUTH_T, scorer, group)
    assert out["adds_m"] == pytest.approx(0.0, abs=1e-9)  # 37° maps 1° vertices on vertices
    assert out["add_m"] == pytest.approx(2 * math.sin(math.radians(37.0) / 2), abs=1e-12)
    # the sampled turns move no vertex more than 1 % of the diameter: MSSD within it
    assert out["mssd_m"] <= 0.01 * scorer.diameter_m
    # a tilt of the axis is not a symmetry: MSSD = the largest displacement
    tilt = math.radians(5.0)
    tilted = _errors(TRUTH_Q * Rotation.from_rotvec([tilt, 0.0, 0.0]), TRUTH_T, scorer, group)
    radius = np.linalg.norm(ring[:, 1:], axis=1)  # distance from the x axis
    assert tilted["mssd_m"] == pytest.approx(np.max(2 * radius * math.sin(tilt / 2)),
                                             rel=0.02)


@pytest.mark.parametrize("e_t, e_q_deg, t_score, q_zero", [
    (0.002, 0.1, 0.0, True),      # both below: a perfect score
    (0.0022, 0.1, 0.0022, True),  # above 2.173 mm/m: kept
    (0.002, 0.17, 0.0, False),    # above 0.169°: kept
    (0.0, 0.0, 0.0, True)])
def test_speedplus_thresholds_zero_the_errors_below_them(e_t, e_q_deg, t_score, q_zero):
    e_q = math.radians(e_q_deg)
    out = speedplus_scores(e_t, e_q)
    assert out["speedplus_t"] == t_score
    assert out["speedplus_q_rad"] == (0.0 if q_zero else e_q)
    assert out["speedplus_score"] == out["speedplus_t"] + out["speedplus_q_rad"]


def test_speedplus_on_a_pose_a_hair_off():
    scorer = TargetScorer(BOX)
    range_m = float(np.linalg.norm(TRUTH_T))
    small = _errors(TRUTH_Q * Rotation.from_rotvec([0.0, math.radians(0.1), 0.0]),
                    TRUTH_T * (1 + 0.002), scorer)
    assert small["e_t"] == pytest.approx(0.002) and small["speedplus_score"] == 0.0
    large = _errors(TRUTH_Q, TRUTH_T + [0.003 * range_m, 0, 0], scorer)
    assert large["speedplus_score"] == pytest.approx(large["e_t"]) and large["e_t"] > 0.002173


# ---- in lidarsim evaluate --------------------------------------------------------------------
def _rows(out: Path) -> list[dict[str, str]]:
    with open(out / "metrics.csv", newline="") as stream:
        return list(csv.DictReader(stream))


def test_evaluate_writes_the_scores(dataset, tmp_path):  # noqa: F811
    """gt_noise with translation noise only: ADD = the translation error on every frame, the
    SPEED+ position score is e_t where it is above 2.173 mm/m and 0 below."""
    result = evaluate_dataset(dataset, tmp_path / "ev", "gt_noise",
                              {"translation_sigma_m": 0.05, "rotation_sigma_deg": 0.0})
    rows = _rows(tmp_path / "ev")
    assert set(SCORES) <= set(rows[0])
    kept = 0
    for row in rows:
        t, e_t = float(row["translation_error_m"]), float(row["e_t"])
        assert float(row["add_m"]) == pytest.approx(t, rel=1e-9)
        assert float(row["mssd_m"]) == pytest.approx(t, rel=1e-9)
        assert float(row["speedplus_q_rad"]) == 0.0
        assert float(row["speedplus_t"]) == (e_t if e_t >= 0.002173 else 0.0)
        kept += e_t >= 0.002173
    assert 0 < kept  # the case is not empty
    summary = json.loads((tmp_path / "ev" / "summary.json").read_text())
    overall = summary["overall"]
    assert overall["scores"]["add_s_accuracy"] == 1.0  # cm errors on a 10 m+ satellite
    assert overall["scores"]["speedplus_score"] == pytest.approx(
        np.mean([float(r["speedplus_score"]) for r in rows]))
    assert overall["add_m"]["mean"] == pytest.approx(np.mean([float(r["add_m"]) for r in rows]))
    assert summary["score_thresholds"]["speedplus_orientation_deg"] == 0.169
    # the diameter of the mesh the simulation traced (brute force on its vertices)
    from lidarsim_core.evaluate.data import open_dataset

    vertices = np.unique(open_dataset(dataset, None)[0][0].model(0).vertices, axis=0)
    from scipy.spatial import ConvexHull

    hull = vertices[ConvexHull(vertices).vertices]
    brute = max(np.linalg.norm(hull - p, axis=1).max() for p in hull)
    assert summary["sequences"]["main"]["target_diameter_m"] == pytest.approx(brute)
    report = (tmp_path / "ev" / "report.html").read_text()
    assert "Scores of the literature" in report and "AR<sub>MSSD</sub>" in report
    assert result.summary["overall"]["scores"] == overall["scores"]
