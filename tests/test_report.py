"""Report figures: the error statistics they show, the run they read, and real pictures on disk."""

from __future__ import annotations

import base64
import json
import math
import os
import re
import subprocess
import sys
from pathlib import Path

import numpy as np
import pytest
from helpers import scenario

import lidarsim_core as ls
from lidarsim_core.base.errors import ConfigError
from lidarsim_core.patterns.fov import fov_coverage
from lidarsim_core.patterns.geometry import (
    directions_from_az_el,
    directions_from_off_axis,
)
from lidarsim_core.pipeline import simulate
from lidarsim_core.plugins import pattern_for
from lidarsim_core.report.colouring import point_colours
from lidarsim_core.report.run import load_run
from lidarsim_core.report.stats import (
    angular_error_components,
    fit_normal,
    range_errors,
)

FIGURES_2D = ("fig05_pattern.png", "fig06_angular_error.png", "fig09_range_error.png",
              "coverage.png")
FIGURES_3D = ("fig07_scene.png", "fig11_without_with_errors.png", "fig12_cloud_by_part.png")


def _cli(*args: str, cwd: Path | None = None) -> subprocess.CompletedProcess:
    env = {**os.environ, "LIDARSIM_DISABLE_PLUGIN_AUTOLOAD": "1", "COLUMNS": "200"}
    # through main(), which loads the command modules (report is one of them)
    code = "import sys; from lidarsim_core.cli import main; main(sys.argv[1:])"
    return subprocess.run([sys.executable, "-c", code, *args], cwd=cwd, env=env,
                          capture_output=True, text=True, timeout=600)


def _viz_available() -> bool:
    from importlib.util import find_spec

    return find_spec("matplotlib") is not None and find_spec("pyvista") is not None


needs_viz = pytest.mark.skipif(not _viz_available(), reason="the viz extra is not installed")


# ---- error statistics (no plotting library needed) -----------------------------------
def _plate_cloud(noise, n_seconds=0.3, seed=3):
    scen = scenario({"model": "plate", "options": {"size_m": [30.0, 30.0]}},
                    {"position_m": [20.0, 0.0, 0.0]}, duration_s=n_seconds, noise=noise, seed=seed)
    return simulate(scen)


def test_angular_components_recover_known_deflections():
    rng = np.random.default_rng(0)
    az, el = rng.uniform(-0.6, 0.6, 500), rng.uniform(-0.5, 0.5, 500)
    a, b = rng.normal(0, 0.01, 500), rng.normal(0, 0.01, 500)
    d0 = directions_from_az_el(az, el)
    e_az = np.stack([-np.sin(az), np.cos(az), np.zeros_like(az)], axis=-1)
    e_el = np.cross(d0, e_az)
    # tilting d0 by tan(a) along e_az and tan(b) along e_el: atan2 gives back a and b exactly
    d1 = d0 + np.tan(a)[:, None] * e_az + np.tan(b)[:, None] * e_el
    rng_true = rng.uniform(5, 50, 500)
    d1 = d1 / np.linalg.norm(d1, axis=1, keepdims=True) * rng_true[:, None]
    cloud = _plate_cloud([], 0.01)
    columns = {k: np.resize(v, 500) for k, v in cloud.columns.items()}
    columns.update(x_true=d1[:, 0], y_true=d1[:, 1], z_true=d1[:, 2], range_true=rng_true,
                   azimuth=az, elevation=el)
    got = angular_error_components(ls.PointCloud(columns, cloud.frame))
    np.testing.assert_allclose(got[:, 0], a, atol=1e-12)
    np.testing.assert_allclose(got[:, 1], b, atol=1e-12)


def test_fitted_sigmas_match_the_injected_ones():
    cloud = _plate_cloud([{"name": "angular", "options": {"sigma_deg": 0.3}},
                          {"name": "range", "options": {"sigma_m": 0.05}}])
    assert len(cloud) > 1500
    ang = fit_normal(np.degrees(angular_error_components(cloud)).ravel())
    rng = fit_normal(range_errors(cloud))
    # σ̂ of n normal draws has relative standard error 1/sqrt(2n): allow 5 of them
    assert ang.sigma == pytest.approx(0.3, rel=5 / math.sqrt(2 * ang.n))
    assert rng.sigma == pytest.approx(0.05, rel=5 / math.sqrt(2 * rng.n))
    assert abs(ang.mean) < 5 * 0.3 / math.sqrt(ang.n)
    lo, hi = rng.sigma_ci95
    assert lo < rng.sigma < hi and hi - lo == pytest.approx(2 * 1.96 * rng.sigma /
                                                            math.sqrt(2 * rng.n))


