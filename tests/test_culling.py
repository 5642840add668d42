"""Culling pulses that cannot reach a target changes no result (lidarsim_core.pipeline.cull).

Each scene runs twice on the same Simulation, with its culler and with ``culler = None``
(every pulse cast), and every column of the point record must be identical.
"""

from __future__ import annotations

from pathlib import Path

import numpy as np
import pytest

from lidarsim_core.noise.base import NoiseModel
from lidarsim_core.pipeline import Simulation
from lidarsim_core.pipeline.cull import PulseCuller, cull_tree
from lidarsim_core.scenario import demo_scenario
from lidarsim_core.scenario import load_scenario, scenario_from_dict

pytest.importorskip("numba", reason="culling runs with the compiled kernels (extra 'fast')")
EXAMPLES = Path(__file__).resolve().parents[1] / "examples" / "scenarios"


def _demo(**changes) -> dict:
    data = demo_scenario(duration_s=0.1, detail="coarse", backend="numpy").model_dump(
        mode="json")
    for key, value in changes.items():
        section, _, field = key.partition("__")
        if field:
            data[section][field] = value
        else:
            data[section] = value
    return data


def _wide_angular_error() -> dict:
    return _demo(noise=[{"name": "angular", "options": {"sigma_deg": 1.5}}, {"name": "range"}])


def _beam_and_returns() -> dict:
    data = _demo()
    data["sensor"]["beam"] = {"sub_rays": 9, "divergence_deg": [0.8, 0.8]}
    data["sensor"]["detection"] = {}
    data["sensor"]["returns"] = {"mode": "multi", "range_resolution_m": 0.3}
    return data


def _two_targets_moving_sensor() -> dict:
    data = _demo()
    data["sensor"].pop("pose")
    data["sensor"]["trajectory"] = {"kind": "constant_velocity", "position_m": [0, 0, 0],
                                    "velocity_m_s": [0.5, 2.0, -1.0],
                                    "angular_velocity_deg_s": [0, 3.0, 6.0]}
    data["targets"].append({"name": "box", "mesh": {"model": "box", "options": {
        "extents_m": [2.0, 2.0, 2.0]}}, "pose": {"position_m": [12.0, -6.0, 1.0]}})
    return data


def _spinning_all_around() -> dict:
    """A 360° scanner among boxes beside, behind, above and across it: every face of the cube
    map, and a box straddling the sensor's planes (one pose: the cube-map path)."""
    data = _demo(sensor={"datasheet": "velodyne-vlp16", "pose": {"position_m": [0, 0, 0]}},
                 scan={"duration_s": 0.1})
    data["targets"] = [
        {"name": name, "mesh": {"model": "box", "options": {"extents_m": extents}},
         "pose": {"position_m": position, "euler_deg": [0, 0, yaw]}}
        for name, extents, position, yaw in [
            ("beside", [2, 2, 2], [0, 6, 0], 0), ("behind", [1, 3, 2], [-8, 0, 0.5], 30),
            ("across", [12, 1, 1], [0, -4, 0], 10), ("above", [4, 4, 1], [1, 1, 5], 0)]]
    return data


def _light_in_orbit() -> dict:
    """Multipath ghosts off a mirror-like panel, a saturating receiver and the Sun: a bounce
    starts from a direct hit, a shadow ray from a hit, so culled pulses (which hit nothing)
    can have neither."""
    from lidarsim_core.report.light import ghost_scenario

    data = ghost_scenario(0.05).model_dump(mode="json")
    data["sensor"]["receiver"] = {"saturation_signal": 30.0, "range_walk": True}
    data["sun"] = {"direction": [-0.6, 0.3, 0.74], "blinding_angle_deg": 5.0}
    return data


