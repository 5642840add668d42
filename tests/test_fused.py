"""The compiled fast path of the seed paper's model (lidarsim_core.pipeline.fused) gives the
general path's point record bit for bit, and only runs where it applies.

Each scene runs on one Simulation twice, with its fast path and with ``sim.fused = None`` (the
NumPy stages of lidarsim_core.pipeline.cast and .stages), and every column must be identical in
dtype and bytes; the inverse normal CDF of the kernels is compared with SciPy's.
"""

from __future__ import annotations

import os
from pathlib import Path

import numpy as np
import pytest

from lidarsim_core.noise.base import NoiseModel
from lidarsim_core.noise.rng import UNIFORM_BITS, ray_normals, stream_key
from lidarsim_core.pipeline import Simulation
from lidarsim_core.pipeline.fused import FusedPath
from lidarsim_core.plugins.manager import get_registry
from lidarsim_core.plugins.registry import Registry
from lidarsim_core.scenario import demo_scenario, load_scenario, scenario_from_dict

pytest.importorskip("numba", reason="the fast path is made of the compiled kernels")
pytestmark = pytest.mark.skipif(os.environ.get("LIDARSIM_KERNELS", "").strip().lower() == "numpy",
                                reason="LIDARSIM_KERNELS=numpy: the general path only")
EXAMPLES = Path(__file__).resolve().parents[1] / "examples" / "scenarios"


def _demo(**changes) -> dict:
    data = demo_scenario(duration_s=0.1, detail="coarse").model_dump(mode="json")
    data.update(changes)
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


def _tumbling_close() -> dict:
    data = _demo()
    data["targets"][0].pop("pose")
    data["targets"][0]["trajectory"] = {
        "kind": "tumbling", "position_m": [12.0, 0.0, 0.0], "symmetry_axis": [0, 1, 0],
        "angular_momentum_axis": [0, 1, 0], "spin_rate_deg_s": 20.0}  # a flat spin
    data["scan"]["body_frame_truth"] = True
    return data


def _suite(name: str, duration: float):
    from lidarsim_core.bench.suite import SUITE

    return scenario_from_dict(SUITE[name][1](duration), source=f"<{name}>")


SCENES = {
    "demo": lambda: scenario_from_dict(_demo()),
    "demo-numpy-backend": lambda: scenario_from_dict(_demo(backend={"name": "numpy"})),
    "chain-of-two-angular-errors-and-ranges": lambda: scenario_from_dict(_demo(noise=[
        {"name": "range", "options": {"sigma_m": 0.05}},
        {"name": "angular", "options": {"sigma_deg": 0.3}},
        {"name": "angular"}, {"name": "range"}])),
    "systematic-and-quantised-ranges": lambda: scenario_from_dict(_demo(noise=[
        {"name": "angular"}, {"name": "range"},
        {"name": "range_systematic", "options": {"bias_m": 0.013, "scale": 2e-4}},
        {"name": "range_quantisation", "options": {"step_m": 0.004, "offset_m": 0.001}}])),
    "no-noise": lambda: scenario_from_dict(_demo(noise=[])),
    "zero-sigma": lambda: scenario_from_dict(_demo(noise=[
        {"name": "angular", "options": {"sigma_deg": 0.0}}, {"name": "range"}])),
    "two-targets-moving-sensor": lambda: scenario_from_dict(_two_targets_moving_sensor()),
    "tumbling-body-frame-truth": lambda: scenario_from_dict(_tumbling_close()),
    "tumbling-hold": lambda: load_scenario(EXAMPLES / "envisat_tumbling_hold.yaml"),
    "frozen-risley": lambda: scenario_from_dict(_demo(
        sensor={"datasheet": "livox-mid70", "pose": {"position_m": [0, 0, 0]}},
        scan={"duration_s": 0.05, "motion": "frozen"})),
    "suite-two-targets": lambda: _suite("two-targets", 0.05),
    "suite-tumbling-rose": lambda: _suite("tumbling-rose", 0.05),
    "suite-flash": lambda: _suite("flash-256", 0.05),
    # the Ziggurat's normals (another named stream) are drawn by the kernels too
    "ziggurat-demo": lambda: scenario_from_dict(_demo(normals="ziggurat")),
    "ziggurat-chain": lambda: scenario_from_dict(_demo(normals="ziggurat", noise=[
        {"name": "range", "options": {"sigma_m": 0.05}},
        {"name": "angular", "options": {"sigma_deg": 0.3}},
        {"name": "angular"}, {"name": "range"},
        {"name": "range_quantisation", "options": {"step_m": 0.004}}])),
    "ziggurat-two-targets-moving-sensor": lambda: scenario_from_dict(
        dict(_two_targets_moving_sensor(), normals="ziggurat")),
    "ziggurat-tumbling": lambda: scenario_from_dict(dict(_tumbling_close(), normals="ziggurat")),
}


