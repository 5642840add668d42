"""Noiseless simulations against analytic geometry (plane, sphere, box), for every backend."""

from __future__ import annotations

import numpy as np
import pytest
from helpers import scenario
from scipy.spatial.transform import Rotation

import lidarsim_core as ls

BACKENDS = ["numpy", pytest.param("embree", marks=pytest.mark.skipif(
    not __import__("importlib").util.find_spec("embreex"), reason="embreex not installed"))]
# NumPy works in float64 throughout; Embree's distances are refined in float64 on the hit
# face's plane, so both meet 1e-6 m on planar faces.
TOL = {"numpy": 1e-6, "embree": 1e-6}


def _unit(v: np.ndarray) -> np.ndarray:
    return v / np.linalg.norm(v, axis=1, keepdims=True)


def _scene_rays(cloud: ls.PointCloud, sc: ls.Scenario) -> tuple[np.ndarray, np.ndarray]:
    """Sensor origin and flown directions of the returns, in the scene frame."""
    pose = sc.sensor.pose
    rot = pose.rotation()
    dirs = rot.apply(_unit(cloud.xyz_true))
    return np.asarray(pose.position_m, float), dirs


@pytest.mark.parametrize("backend", BACKENDS)
def test_plane_hits_equal_ray_plane_intersection(backend):
    # plate of 40 m x 40 m, normal tilted 25 deg about Z, 12 m ahead of a tilted sensor
    plate_rot = Rotation.from_euler("z", 25, degrees=True)
    sc = scenario({"model": "plate", "options": {"size_m": [40.0, 40.0]}},
                  {"position_m": [12.0, 0.5, -0.3], "quaternion_xyzw": plate_rot.as_quat().tolist()},
                  sensor_pose={"position_m": [0.2, -0.1, 0.05], "euler_deg": [3.0, -4.0, 2.0]},
                  backend=backend)
    cloud = ls.simulate(sc)
    assert len(cloud) == cloud.frame.rays_emitted  # the plate fills the FOV
    origin, dirs = _scene_rays(cloud, sc)
    normal = plate_rot.apply([1.0, 0.0, 0.0])
    point = np.array([12.0, 0.5, -0.3])
    expected = (point - origin) @ normal / (dirs @ normal)
    np.testing.assert_allclose(cloud["range_true"], expected, rtol=0, atol=TOL[backend])
    cos_inc = np.abs(dirs @ normal)
    np.testing.assert_allclose(np.cos(cloud["incidence_angle"]), cos_inc, atol=1e-9)


@pytest.mark.parametrize("backend", BACKENDS)
def test_sphere_hits_lie_between_inscribed_polyhedron_and_sphere(backend):
    radius, centre = 3.0, np.array([15.0, 0.0, 0.0])
    sc = scenario({"model": "sphere", "options": {"radius_m": radius, "subdivisions": 5}},
                  {"position_m": centre.tolist()}, backend=backend)
    cloud = ls.simulate(sc)
    origin, dirs = _scene_rays(cloud, sc)
    # analytic first intersection with the true sphere
    oc = origin - centre
    b = dirs @ oc
    disc = b * b - (oc @ oc - radius ** 2)
    hit_sphere = disc > 0
    assert hit_sphere.all()
    t_sphere = -b - np.sqrt(disc)
    # the icosphere is inscribed: its surface lies between radius*cos(a) and radius, where a is
    # the angular radius of a facet (edge ~ 1.1 * radius / 2**subdivisions)
    sagitta = radius * (1 - np.cos(1.2 / 2 ** 5))
    hits = origin + dirs * cloud["range_true"][:, None]
    dist = np.linalg.norm(hits - centre, axis=1)
    assert np.all(dist <= radius + 1e-9)
    assert np.all(dist >= radius - sagitta)
    assert np.all(cloud["range_true"] >= t_sphere - 1e-9)
    # hit/miss agrees with the true sphere away from the polyhedron's silhouette band
    rays = ls.Simulation(sc).pattern.rays(0.0, sc.scan.duration_s)
    miss_distance = np.linalg.norm(np.cross(rays.direction, centre), axis=1)  # origin at 0
    hit_rays = set(cloud["ray_index"].tolist())
    hit = np.array([k in hit_rays for k in rays.index])
    assert np.all(hit[miss_distance < radius - sagitta])
    assert not np.any(hit[miss_distance > radius])
    assert hit.sum() > 0.05 * len(hit)


@pytest.mark.parametrize("backend", BACKENDS)
def test_box_hits_equal_slab_intersection(backend):
    extents = np.array([2.0, 6.0, 4.0])
    rot = Rotation.from_euler("xyz", [10, 20, 30], degrees=True)
    centre = np.array([9.0, 0.4, -0.2])
    sc = scenario({"model": "box", "options": {"extents_m": extents.tolist()}},
                  {"position_m": centre.tolist(), "quaternion_xyzw": rot.as_quat().tolist()},
                  backend=backend)
    cloud = ls.simulate(sc)
    assert len(cloud) > 100
    origin, dirs = _scene_rays(cloud, sc)
    # slab method in the box frame, independent of the mesh
    o = rot.apply(origin - centre, inverse=True)
    d = rot.apply(dirs, inverse=True)
    with np.errstate(divide="ignore"):
        t1 = (-extents / 2 - o) / d
        t2 = (extents / 2 - o) / d
    t_near = np.minimum(t1, t2).max(axis=1)
    t_far = np.maximum(t1, t2).min(axis=1)
    assert np.all(t_near <= t_far + 1e-9)
    np.testing.assert_allclose(cloud["range_true"], t_near, rtol=0, atol=TOL[backend])


def test_misses_produce_no_points_and_ranges_are_gated():
    # the plate sits beyond the maximum range: nothing detected, and no crash
    from helpers import datasheet

    sc = scenario({"model": "plate", "options": {"size_m": [50.0, 50.0]}},
                  {"position_m": [30.0, 0, 0]}, sheet=datasheet(range_max_m=20.0))
    cloud = ls.simulate(sc)
    assert len(cloud) == 0 and cloud.frame.rays_emitted > 0
    behind = scenario({"model": "plate", "options": {"size_m": [50.0, 50.0]}},
                      {"position_m": [-10.0, 0, 0]})
    assert len(ls.simulate(behind)) == 0


@pytest.mark.skipif(not __import__("importlib").util.find_spec("embreex"),
                    reason="embreex not installed")
def test_backends_agree_on_the_envisat_demo_scene():
    from lidarsim_core.scenario import demo_scenario

    clouds = {b: ls.simulate(demo_scenario(duration_s=0.3, noise=False, backend=b))
              for b in ("numpy", "embree")}
    a, b = clouds["numpy"], clouds["embree"]
    ia, ib = set(a["ray_index"].tolist()), set(b["ray_index"].tolist())
    # hit/miss may differ only for rays grazing an edge: a handful in 30,000
    assert len(ia ^ ib) <= 5, len(ia ^ ib)
    common = np.array(sorted(ia & ib))
    ra = dict(zip(a["ray_index"].tolist(), a["range_true"]))
    rb = dict(zip(b["ray_index"].tolist(), b["range_true"]))
    diff = np.array([ra[k] - rb[k] for k in common])
    assert len(common) > 2000
    # same face and float64-refined distance: agreement far below a micrometre for almost all
    assert np.mean(np.abs(diff) < 1e-6) > 0.999
