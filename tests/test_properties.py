"""Property-based tests (Hypothesis) of the building blocks every point depends on.

* poses and transforms: rotations are orthonormal, inverses round-trip, the pipeline's
  single-pose fast path equals the general one;
* scan patterns (every catalogue sensor): unit directions inside the FOV at any index, and the
  rays of an index set do not depend on how it is cut into chunks or ordered;
* ray backends: random rays against random convex polyhedra agree with an independent
  reference (the ray clipped by the polyhedron's half-spaces, no triangles involved);
* noise models that declare zero mean have zero mean, for any seed, frame and σ.
"""

from __future__ import annotations

import functools
import math

import numpy as np
import pytest
from hypothesis import HealthCheck, assume, given, settings
from hypothesis import strategies as st
from scipy.spatial import ConvexHull
from scipy.spatial.transform import Rotation

from lidarsim_core.geometry.frames import rotate, to_body
from lidarsim_core.geometry.poses import Poses
from lidarsim_core.scenario import PoseConfig

FAST = settings(max_examples=100, deadline=None,
                suppress_health_check=[HealthCheck.too_slow])

finite = st.floats(min_value=-1e4, max_value=1e4, allow_nan=False, allow_infinity=False)
vec3 = st.tuples(finite, finite, finite)
quat = st.tuples(*[st.floats(-1, 1, allow_nan=False)] * 4).filter(
    lambda q: math.fsum(x * x for x in q) > 1e-6)
angles = st.tuples(*[st.floats(-720, 720, allow_nan=False)] * 3)
sequences = st.sampled_from(["xyz", "zyx", "xzx", "XYZ", "ZYX", "ZXZ"])


def _poses(positions: list, quats: list) -> Poses:
    return Poses(np.asarray(positions, dtype=float).reshape(-1, 3),
                 Rotation.from_quat(np.asarray(quats, dtype=float).reshape(-1, 4)))


# ---- poses and transforms ----------------------------------------------------------------
@FAST
@given(st.one_of(st.builds(lambda q: {"quaternion_xyzw": q}, quat),
                 st.builds(lambda a, s: {"euler_deg": a, "euler_sequence": s}, angles,
                           sequences)),
       vec3)
def test_configured_rotations_are_proper_orthonormal(rotation, position):
    pose = PoseConfig(position_m=position, **rotation).to_pose()
    m = pose.as_matrices()[0]
    r = m[:3, :3]
    np.testing.assert_allclose(r @ r.T, np.eye(3), atol=1e-12)
    assert np.linalg.det(r) == pytest.approx(1.0, abs=1e-12)
    np.testing.assert_array_equal(m[3], [0, 0, 0, 1])
    np.testing.assert_array_equal(m[:3, 3], position)


@FAST
@given(st.lists(st.tuples(vec3, quat), min_size=1, max_size=8), st.lists(vec3, min_size=1,
                                                                           max_size=8))
def test_inverse_round_trips(pose_list, point_list):
    n = min(len(pose_list), len(point_list))
    poses = _poses([p for p, _ in pose_list[:n]], [q for _, q in pose_list[:n]])
    points = np.asarray(point_list[:n], dtype=float)
    scale = 1.0 + np.abs(points).max() + np.abs(poses.position).max()
    np.testing.assert_allclose(poses.apply_inverse(poses.apply(points)), points,
                               atol=1e-12 * scale)
    np.testing.assert_allclose(poses.inverse().apply(poses.apply(points)), points,
                               atol=1e-12 * scale)
    np.testing.assert_allclose(poses.rotate_inverse(poses.rotate(points)), points,
                               atol=1e-12 * scale)
    # the inverse's matrices are the inverse matrices
    np.testing.assert_allclose(poses.inverse().as_matrices() @ poses.as_matrices(),
                               np.broadcast_to(np.eye(4), (n, 4, 4)), atol=1e-12 * scale)