def test_noiseless_cloud_has_no_angular_or_range_error():
    cloud = _plate_cloud([], 0.05)
    assert np.max(np.abs(angular_error_components(cloud))) < 1e-12
    assert np.max(np.abs(range_errors(cloud))) == 0.0


def test_fitted_normal_density_integrates_to_one():
    fit = fit_normal(np.random.default_rng(1).normal(2.0, 0.5, 20000))
    x = np.linspace(-3, 7, 20001)
    assert np.trapezoid(fit.pdf(x), x) == pytest.approx(1.0, abs=1e-6)
    peak = 1 / (fit.sigma * math.sqrt(2 * math.pi))
    assert fit.pdf(np.array([fit.mean]))[0] == pytest.approx(peak)


def test_colour_by_time_range_intensity_and_unknown():
    cloud = _plate_cloud([], 0.05)
    time_ms = point_colours(cloud, "time")
    np.testing.assert_allclose(time_ms.values, 1e3 * (cloud["timestamp"] - cloud.frame.t_start))
    assert point_colours(cloud, "range").values.max() == pytest.approx(cloud["range"].max())
    part = point_colours(cloud, "part")
    assert part.categorical and part.names == ("plate",)
    cloud.columns.pop("intensity")  # as in a file written without intensity
    with pytest.raises(ConfigError, match="--color-by.*choose one of part, range, time"):
        point_colours(cloud, "intensity")
    cloud.columns["intensity"] = np.linspace(0, 1, len(cloud))
    assert point_colours(cloud, "intensity").values[-1] == 1.0


# ---- figures' geometry -------------------------------------------------------------------
def test_rays_meet_the_plane_at_tan_theta():
    from lidarsim_core.report.charts import plane_points

    theta = np.radians([0.0, 10.0, 35.2])
    phi = np.radians([0.0, 90.0, 200.0])
    pts, forward = plane_points(directions_from_off_axis(theta, phi), 1.0)
    assert forward.all()
    np.testing.assert_allclose(np.hypot(pts[:, 0], pts[:, 1]), np.tan(theta), atol=1e-12)
    np.testing.assert_allclose(np.arctan2(pts[2, 1], pts[2, 0]) % (2 * np.pi), phi[2])


@pytest.mark.parametrize("sensor", ["livox-mid70-rose", "velodyne-vlp16"])
def test_coverage_map_counts_every_ray_and_agrees_with_fov_coverage(sensor):
    from lidarsim_core.report.charts import coverage_map

    pattern = pattern_for(ls.get_sensor(sensor))
    cmap = coverage_map(pattern, 0.05, 0.5)
    k0, k1 = pattern.index_range(0.0, 0.05)
    assert cmap.counts.sum() == k1 - k0  # every ray lands in exactly one cell
    official = fov_coverage(pattern, 0.05, 0.5).coverage
    assert 0.0 < cmap.coverage < 1.0
    assert cmap.coverage == pytest.approx(official, abs=0.03)


# ---- the run directory -----------------------------------------------------------------
def _write_run(directory: Path, noise, *, duration=0.05) -> Path:
    import yaml

    scen = ls.demo_scenario(duration_s=duration, noise=bool(noise), detail="coarse",
                            backend="numpy", seed=5)
    directory.mkdir(parents=True, exist_ok=True)
    (directory / "scenario.yaml").write_text(yaml.safe_dump(scen.model_dump(mode="json")))
    simulate(scen).save(directory / "cloud.npz")
    return directory


def test_run_without_its_noiseless_twin_is_completed_by_simulation(tmp_path):
    run_dir = _write_run(tmp_path / "run", noise=True)
    run = load_run(run_dir)
    assert run.simulated == ["without errors"] and run.notes == []
    assert run.files == {"with errors": run_dir / "cloud.npz"}
    np.testing.assert_array_equal(run.clean["range"], run.clean["range_true"])
    assert run.clean.frame.rays_emitted == run.noisy.frame.rays_emitted
    assert run.noisy.frame.noise == ["angular", "range"]
    with pytest.raises(ConfigError, match="no cloud without errors"):
        load_run(run_dir, complete=False)