SCENES = {
    "light-in-orbit": lambda: scenario_from_dict(_light_in_orbit()),
    "spinning-all-around": lambda: scenario_from_dict(_spinning_all_around()),
    "demo": lambda: scenario_from_dict(_demo()),
    "wide-angular-error": lambda: scenario_from_dict(_wide_angular_error()),
    "beam-detection-multi-return": lambda: scenario_from_dict(_beam_and_returns()),
    "two-targets-moving-sensor": lambda: scenario_from_dict(_two_targets_moving_sensor()),
    "tumbling-hold": lambda: load_scenario(EXAMPLES / "envisat_tumbling_hold.yaml"),
    "flyaround": lambda: load_scenario(EXAMPLES / "flyaround_50m.yaml"),
    "frozen-risley": lambda: scenario_from_dict(_demo(
        sensor={"datasheet": "livox-mid70", "pose": {"position_m": [0, 0, 0]}},
        scan={"duration_s": 0.05, "motion": "frozen"})),
    # the benchmark's realistic scenes: per-ray target poses seen through the Risley prisms,
    # a spinning scanner and a Risley sensor both moving and turning, beam divergence
    "tumbling-risley": lambda: _suite("tumbling-risley", 0.05),
    "vlp16-circling": lambda: _suite("vlp16-circling-15m", 0.15),
    "flyaround-risley": lambda: _suite("flyaround-50m", 0.05),
    "torque-free-fast-spin": lambda: scenario_from_dict(_torque_free()),
}


def _suite(name: str, duration: float):
    from lidarsim_core.bench.suite import SUITE

    return scenario_from_dict(SUITE[name][1](duration), source=f"<{name}>")


def _torque_free() -> dict:
    """A triaxial body spinning fast (30 °/s) and close: poses change a lot within a piece."""
    data = _demo(scan={"duration_s": 0.1})
    data["targets"][0].pop("pose")
    data["targets"][0]["trajectory"] = {
        "kind": "torque_free", "position_m": [12, 0, 0], "inertia_kg_m2": [17000, 124000, 129000],
        "angular_velocity_deg_s": [20, 5, 30], "centre_of_mass_m": [0, 0, 2]}
    return data


@pytest.mark.parametrize("scene", sorted(SCENES))
def test_culling_changes_nothing(scene):
    sim = Simulation(SCENES[scene]())
    assert sim.culler is not None
    culled = sim.run_frame(0)
    sim.culler = None
    every_pulse = sim.run_frame(0)
    assert len(every_pulse) > 50
    assert culled.columns.keys() == every_pulse.columns.keys()
    for name, column in every_pulse.columns.items():
        np.testing.assert_array_equal(culled[name], column, err_msg=name)


def test_culling_drops_most_pulses_that_miss():
    sim = Simulation(demo_scenario(duration_s=0.2, detail="medium"))
    k0, k1 = sim.frame_rays(0)
    batch = sim.pattern.rays_for_indices(np.arange(k0, k1))
    kept = sim.culler.keep(sim.context, batch, 0.0)
    hits = len(sim.run_frame(0))
    # 11 % of the pulses hit Envisat; the culler keeps them all and not many more
    assert hits <= len(kept) < 0.35 * len(batch)


def test_a_still_scene_culls_with_every_leaf_and_a_moving_one_with_fewer_boxes(monkeypatch):
    """A still scene's cube map (kept for every frame) is made of the tree's leaves and keeps
    fewer pulses than one made of the boxes MOVING_GRID_LEVELS down, which a map made per
    piece uses; both keep every pulse that hits (test_culling_changes_nothing)."""
    from lidarsim_core.pipeline import cull as cull_module

    sim = Simulation(demo_scenario(duration_s=0.2, detail="medium"))
    k0, k1 = sim.frame_rays(0)
    batch = sim.pattern.rays_for_indices(np.arange(k0, k1))
    deep = len(sim.culler.keep(sim.context, batch, 0.0))
    levels = []
    original = PulseCuller._grid

    def spy(self, rotations, origins, grows, trees, depth):  # noqa: ANN001, ANN202
        levels.append(depth)
        return original(self, rotations, origins, grows, trees, depth)

    monkeypatch.setattr(PulseCuller, "_grid", spy)
    monkeypatch.setattr(cull_module, "CULL_TREE_LEVELS", cull_module.MOVING_GRID_LEVELS)
    shallow_culler = PulseCuller(sim.culler.margin_rad)
    shallow = len(shallow_culler.keep(sim.context, batch, 0.0))
    assert levels == [cull_module.MOVING_GRID_LEVELS]
    hits = len(sim.run_frame(0))
    assert hits <= deep < 0.95 * shallow