@FAST
@given(vec3, quat, vec3, quat, st.lists(vec3, min_size=1, max_size=5))
def test_relative_pose_composes_back(p_a, q_a, p_b, q_b, point_list):
    """a expressed in b's frame, then mapped by b, is a: b ∘ (b⁻¹ ∘ a) = a."""
    a, b = _poses([p_a], [q_a]), _poses([p_b], [q_b])
    rel = a.relative_to(b)
    points = np.asarray(point_list, dtype=float)
    scale = 1.0 + np.abs(points).max() + np.abs(a.position).max() + np.abs(b.position).max()
    np.testing.assert_allclose(b.apply(rel.apply(points)), a.apply(points), atol=1e-11 * scale)


@FAST
@given(vec3, quat, st.lists(vec3, min_size=1, max_size=20))
def test_single_pose_fast_path_equals_the_general_transform(position, q, vectors):
    """The pipeline's one-matrix path (chunks.rotate, chunks.to_body) equals Poses' methods."""
    pose = _poses([position], [q])
    v = np.asarray(vectors, dtype=float)
    scale = 1.0 + np.abs(v).max() + np.abs(pose.position).max()
    np.testing.assert_allclose(rotate(pose, v), pose.rotate(v), atol=1e-12 * scale)
    np.testing.assert_allclose(rotate(pose, v, inverse=True), pose.rotate_inverse(v),
                               atol=1e-12 * scale)
    np.testing.assert_allclose(to_body(pose, v), pose.apply_inverse(v), atol=1e-11 * scale)


# ---- scan patterns -----------------------------------------------------------------------
def _sensor_names() -> list[str]:
    from lidarsim_core.plugins import get_registry

    return get_registry().names("sensor")


@functools.lru_cache(maxsize=None)
def _pattern(name: str):
    from lidarsim_core.plugins.resolve import get_sensor, pattern_for

    return pattern_for(get_sensor(name))


@settings(max_examples=150, deadline=None, suppress_health_check=[HealthCheck.too_slow])
@given(st.sampled_from(_sensor_names()), st.integers(0, 10 ** 9), st.integers(1, 1500),
       st.lists(st.integers(0, 1500), max_size=6), st.randoms(use_true_random=False))
def test_patterns_are_unit_inside_fov_and_chunk_invariant(name, start, length, cuts, rnd):
    pattern = _pattern(name)
    index = np.arange(start, start + length, dtype=np.int64)
    whole = pattern.rays_for_indices(index)
    np.testing.assert_array_equal(whole.index, index)
    norms = np.linalg.norm(whole.direction, axis=1)
    np.testing.assert_allclose(norms, 1.0, atol=1e-12)
    assert pattern.inside_fov(whole.direction, 1e-6).all(), name
    np.testing.assert_array_equal(whole.t, pattern.time_of_index(index))
    # any cut of the index range into chunks gives the same rays
    bounds = sorted({0, length, *[c for c in cuts if c < length]})
    parts = [pattern.rays_for_indices(index[a:b]) for a, b in zip(bounds, bounds[1:])]
    for attr in ("t", "direction", "channel"):
        np.testing.assert_array_equal(np.concatenate([getattr(p, attr) for p in parts]),
                                      getattr(whole, attr))
    # and so does any order: a ray depends on its own index only
    order = list(range(length))
    rnd.shuffle(order)
    shuffled = pattern.rays_for_indices(index[order])
    np.testing.assert_array_equal(shuffled.direction, whole.direction[order])
    np.testing.assert_array_equal(shuffled.t, whole.t[order])
    np.testing.assert_array_equal(shuffled.channel, whole.channel[order])


# ---- ray backends against convex polyhedra -----------------------------------------------
def _backends() -> list:
    from lidarsim_core.plugins import get_registry

    out = []
    for entry in get_registry().iter("ray_backend"):
        ok, _ = entry.obj.is_available()
        if ok:
            out.append(pytest.param(entry.name, id=entry.name))
    return out