def _assert_same(fast, general) -> None:
    assert list(fast.columns) == list(general.columns)
    for name, column in general.columns.items():
        mine = np.asarray(fast[name])
        assert mine.dtype == column.dtype, name
        np.testing.assert_array_equal(mine, column, err_msg=name)
        assert mine.tobytes() == np.asarray(column).tobytes(), name  # -0.0, NaN bits too


@pytest.mark.parametrize("scene", sorted(SCENES))
def test_fast_path_equals_the_general_path(scene):
    sim = Simulation(SCENES[scene]())
    assert sim.fused is not None
    fast = sim.run_frame(0)
    sim.fused = None
    general = sim.run_frame(0)
    assert len(general) > 50
    _assert_same(fast, general)


def _embree_binding() -> bool:
    from lidarsim_core.backends.embree_backend import binding_status

    return binding_status()[0]


def test_the_cast_runs_in_the_compiled_loop_with_the_embree_binding_only():
    """Embree through its binding hands the fast path a compiled cast; the NumPy backend
    does not (its cast stays ``backend.cast``)."""
    embree = Simulation(scenario_from_dict(_two_targets_moving_sensor()))
    numpy_backend = Simulation(scenario_from_dict(_demo(backend={"name": "numpy"})))
    assert numpy_backend.fused.compiled is None
    if not _embree_binding():
        pytest.skip("the Embree 4 binding does not load here")
    handles = embree.fused.compiled
    assert handles is not None and len(handles) == 2
    assert all(h.width in (1, 4, 8, 16) and h.scene != 0 and h.intersect != 0 for h in handles)


@pytest.mark.parametrize("scene", ["two-targets-moving-sensor", "tumbling-body-frame-truth",
                                   "suite-flash", "ziggurat-chain"])
@pytest.mark.parametrize(("chunk", "threads"), [(1000, "1"), (None, "2")])
def test_the_in_loop_cast_equals_the_backends_cast(monkeypatch, scene, chunk, threads):
    """The cast inside the compiled loop (body rays, Embree packets, refinement, closest
    target) gives the bits of the fast path that casts through ``backend.cast``, across
    chunks (1000: not a multiple of the packet width) and threads."""
    if not _embree_binding():
        pytest.skip("the Embree 4 binding does not load here")
    sim = Simulation(SCENES[scene]())
    assert sim.fused.compiled is not None
    monkeypatch.setenv("LIDARSIM_THREADS", "1")
    sim.fused._compiled = None  # through backend.cast
    by_backend = sim.run_frame(0)
    sim.fused._compiled = False  # asked again: the compiled loop
    monkeypatch.setenv("LIDARSIM_THREADS", threads)
    in_loop = sim.run_frame(0, chunk_rays=chunk)
    assert sim.fused.compiled is not None
    assert len(in_loop) > 50
    _assert_same(in_loop, by_backend)


@pytest.mark.parametrize(("chunk", "threads"), [(997, "1"), (4096, "2"), (None, "3")])
@pytest.mark.parametrize("normals", ["inverse_cdf", "ziggurat"])
def test_fast_path_is_independent_of_chunks_and_threads(monkeypatch, chunk, threads, normals):
    sim = Simulation(scenario_from_dict(dict(_two_targets_moving_sensor(), normals=normals)))
    fused, sim.fused = sim.fused, None
    monkeypatch.setenv("LIDARSIM_THREADS", "1")
    general = sim.run_frame(0)
    sim.fused = fused
    monkeypatch.setenv("LIDARSIM_THREADS", threads)
    _assert_same(sim.run_frame(0, chunk_rays=chunk), general)


