"""Benchmark the closed loop: what a step of :class:`lidarsim_core.loop.LoopSession` costs on
top of simulating its frame.

Run from the repository root::

    python benchmarks/bench_loop.py [--steps 40] [--repeat 5]

The scene is ``examples/scenarios/envisat_tumbling_hold.yaml``: a Livox MID-70 30 m ahead of
Envisat tumbling at 2.67 °/s, 0.1 s frames (10,000 pulses each). A session steps ``--steps``
frames, the chaser commanded by an impulse every step (HCW propagation, the attitude law, the
keyframe window); its record is then replayed by a plain scenario run, frame by frame, which
gives the same clouds to the bit. Each frame is run both ways ``--repeat`` times, which of the
two goes first alternating from round to round, and per frame the shortest time of each is
kept (timings on a shared machine are noisy).

It prints:

* ``simulation``: the replay's ``Simulation.run_frame`` per frame, the simulation time of the
  frame (the same poses, rays and bits as the step);
* ``step``: ``LoopSession.step`` per frame;
* ``overhead``: the median over frames of ``step - simulation``, in ms and as a share of
  ``simulation`` (the issue asks for < 10 %); on a loaded machine this difference of two
  noisy times wanders by several per cent from run to run;
* ``loop-only``: the step's own work measured inside it (the time of the step less the time
  spent in the simulation's ``iter_span_chunks`` and ``frame_infos``), a figure that does not
  depend on which frames were faster in which round.
"""

from __future__ import annotations

import argparse
import sys
import tempfile
import time
from pathlib import Path

import numpy as np

ROOT = Path(__file__).resolve().parents[1]
sys.path.insert(0, str(ROOT / "src"))

from lidarsim_core.loop import LoopSession  # noqa: E402
from lidarsim_core.pipeline.simulation import Simulation  # noqa: E402
from lidarsim_core.scenario.load import load_scenario  # noqa: E402

SCENARIO = ROOT / "examples" / "scenarios" / "envisat_tumbling_hold.yaml"


def command(step: int) -> list[float]:
    """A small, varying impulse (m/s, LVLH): the chaser moves in every step."""
    return [1e-3 * np.sin(step), -2e-3, 1e-3 * np.cos(step)]


class _Timed(Simulation):
    """A simulation that adds up the time spent in its scan and metadata calls."""

    inner = 0.0

    def iter_span_chunks(self, *args, **kwargs):  # type: ignore[override]
        t = time.perf_counter()
        chunks = list(super().iter_span_chunks(*args, **kwargs))
        type(self).inner += time.perf_counter() - t
        return iter(chunks)

    def frame_infos(self, *args, **kwargs):  # type: ignore[override]
        t = time.perf_counter()
        out = super().frame_infos(*args, **kwargs)
        type(self).inner += time.perf_counter() - t
        return out


def main() -> None:
    parser = argparse.ArgumentParser(description=__doc__.splitlines()[0])
    parser.add_argument("--steps", type=int, default=40)
    parser.add_argument("--repeat", type=int, default=9)
    args = parser.parse_args()
    sim = _Timed(load_scenario(SCENARIO))
    LoopSession(sim).step()  # build the BVH, compile the kernels
    with tempfile.TemporaryDirectory() as tmp:
        session = LoopSession(sim)
        for j in range(args.steps):
            session.step(0.1, delta_v_m_s=command(j))
        replay = Simulation(load_scenario(session.record(Path(tmp) / "loop.yaml")))
        replay.run_frame(0)
        n = args.steps
        sim_t = np.full(n, np.inf)
        step_t = np.full(n, np.inf)
        own_t = np.full(n, np.inf)
        for round_ in range(args.repeat):
            session = LoopSession(sim)
            for j in range(n):
                # which of the two runs first alternates from round to round
                for first in ((True, False) if round_ % 2 else (False, True)):
                    if first:
                        t = time.perf_counter()
                        replay.run_frame(j)
                        sim_t[j] = min(sim_t[j], time.perf_counter() - t)
                        continue
                    _Timed.inner = 0.0
                    t = time.perf_counter()
                    session.step(0.1, delta_v_m_s=command(j))
                    spent = time.perf_counter() - t
                    step_t[j] = min(step_t[j], spent)
                    own_t[j] = min(own_t[j], spent - _Timed.inner)
    s, st, own = (float(np.median(a)) * 1e3 for a in (sim_t, step_t, own_t))
    over = float(np.median(step_t - sim_t)) * 1e3
    print(f"frames: {n} x 0.1 s MID-70 (10,000 pulses), Envisat tumbling at 30 m; "
          f"median over frames of the best of {args.repeat}")
    print(f"simulation (replay run_frame): {s:8.3f} ms")
    print(f"step (LoopSession.step):       {st:8.3f} ms")
    print(f"overhead (step - simulation):  {over:8.3f} ms = {100 * over / s:5.1f} % "
          f"of the simulation")
    print(f"loop-only (inside the step):   {own:8.3f} ms = {100 * own / s:5.1f} % "
          f"of the simulation")


if __name__ == "__main__":
    main()