def clipped_ray(planes: np.ndarray, origins: np.ndarray, dirs: np.ndarray):
    """First crossing of each ray with the convex region ``n·x + c <= 0`` (Cyrus–Beck).

    Returns the distance (NaN on a miss), the index of the plane crossed and a margin: how far
    (in length) the decision is from changing (grazing rays and rays near an edge have a small
    margin and are not compared).
    """
    n, c = planes[:, :3], planes[:, 3]
    denom = dirs @ n.T                                   # (R, P)
    dist = -(origins @ n.T + c)                          # signed distance inside each plane
    with np.errstate(divide="ignore", invalid="ignore"):
        t = dist / denom
    entering = denom < 0
    t_in = np.where(entering, t, -np.inf)
    t_out = np.where(denom > 0, t, np.inf)
    enter = t_in.max(axis=1)
    exit_ = t_out.min(axis=1)
    inside = (dist >= 0).all(axis=1)
    first = np.where(inside, exit_, enter)
    plane = np.where(inside, t_out.argmin(axis=1), t_in.argmax(axis=1))
    hit = (enter <= exit_) & (first > 0)
    sorted_in = np.sort(t_in, axis=1)
    sorted_out = np.sort(t_out, axis=1)
    # near an edge: the two best planes give nearly the same crossing; grazing: enter ≈ exit
    edge = np.where(inside, sorted_out[:, 1] - sorted_out[:, 0], sorted_in[:, -1] - sorted_in[:, -2])
    margin = np.minimum(np.abs(exit_ - enter), edge)
    margin = np.where(np.isfinite(margin), margin, np.inf)
    return np.where(hit, first, np.nan), plane, margin


@settings(max_examples=60, deadline=None, suppress_health_check=[HealthCheck.too_slow])
@pytest.mark.parametrize("backend_name", _backends())
@given(seed=st.integers(0, 2 ** 32 - 1), n_points=st.integers(4, 40),
       scale=st.sampled_from([0.05, 1.0, 30.0]), offset=st.sampled_from([0.0, 50.0]))
def test_backends_agree_with_clipping_on_convex_polyhedra(backend_name, seed, n_points, scale,
                                                          offset):
    from lidarsim_core.plugins import get_registry
    from lidarsim_core.scene.mesh import Mesh

    rng = np.random.default_rng(seed)
    centre = np.array([offset, -offset / 2, offset / 3])
    points = centre + scale * rng.normal(size=(n_points, 3))
    try:
        hull = ConvexHull(points)
    except Exception:  # coplanar draws: not a polyhedron
        assume(False)
    assume(hull.volume > 1e-3 * scale ** 3)
    mesh = Mesh.from_arrays(hull.points, hull.simplices, name="hull")
    # rays from a sphere around the hull toward points near it (hits and misses), and from
    # inside the hull (every one hits the surface from within)
    n_rays = 200
    radius = 3 * scale
    outside = centre + radius * _unit(rng.normal(size=(n_rays, 3)))
    aim = centre + 1.2 * scale * rng.normal(size=(n_rays, 3))
    inside = hull.points[hull.vertices].mean(axis=0) + 0.01 * scale * rng.normal(size=(20, 3))
    origins = np.vstack([outside, inside])
    dirs = np.vstack([_unit(aim - outside), _unit(rng.normal(size=(20, 3)))])
    inside_ok = (hull.equations[:, :3] @ inside.T + hull.equations[:, 3:4] < 0).all(axis=0)
    keep = np.concatenate([np.ones(n_rays, bool), inside_ok])
    origins, dirs = origins[keep], dirs[keep]

    backend = get_registry().get("ray_backend", backend_name)()
    hits = backend.cast(mesh, origins, dirs)
    ref, plane, margin = clipped_ray(hull.equations, origins, dirs)
    length = scale + np.abs(centre).max() + radius
    tol = max(backend.distance_rtol, backend.edge_tolerance_rel, 1e-9) * length * 100
    # a backend's declared precision cannot resolve an object much smaller than its tolerance
    assume(tol < 0.01 * scale)
    # the contract ignores hits closer than epsilon_m (docs/backends.md): a crossing about
    # that close to the origin is left out, as one near an edge is
    with np.errstate(invalid="ignore"):
        near = ref < backend.options.epsilon_m + tol
    clear = (margin > tol) & ~near
    assert clear.sum() > 0.5 * len(clear)
    np.testing.assert_array_equal(hits.hit[clear], ~np.isnan(ref[clear]))
    both = clear & hits.hit
    np.testing.assert_allclose(hits.distance[both], ref[both], rtol=0,
                               atol=backend.distance_rtol * length * 10 + 1e-12 * length)
    # the face hit lies in the plane the reference crossed, and its normal is that plane's
    # (up to the sign: the hull's triangles are not consistently oriented)
    cos = np.einsum("ij,ij->i", hits.normal[both], hull.equations[plane[both], :3])
    np.testing.assert_allclose(np.abs(cos), 1.0, atol=1e-4)