def test_a_cloud_from_another_configuration_is_noted(tmp_path):
    import yaml

    run_dir = _write_run(tmp_path / "run", noise=True)
    data = yaml.safe_load((run_dir / "scenario.yaml").read_text())
    data["seed"] = 99
    (run_dir / "scenario.yaml").write_text(yaml.safe_dump(data))
    run = load_run(run_dir)
    assert len(run.notes) == 1 and run.notes[0].startswith("cloud.npz was made by a "
                                                           "configuration other")


def test_run_errors_name_the_directory(tmp_path):
    with pytest.raises(ConfigError, match="no scenario file"):
        load_run(tmp_path)
    (tmp_path / "scenario.yaml").write_text((Path(__file__).parents[1] / "examples" /
                                             "envisat_mid70.yaml").read_text())
    np.savez(tmp_path / "rays.npz", t=np.zeros(3))  # not a lidarsim cloud: ignored
    with pytest.raises(ConfigError, match="no point cloud written by lidarsim"):
        load_run(tmp_path)
    _write_run(tmp_path / "other", noise=True)
    (tmp_path / "other" / "cloud.npz").rename(tmp_path / "cloud.npz")
    with pytest.raises(ConfigError, match="no cloud of frame 3"):
        load_run(tmp_path, frame=3)


def test_importing_the_report_package_stays_light():
    code = ("import sys, lidarsim_core.report, lidarsim_core.cli.report; "
            "print(sorted(m for m in ('pyvista', 'vtk', 'matplotlib') if m in sys.modules))")
    out = subprocess.run([sys.executable, "-c", code], capture_output=True, text=True,
                         check=True).stdout
    assert out.strip() == "[]"


# ---- pictures on disk --------------------------------------------------------------------
def _image(path: Path) -> np.ndarray:
    from PIL import Image

    return np.asarray(Image.open(path).convert("RGB")).astype(int)


def _near(img: np.ndarray, rgb: str, tol: int = 40) -> int:
    """Pixels within ``tol`` of the colour ``#rrggbb``."""
    target = np.array([int(rgb[i:i + 2], 16) for i in (1, 3, 5)])
    return int((np.abs(img - target).max(axis=2) <= tol).sum())


def _hue_pixels(img: np.ndarray, rgb: str, tol_deg: float = 12.0) -> int:
    """Saturated pixels whose hue is within ``tol_deg`` of the colour's (shading-proof)."""
    from matplotlib.colors import rgb_to_hsv

    target = rgb_to_hsv(np.array([int(rgb[i:i + 2], 16) for i in (1, 3, 5)]) / 255.0)
    hsv = rgb_to_hsv(img / 255.0)
    diff = np.abs((hsv[..., 0] - target[0] + 0.5) % 1.0 - 0.5) * 360
    return int(((diff <= tol_deg) & (hsv[..., 1] > 0.4) & (hsv[..., 2] > 0.15)).sum())


def _hue_bins(img: np.ndarray, min_pixels: int = 150) -> int:
    """How many 30° hue bins hold at least ``min_pixels`` saturated pixels."""
    from matplotlib.colors import rgb_to_hsv

    hsv = rgb_to_hsv(img / 255.0).reshape(-1, 3)
    hue = hsv[(hsv[:, 1] > 0.4) & (hsv[:, 2] > 0.15), 0]
    return int((np.bincount((hue * 12).astype(int) % 12, minlength=12) >= min_pixels).sum())


def _assert_real_picture(path: Path, min_size=(600, 400)) -> np.ndarray:
    img = _image(path)
    h, w, _ = img.shape
    assert w >= min_size[0] and h >= min_size[1], f"{path.name} is only {w}×{h}"
    not_white = (img < 235).any(axis=2).mean()
    assert 0.01 < not_white < 0.97, f"{path.name}: {100 * not_white:.1f} % non-white pixels"
    q = img // 16
    colours = len(np.unique(q[..., 0] * 256 + q[..., 1] * 16 + q[..., 2]))
    assert colours >= 20, f"{path.name} has only {colours} colour bins"
    return img