def test_margin_covers_the_largest_possible_draw_and_the_beam():
    sim = Simulation(scenario_from_dict(_wide_angular_error()))
    from lidarsim_core.noise.rng import MAX_ABS_NORMAL

    assert sim.culler.margin_rad == pytest.approx(
        np.sqrt(2) * MAX_ABS_NORMAL * np.radians(1.5), rel=1e-5)
    beam = Simulation(scenario_from_dict(_beam_and_returns()))
    assert beam.culler.margin_rad > np.sqrt(2) * MAX_ABS_NORMAL * np.radians(0.1)


def test_no_culling_for_models_it_cannot_bound_or_false_alarms():
    class Wobble(NoiseModel):
        name = "wobble"

        def perturb_rays(self, directions, ray_index, ctx):
            return directions[:, [0, 2, 1]]

    sim = Simulation(scenario_from_dict(_demo()))
    sim.noise.append(Wobble())
    assert PulseCuller.for_context(sim.context) is None
    data = _demo(noise=[{"name": "angular"}, {"name": "range"}, {"name": "false_alarms",
                                                                  "options": {"rate_hz": 1e5}}])
    assert Simulation(scenario_from_dict(data)).culler is None


def test_no_culling_without_the_kernels(monkeypatch):
    monkeypatch.setenv("LIDARSIM_KERNELS", "numpy")
    assert Simulation(scenario_from_dict(_demo())).culler is None


def test_cull_tree_encloses_every_triangle_and_children_sit_in_parents():
    mesh = Simulation(demo_scenario(duration_s=0.01, detail="medium")).targets[0].mesh
    lo, hi, child, _ = cull_tree(mesh)
    assert child[0] >= 0 and (child >= -1).all() and len(lo) > 16
    leaves = np.flatnonzero(child < 0)
    tri = mesh.triangles
    inside = np.zeros(len(tri), dtype=bool)
    for leaf in leaves:
        inside |= ((tri.min(axis=1) >= lo[leaf]) & (tri.max(axis=1) <= hi[leaf])).all(axis=1)
    assert inside.all()
    for node in np.flatnonzero(child >= 0):
        for c in (child[node], child[node] + 1):
            assert (lo[c] >= lo[node]).all() and (hi[c] <= hi[node]).all()


def _tree_node_by_node(triangles: np.ndarray, levels: int, fewest: int) -> tuple:
    """The tree as ``cull_tree`` defines it, one node at a time from a breadth-first queue:
    a node's box bounds its triangles; a node of at least ``2 * fewest`` triangles above
    ``levels`` is split at the median of its box's longest axis (a stable sort of the
    triangles' centres along it), its children consecutive."""
    tri_lo, tri_hi = triangles.min(axis=1), triangles.max(axis=1)
    lo, hi, child, depth, queue = [], [], [], [], [(np.arange(len(triangles)), 0)]
    while queue:
        group, level = queue.pop(0)
        lo.append(tri_lo[group].min(axis=0))
        hi.append(tri_hi[group].max(axis=0))
        depth.append(level)
        if level == levels or len(group) < 2 * fewest:
            child.append(-1)
            continue
        child.append(len(lo) + len(queue))
        axis = (hi[-1] - lo[-1]).argmax()
        order = np.argsort(tri_lo[group, axis] + tri_hi[group, axis], kind="stable")
        half = len(group) // 2
        queue += [(group[order[:half]], level + 1), (group[order[half:]], level + 1)]
    return np.array(lo), np.array(hi), np.array(child), np.array(depth)


def test_cull_tree_is_the_node_by_node_tree():
    """The level-at-a-time build gives the tree of its definition, node for node, on Envisat,
    random meshes of sizes around the split threshold, and meshes full of ties (equal
    centres keep their order, as a stable sort does)."""
    from types import SimpleNamespace

    from lidarsim_core.pipeline.cull import CULL_TREE_LEVELS, MIN_BOX_TRIANGLES, _build_tree

    rng = np.random.default_rng(7)
    grid = np.stack(np.meshgrid(np.arange(12), np.arange(9), np.arange(3)), -1).reshape(-1, 3)
    triangle = np.array([[0, 0, 0], [1, 0, 0], [0, 1, 0]])
    meshes = [Simulation(demo_scenario(duration_s=0.01, detail="medium")).targets[0].mesh.triangles,
              (grid[:, None, :] + triangle[None]).astype(np.float64), np.zeros((40, 3, 3))]
    meshes += [rng.normal(size=(n, 3, 3)) for n in (1, 15, 16, 17, 33, 1000, 4099)]
    for triangles in meshes:
        built = _build_tree(SimpleNamespace(triangles=triangles))
        expected = _tree_node_by_node(triangles, CULL_TREE_LEVELS, MIN_BOX_TRIANGLES)
        for got, want in zip(built, expected):
            assert got.shape == want.shape and np.array_equal(got, want)
        assert built.child.dtype == built.depth.dtype == np.int64