def test_inverse_normal_cdf_is_scipys_to_the_bit():
    from scipy.special import ndtri as scipy_ndtri

    from lidarsim_core.kernels.fused import ndtri, ndtri_block, normals

    key = stream_key(7, 3, "noise.0.angular")
    index = np.arange(0, 3_000_000, 7, dtype=np.int64)
    np.testing.assert_array_equal(normals(key, index, 2), ray_normals(7, 3, "noise.0.angular",
                                                                       index, 2))
    step = 2.0 ** -UNIFORM_BITS
    edges = np.concatenate([(np.arange(2000) + 0.5) * step, 1.0 - (np.arange(2000) + 0.5) * step,
                            np.exp(-np.linspace(0.0, 36.0, 20001)),
                            np.nextafter(np.exp(-2.0), [0.0, 1.0]),
                            1.0 - np.nextafter(np.exp(-2.0), [0.0, 1.0])])
    edges = edges[(edges > 0) & (edges < 1)]
    mine = np.array([ndtri(u) for u in edges])
    assert mine.tobytes() == scipy_ndtri(edges).tobytes()
    # the block version (the central branch vectorised, the tails gathered), in blocks of
    # every length around the kernels' block and shuffled so that tails and centre mix
    shuffled = np.random.default_rng(5).permutation(edges)
    for length in (1, 255, 256, 257, len(shuffled)):
        out = np.full(length, np.nan)
        ndtri_block(shuffled[:length], out, length)
        assert out.tobytes() == scipy_ndtri(shuffled[:length]).tobytes()


class _Wobble(NoiseModel):
    """A third-party range error."""

    name = "wobble"

    def perturb_returns(self, returns, ctx):
        returns.range_measured = returns.range_measured + 0.01
        return returns


def test_third_party_models_beam_and_detection_take_the_general_path(monkeypatch):
    registry = Registry({kind: dict(table) for kind, table in get_registry().entries.items()})
    registry.add("noise_model", "wobble", _Wobble, "tests")
    third_party = Simulation(scenario_from_dict(_demo(noise=[{"name": "angular"},
                                                             {"name": "wobble"}])), registry)
    assert third_party.fused is None
    ranges = third_party.run_frame(0)["range"]
    third_party.noise.pop()
    third_party.fused = FusedPath.for_context(third_party.context, third_party.stages)
    assert third_party.fused is not None
    np.testing.assert_array_equal(ranges, third_party.run_frame(0)["range"] + 0.01)

    subclass = _demo(noise=[{"name": "angular_point"}, {"name": "range"}])
    assert Simulation(scenario_from_dict(subclass)).fused is None
    growing = _demo(noise=[{"name": "angular"}, {"name": "range_growing"}])
    assert Simulation(scenario_from_dict(growing)).fused is None
    beam = _demo()
    beam["sensor"]["beam"] = {"sub_rays": 9, "divergence_deg": [0.8, 0.8]}
    beam["sensor"]["returns"] = {"range_resolution_m": 0.3}
    assert Simulation(scenario_from_dict(beam)).fused is None
    detection = _demo()
    detection["sensor"]["detection"] = {}
    assert Simulation(scenario_from_dict(detection)).fused is None
    false_alarms = _demo(noise=[{"name": "range"},
                                {"name": "false_alarms", "options": {"rate_hz": 1e5}}])
    assert Simulation(scenario_from_dict(false_alarms)).fused is None
    monkeypatch.setenv("LIDARSIM_KERNELS", "numpy")
    assert Simulation(scenario_from_dict(_demo())).fused is None


def test_empty_and_small_pieces_give_the_general_columns():
    from lidarsim_core.pipeline.cast import process_piece
    from lidarsim_core.pipeline.posing import with_piece_poses

    sim = Simulation(scenario_from_dict(_two_targets_moving_sensor()))
    contexts = sim.context.noise_contexts(0)
    rays = with_piece_poses(sim.context, sim.pattern.rays_for_indices(np.arange(0, 64)), 0.0)
    for batch in (rays.take(np.array([], dtype=np.int64)), rays):
        fast = sim.fused.process(batch, contexts, 0.0)
        general = process_piece(sim.context, sim.stages, batch, contexts, 0.0, 0)
        assert list(fast) == list(general)
        for name, column in general.items():
            assert fast[name].dtype == column.dtype, name
            assert fast[name].tobytes() == np.asarray(column).tobytes(), name


def test_without_the_binding_the_fast_path_casts_through_embreex(monkeypatch):
    """An Embree backend whose binding cannot load gives no compiled cast: the fast path then
    casts through ``backend.cast`` (embreex), with the general path's bits."""
    from collections import OrderedDict

    from lidarsim_core.backends import embree4
    from lidarsim_core.backends.embree_backend import EmbreeBackend
    from lidarsim_core.base.errors import BackendError

    def refuse():
        raise BackendError("the Embree library x is version 4.9.0; its layout is unknown")

    monkeypatch.setattr(embree4, "load", refuse)
    monkeypatch.setattr(EmbreeBackend, "_prepared", OrderedDict())  # prepare afresh
    sim = Simulation(scenario_from_dict(_two_targets_moving_sensor()))
    assert sim.fused is not None and sim.fused.compiled is None
    fast = sim.run_frame(0)
    sim.fused = None
    general = sim.run_frame(0)
    assert len(general) > 50
    _assert_same(fast, general)