def _unit(v: np.ndarray) -> np.ndarray:
    return v / np.linalg.norm(v, axis=1, keepdims=True)


# ---- noise -------------------------------------------------------------------------------
def _returns(rng: np.random.Generator, n: int):
    from lidarsim_core.noise.base import Returns

    d = _unit(rng.normal(size=(n, 3)))
    r = rng.uniform(1.0, 100.0, n)
    return Returns(np.arange(n, dtype=np.int64) * 7 + 3, d, r, r.copy(), d.copy())


def _model(name: str, **options):
    from lidarsim_core.plugins import get_registry

    return get_registry().get("noise_model", name).from_config(options)


def _ctx(seed: int, frame: int, stream: str):
    from lidarsim_core.noise.base import NoiseContext
    from lidarsim_core.plugins.resolve import get_sensor

    return NoiseContext(get_sensor("livox-mid70-rose"), seed, frame, stream)


N_NOISE = 20000


@FAST
@given(st.sampled_from(["range", "range_growing"]), st.integers(0, 2 ** 63 - 1),
       st.integers(0, 10 ** 6), st.floats(1e-4, 1.0))
def test_gaussian_range_errors_have_zero_mean(name, seed, frame, sigma):
    rng = np.random.default_rng(seed % 2 ** 32)
    returns = _returns(rng, N_NOISE)
    model = _model(name, sigma_m=sigma)
    out = model.perturb_returns(returns, _ctx(seed, frame, f"noise.0.{name}"))
    err = out.range_measured - out.range_true
    per_point = model.sigma_at(returns.range_true, _ctx(seed, frame, "")) \
        if name == "range_growing" else np.full(N_NOISE, sigma)
    z = err / per_point
    # standardised errors: mean 0 within 6 standard errors, unit spread
    assert abs(z.mean()) < 6 / math.sqrt(N_NOISE)
    assert z.std() == pytest.approx(1.0, abs=0.05)
    np.testing.assert_array_equal(out.direction_measured, returns.direction_measured)


@FAST
@given(st.integers(0, 2 ** 63 - 1), st.integers(0, 10 ** 6), st.floats(1e-3, 0.5))
def test_angular_error_has_zero_mean_about_both_axes(seed, frame, sigma_deg):
    from lidarsim_core.noise.base import perpendicular_basis

    rng = np.random.default_rng(seed % 2 ** 32)
    d = _unit(rng.normal(size=(N_NOISE, 3)))
    model = _model("angular", sigma_deg=sigma_deg)
    flown = model.perturb_rays(d, np.arange(N_NOISE, dtype=np.int64),
                               _ctx(seed, frame, "noise.0.angular"))
    np.testing.assert_allclose(np.linalg.norm(flown, axis=1), 1.0, atol=1e-12)
    u, v = perpendicular_basis(d)
    sigma = math.radians(sigma_deg)
    for axis in (u, v):
        z = np.einsum("ij,ij->i", flown, axis) / sigma  # small-angle deflection about the axis
        assert abs(z.mean()) < 6 / math.sqrt(N_NOISE)
        assert z.std() == pytest.approx(1.0, abs=0.05)


@FAST
@given(st.integers(0, 2 ** 63 - 1), st.floats(1e-4, 0.1), st.floats(0.0, 1.0))
def test_range_quantisation_error_is_centred_and_bounded(seed, step, offset_fraction):
    rng = np.random.default_rng(seed % 2 ** 32)
    returns = _returns(rng, N_NOISE)
    model = _model("range_quantisation", step_m=step, offset_m=offset_fraction * step)
    out = model.perturb_returns(returns, _ctx(seed, 0, "noise.0.range_quantisation"))
    err = out.range_measured - out.range_true
    assert np.abs(err).max() <= step / 2 * (1 + 1e-9) + 1e-12
    # uniform on [-q/2, q/2]: mean 0, σ = q/√12 (ranges spread over many steps)
    assert abs(err.mean()) < 6 * step / math.sqrt(12 * N_NOISE)