def _spinning_far() -> dict:
    """Envisat 40 m away spinning at 15 °/s about its long axis, as one 0.3 s piece: the cube
    map of the middle pose needs its boxes grown by the motion."""
    data = _demo(scan={"duration_s": 0.3}, noise=[])  # no angular error to hide the motion
    data["targets"][0].pop("pose")
    data["targets"][0]["trajectory"] = {
        "kind": "constant_velocity", "position_m": [40, 0, 0],
        "euler_deg": [0, 0, 90], "angular_velocity_deg_s": [0, 15.0, 0.0]}
    return data


def _posed_path_only(monkeypatch):
    """Cull on the posed batch (:meth:`PulseCuller.keep`), as for trajectories without rate
    bounds."""
    monkeypatch.setattr(PulseCuller, "keep_before_poses", lambda self, *args, **kwargs: None)


def test_moving_grid_is_used_and_its_motion_growth_is_needed(monkeypatch):
    _posed_path_only(monkeypatch)
    sim = Simulation(scenario_from_dict(_spinning_far()))
    used = []
    original = PulseCuller._moving_grid

    def spy(self, *args):
        grid, too_fast = original(self, *args)
        used.append(grid is not None)
        return grid, too_fast

    monkeypatch.setattr(PulseCuller, "_moving_grid", spy)
    monkeypatch.setenv("LIDARSIM_THREADS", "1")
    culled = sim.run_frame(0, chunk_rays=1_000_000)
    assert used and all(used)
    sim.culler, culler = None, sim.culler
    every_pulse = sim.run_frame(0, chunk_rays=1_000_000)
    for name, column in every_pulse.columns.items():
        np.testing.assert_array_equal(culled[name], column, err_msg=name)
    # without growing the boxes by the motion, pulses that hit are lost
    import lidarsim_core.kernels.cull as kernel_cull

    monkeypatch.setattr(kernel_cull, "motion_bound", lambda *args: 0.0)
    sim.culler = culler
    culler._grids.clear()
    assert len(sim.run_frame(0, chunk_rays=1_000_000)) < len(every_pulse)


def test_culling_before_poses_grows_the_map_by_the_rate_bounds(monkeypatch):
    """The spinning Envisat culled from its rate bounds alone (no pose per pulse): one cube
    map per piece, the points those of casting every pulse, and without the growth by the
    motion pulses that hit are lost."""
    from lidarsim_core.pipeline import cull

    sim = Simulation(scenario_from_dict(_spinning_far()))
    decided = []
    original = PulseCuller.keep_before_poses

    def spy(self, *args, **kwargs):
        rows = original(self, *args, **kwargs)
        decided.append(rows is not None)
        return rows

    monkeypatch.setattr(PulseCuller, "keep_before_poses", spy)
    monkeypatch.setattr(PulseCuller, "_moving_grid", None)  # the posed path is not taken
    monkeypatch.setenv("LIDARSIM_THREADS", "1")
    culled = sim.run_frame(0, chunk_rays=1_000_000)
    assert decided and all(decided)
    sim.culler, culler = None, sim.culler
    every_pulse = sim.run_frame(0, chunk_rays=1_000_000)
    for name, column in every_pulse.columns.items():
        np.testing.assert_array_equal(culled[name], column, err_msg=name)
    monkeypatch.setattr(cull, "_strays", lambda *args: 0.0)
    sim.culler = culler
    culler._grids.clear()
    assert len(sim.run_frame(0, chunk_rays=1_000_000)) < len(every_pulse)


