"""The pipeline's pieces and threads change nothing in the output."""

from __future__ import annotations

import threading

import numpy as np
import pytest

from lidarsim_core.pipeline import simulation as pipeline_module
from lidarsim_core.backends.numpy_backend import NumpyBackend
from lidarsim_core.pipeline import Simulation
from lidarsim_core.scenario import demo_scenario
from lidarsim_core.scenario import scenario_from_dict


def _tumbling(backend: str):
    data = demo_scenario(duration_s=0.05, detail="coarse", backend=backend).model_dump(mode="json")
    target = data["targets"][0]
    pose = target.pop("pose")
    target["trajectory"] = {"kind": "tumbling", "position_m": pose["position_m"],
                            "quaternion_xyzw": pose["quaternion_xyzw"],
                            "symmetry_axis": [0, 1, 0], "angular_momentum_axis": [0, 0, -1],
                            "spin_rate_deg_s": 40.0, "precession_rate_deg_s": 30.0}
    return scenario_from_dict(data)


SCENES = {
    "static-numpy": lambda: demo_scenario(duration_s=0.05, detail="coarse", backend="numpy"),
    "static-auto": lambda: demo_scenario(duration_s=0.05, detail="coarse", backend="auto"),
    "tumbling-auto": lambda: _tumbling("auto"),
}


@pytest.mark.parametrize("scene", sorted(SCENES))
def test_threads_pieces_and_chunks_do_not_change_the_cloud(scene, monkeypatch):
    sim = Simulation(SCENES[scene]())
    monkeypatch.setenv("LIDARSIM_THREADS", "1")
    reference = sim.run_frame(0)
    assert len(reference) > 100
    monkeypatch.setenv("LIDARSIM_THREADS", "3")
    monkeypatch.setattr(pipeline_module, "PIECE_RAYS", 701)
    for chunk in (None, 1999):
        cloud = sim.run_frame(0, chunk)
        for name, column in reference.columns.items():
            np.testing.assert_array_equal(cloud[name], column, err_msg=f"{name}, chunk {chunk}")
    # iter_chunks still yields one dictionary per chunk of emitted rays
    sizes = [len(c["ray_index"]) for c in sim.iter_chunks(0, 1999)]
    assert len(sizes) == 3 and sum(sizes) == len(reference)


class _SingleThreaded(NumpyBackend):
    thread_safe = False
    seen: set[int] = set()

    def intersect(self, prepared, origins, directions):
        self.seen.add(threading.get_ident())
        return super().intersect(prepared, origins, directions)


def test_backend_that_is_not_thread_safe_is_called_from_one_thread(monkeypatch):
    sim = Simulation(demo_scenario(duration_s=0.05, detail="coarse", backend="numpy"))
    sim.backend = _SingleThreaded()
    monkeypatch.setenv("LIDARSIM_THREADS", "4")
    monkeypatch.setattr(pipeline_module, "PIECE_RAYS", 500)
    sim.run_frame(0)
    assert _SingleThreaded.seen == {threading.get_ident()}