@pytest.fixture(scope="module")
def demo_dir(tmp_path_factory):
    if not _viz_available():
        pytest.skip("the viz extra is not installed")
    out = tmp_path_factory.mktemp("demo") / "demo-out"
    res = _cli("demo", "--out", str(out), "--duration", "0.3", "--detail", "coarse")
    assert res.returncode == 0, res.stderr
    assert "report:" in res.stdout and "report.html" in res.stdout, res.stdout
    return out


@needs_viz
def test_demo_leaves_every_figure_as_a_real_picture(demo_dir):
    from lidarsim_core.report.render import rendering_backend

    rendering_backend()  # fails the test, with what to install, when no OpenGL renders here
    for name in FIGURES_2D + FIGURES_3D:
        _assert_real_picture(demo_dir / name)
    summary = json.loads((demo_dir / "report.json").read_text())["summary"]
    assert summary["sensor"] == "livox-mid70-rose" and summary["rays_emitted"] == 30000
    n = summary["points_with_errors"]
    assert summary["angular_sigma_deg"] == pytest.approx(0.1, rel=5 / math.sqrt(4 * n))
    assert summary["range_sigma_mm"] == pytest.approx(20.0, rel=5 / math.sqrt(2 * n))
    assert summary["simulated_by_report"] == []