def test_tumbling_target_near_a_still_sensor_uses_cube_maps(monkeypatch):
    """Envisat tumbling 31 m ahead of a still sensor, 15 s in, when its bounding box is nearer
    than its own size: every piece is culled by cube maps (none pulse by pulse), and the
    points are those of casting every pulse."""
    from lidarsim_core.bench.suite import SUITE

    sim = Simulation(scenario_from_dict(SUITE["tumbling-fixed-rose"][1](0.2)))
    per_pulse = []
    original = PulseCuller._per_pulse

    def spy(self, *args):
        per_pulse.append(True)
        return original(self, *args)

    monkeypatch.setattr(PulseCuller, "_per_pulse", spy)
    culled = sim.run_frame(0)
    assert not per_pulse
    sim.culler = None
    every_pulse = sim.run_frame(0)
    assert len(every_pulse) > 1000
    for name, column in every_pulse.columns.items():
        np.testing.assert_array_equal(culled[name], column, err_msg=name)


def test_fast_targets_get_a_cube_map_per_block(monkeypatch):
    """The debris box of the two-target scene moves by more than a tenth of its size within
    a piece: the piece is halved (at most twice) into blocks with maps of their own where the
    motion allows, and nothing changes."""
    from lidarsim_core.pipeline import cull

    _posed_path_only(monkeypatch)
    sim = Simulation(_suite("two-targets", 0.3))
    blocks = []
    original = PulseCuller._moving_blocks

    def spy(self, posed, trees, start, stop, splits=0):
        result = original(self, posed, trees, start, stop, splits)
        if start == 0 and stop == max(len(posed.sensor), *(len(p) for p in posed.targets)):
            blocks.append(result)
        return result

    monkeypatch.setattr(PulseCuller, "_moving_blocks", spy)
    monkeypatch.setenv("LIDARSIM_THREADS", "1")
    culled = sim.run_frame(0, chunk_rays=1_000_000)
    assert blocks and max(len(b) for b in blocks) > 1
    assert max(len(b) for b in blocks) <= 2 ** cull.MAX_MOVING_SPLITS
    assert any(grid is not None for b in blocks for _, _, grid in b)
    sim.culler = None
    every_pulse = sim.run_frame(0, chunk_rays=1_000_000)
    for name, column in every_pulse.columns.items():
        np.testing.assert_array_equal(culled[name], column, err_msg=name)


def test_direction_grid_holds_every_direction_that_meets_a_box():
    """Random boxes beside, across, behind and around the sensor (some straddling the cube
    map's face planes, some a few cm away): every direction whose ray meets a box, found by
    an exact slab test, lies in a set cell; and far boxes leave most cells clear."""
    from scipy.spatial.transform import Rotation

    from lidarsim_core.kernels.cull import cull_by_grid, direction_grid
    from lidarsim_core.pipeline.cull import _CORNERS

    rng = np.random.default_rng(7)
    directions = rng.normal(size=(200_000, 3))
    directions /= np.linalg.norm(directions, axis=1)[:, None]
    checked = 0
    for _ in range(40):
        half = rng.uniform(0.05, 3.0, 3)
        centre = rng.normal(size=3) * rng.uniform(0.5, 12.0)
        rotation = Rotation.from_euler("xyz", rng.uniform(0, 2 * np.pi, 3)).as_matrix()
        if np.all(np.abs(centre @ rotation) < half + 0.02):
            continue  # the sensor inside (or touching) the box: None, tested below
        body = np.where(_CORNERS, half, -half)
        corners = body @ rotation.T + centre
        grid = direction_grid(corners[None], 256)
        assert grid is not None
        # exact slab test in the box's frame: origin -centre, direction R^T d
        o = -centre @ rotation
        d = directions @ rotation
        with np.errstate(divide="ignore", invalid="ignore"):
            a, b = (-half - o) / d, (half - o) / d
        near = np.nanmax(np.minimum(a, b), axis=1).clip(0)
        far = np.nanmin(np.maximum(a, b), axis=1)
        meets = near <= far
        kept = np.zeros(len(directions), bool)
        kept[cull_by_grid(directions, grid)] = True
        assert not (meets & ~kept).any()
        checked += int(meets.sum())
        if np.linalg.norm(centre) > 4 * np.linalg.norm(half):  # a far box: a small map
            assert kept.mean() < 0.5
    assert checked > 1000
    inside = np.where(_CORNERS, 1.0, -1.0)[None] + np.array([0.3, 0, 0])
    assert direction_grid(inside, 64) is None