@needs_viz
def test_figures_show_what_the_paper_shows(demo_dir):
    from lidarsim_core.report.charts import _SEGMENT_COLOURS
    from lidarsim_core.report.colouring import part_colour
    from lidarsim_core.report.scene import CLEAN_COLOUR, NOISY_COLOUR, SENSOR_COLOUR

    pattern = _image(demo_dir / "fig05_pattern.png")
    for colour in _SEGMENT_COLOURS[:3]:  # three rosettes, each drawn
        assert _near(pattern, colour, 30) > 1000
    scene = _image(demo_dir / "fig07_scene.png")
    assert _near(scene, SENSOR_COLOUR, 40) > 500  # the red LiDAR and its axes
    errors = _image(demo_dir / "fig11_without_with_errors.png")
    h, w, _ = errors.shape
    lower = errors[h // 3:]
    left, right = lower[:, : w // 2], lower[:, w // 2:]
    assert _near(left, CLEAN_COLOUR) > 300 and _near(left, NOISY_COLOUR) == 0
    assert _near(right, NOISY_COLOUR) > 300 and _near(right, CLEAN_COLOUR) == 0
    # edge-on row: noiseless points lie on one line, noisy ones spread over many rows
    for half, colour, rows in ((left, CLEAN_COLOUR, (1, 12)), (right, NOISY_COLOUR, (25, 10**6))):
        bottom = half[half.shape[0] // 2:]
        hit_rows = int((np.abs(bottom - [int(colour[i:i + 2], 16) for i in (1, 3, 5)])
                        .max(axis=2) <= 40).any(axis=1).sum())
        assert rows[0] <= hit_rows <= rows[1], (colour, hit_rows)
    cloud = _image(demo_dir / "fig12_cloud_by_part.png")
    h, w, _ = cloud.shape
    for half in (cloud[:, : w // 2], cloud[:, w // 2:]):  # model and cloud: bus and solar array
        assert _hue_pixels(half, part_colour(0)) > 500 and _hue_pixels(half, part_colour(1)) > 500


@needs_viz
@pytest.mark.parametrize("sensor", ["velodyne-vlp16", "rvs-class-lissajous"])
def test_pattern_figure_of_spinning_and_rectangular_sensors(sensor, tmp_path):
    from lidarsim_core.report.charts import _SEGMENT_COLOURS, pattern_figure

    path = pattern_figure(pattern_for(ls.get_sensor(sensor)), tmp_path / "p.png")
    img = _assert_real_picture(path)
    counts = [_near(img, colour, 30) for colour in _SEGMENT_COLOURS[:3]]
    assert min(counts) > 500, counts  # three segments, each drawn
    if sensor == "velodyne-vlp16":  # a third of a revolution each: similar extents
        assert max(counts) < 1.6 * min(counts), counts


@needs_viz
def test_html_report_is_self_contained(demo_dir):
    page = (demo_dir / "report.html").read_text()
    images = re.findall(r'src="data:image/png;base64,([^"]+)"', page)
    assert len(images) == len(FIGURES_2D + FIGURES_3D)
    assert all(base64.b64decode(i)[:8] == b"\x89PNG\r\n\x1a\n" for i in images)
    assert not re.search(r'(src|href)="(https?:|//|[^"#d][^"]*\.(png|css|js))', page)
    assert "lidarsim report" in page and "Fig. 11" in page


@needs_viz
def test_report_command_options_and_one_line_errors(demo_dir, tmp_path):
    out = tmp_path / "rep"
    res = _cli("report", str(demo_dir), "--out", str(out), "--no-3d", "--coverage-time", "0.1",
               "--cell-deg", "1")
    assert res.returncode == 0, res.stderr
    assert sorted(p.name for p in out.glob("*.png")) == sorted(FIGURES_2D)
    summary = json.loads((out / "report.json").read_text())["summary"]
    assert summary["coverage_time_s"] == 0.1 and summary["coverage_cell_deg"] == 1.0
    assert "--coverage-time 0.1" in (out / "report.html").read_text()
    bad = _cli("report", str(demo_dir), "--out", str(tmp_path / "x"), "--color-by", "colour")
    assert bad.returncode == 2 and "--color-by" in bad.stderr and "choose one of" in bad.stderr
    assert not (tmp_path / "x").exists()
    empty = _cli("report", str(tmp_path / "nowhere"))
    assert empty.returncode == 2 and "nowhere" in empty.stderr


@needs_viz
def test_cloud_coloured_by_time_runs_through_the_colour_map(demo_dir, tmp_path):
    from lidarsim_core.report.render import rendering_backend
    from lidarsim_core.report.scene import cloud_figure

    rendering_backend()
    path = cloud_figure(load_run(demo_dir), tmp_path / "by_time.png", "time")
    img = _assert_real_picture(path)
    # the cloud half above the colour bar: the 'turbo' map spreads the points over many hues,
    # where colouring by part gives the bus's blue and the array's orange only
    points = img[: int(0.85 * img.shape[0]), img.shape[1] // 2:]
    assert _hue_bins(points) >= 5, _hue_bins(points)
    by_part = _image(demo_dir / "fig12_cloud_by_part.png")
    assert _hue_bins(by_part[: int(0.85 * by_part.shape[0]), by_part.shape[1] // 2:]) <= 3


@needs_viz
def test_without_opengl_the_report_keeps_the_2d_figures(demo_dir, tmp_path, monkeypatch):
    from lidarsim_core.report import builder, render

    monkeypatch.setitem(render._chosen, "window", False)
    monkeypatch.setitem(render._chosen, "why", "no OpenGL here (test)")
    report = builder.write_report(demo_dir, tmp_path / "r")
    assert {f.path.name for f in report.figures} == set(FIGURES_2D)
    assert any("3-D figures" in n and "no OpenGL here" in n for n in report.notes)
    assert "no OpenGL here" in (tmp_path / "r" / "report.html").read_text()


def test_demo_without_the_viz_extra_says_so_in_one_line(tmp_path, monkeypatch, capsys):
    from lidarsim_core.cli import report as cli_report
    from lidarsim_core.report import builder

    def missing() -> None:
        raise builder.VizMissing("report figures need pyvista: pip install "
                                 "'lidarsim-core[viz]'")

    monkeypatch.setattr(builder, "require_viz", missing)
    cli_report.demo_report(tmp_path)
    out = capsys.readouterr().out
    assert "no report figures" in out and "lidarsim-core[viz]" in out
    assert list(tmp_path.iterdir()) == []


@needs_viz
def test_the_pages_regenerate_command_works_as_written(demo_dir):
    """report.html ends with the command that regenerates it; run as printed (with its
    --overwrite: the report's own files are in the folder), it succeeds and writes the same
    figures."""
    import html
    import re
    import shlex

    page = (demo_dir / "report.html").read_text(encoding="utf-8")
    command = html.unescape(re.search(r"<h2>Regenerate</h2>\s*<pre>(.*?)</pre>", page,
                                      re.S).group(1))
    words = shlex.split(command)
    assert words[:2] == ["lidarsim", "report"] and "--overwrite" in words
    before = {p.name for p in demo_dir.iterdir()}
    res = _cli(*words[1:])
    assert res.returncode == 0, res.stderr
    assert {p.name for p in demo_dir.iterdir()} == before  # the same files, replaced
    assert res.stderr == ""  # progress lines only at a terminal: a pipe gets no chatter
