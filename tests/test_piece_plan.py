"""How a span is cut into pieces for the threads (lidarsim_core.pipeline.balance): on the calling
thread or one piece per thread, whichever measured faster, and at equal costs."""

from __future__ import annotations

import numpy as np
import pytest

from lidarsim_core.pipeline import Simulation
from lidarsim_core.pipeline.balance import (DEAD_BAND, EXPLORE, MIN_SHARE, PROBE_EVERY, PROBE_MOST,
                                           PiecePlan)
from lidarsim_core.scenario import demo_scenario


def _times(bounds: list[float], density) -> list[float]:  # noqa: ANN001
    """Each piece's cost under a cost density on [0, 1] (midpoint rule, fine grid)."""
    x = (np.arange(200_000) + 0.5) / 200_000
    cost = density(x) / len(x)
    return [float(cost[(x >= a) & (x < b)].sum()) for a, b in zip(bounds, bounds[1:])]


@pytest.mark.parametrize("parts", [2, 3, 4])
def test_cuts_converge_to_equal_costs(parts):
    """With a cost density three times higher on the chunk's second half (a flash whose lower
    half hits the target), the cuts move to where the pieces' costs are within the dead band
    of each other, near the closed-form points of the cumulative cost."""
    def density(x):  # noqa: ANN001, ANN202
        return np.where(x < 0.5, 1.0, 3.0)

    balance = PiecePlan()
    for _ in range(40):
        bounds = balance.bounds(parts)
        balance.record(bounds, [t * 1e-2 for t in _times(bounds, density)])
    # cumulative cost C(x) = x on [0, .5], .5 + 3 (x - .5) after; total 2
    want = [c if c <= 0.5 else 0.5 + (c - 0.5) / 3 for c in (2 * j / parts for j in
                                                            range(1, parts))]
    got = balance.bounds(parts)[1:-1]
    np.testing.assert_allclose(got, want, atol=0.04)  # the dead band: ±6 % of a share
    even = _times(PiecePlan().bounds(parts), density)
    costs = _times(balance.bounds(parts), density)
    mean = sum(costs) / parts
    assert max(abs(c - mean) for c in even) > 0.3 * mean  # far off at the start
    assert max(abs(c - mean) for c in costs) <= DEAD_BAND * mean


def test_even_times_leave_even_cuts_and_small_ones_are_ignored():
    balance = PiecePlan()
    assert balance.bounds(2) == [0.0, 0.5, 1.0]
    balance.record([0.0, 0.5, 1.0], [1.0, 1.0 + DEAD_BAND])  # within the dead band
    assert balance.bounds(2) == [0.0, 0.5, 1.0]
    balance.record([0.0, 0.5, 1.0], [1e-6, 9e-6])  # too short to tell
    assert balance.bounds(2) == [0.0, 0.5, 1.0]
    balance.record([0.0, 0.5, 1.0], [1.0, 2.0])
    assert 0.5 < balance.bounds(2)[1] < 0.7
    assert balance.bounds(3) == pytest.approx([0, 1 / 3, 2 / 3, 1])  # another thread count


def test_a_piece_keeps_its_least_share_and_cuts_cover_the_chunk():
    balance = PiecePlan()
    for _ in range(30):  # all the cost in the first piece, whatever its size
        bounds = balance.bounds(2)
        balance.record(bounds, [1.0, 0.0])
    assert balance.bounds(2)[1] == pytest.approx(MIN_SHARE / 2)
    for start, stop in ((0, 10), (5, 6), (100, 65_636)):
        for bounds in ([0, 0.25, 1], [0, 0.5, 0.75, 1], [0, 1e-9, 1]):
            cuts = PiecePlan.cuts(start, stop, bounds)
            assert cuts[0][0] == start and cuts[-1][1] == stop
            assert all(lo < hi for lo, hi in cuts)
            assert all(a[1] == b[0] for a, b in zip(cuts, cuts[1:]))


def test_skewed_cuts_leave_every_column_unchanged(monkeypatch):
    """The cuts only move work between threads: cut anywhere, the frame is the one-thread
    frame bit for bit."""
    sim = Simulation(demo_scenario(duration_s=0.05, detail="coarse"))
    monkeypatch.setenv("LIDARSIM_THREADS", "1")
    reference = sim.run_frame(0)
    monkeypatch.setenv("LIDARSIM_THREADS", "2")
    monkeypatch.setattr(sim._plan, "threaded", lambda: True)
    for cut in (0.25, 0.5, 0.75):
        monkeypatch.setattr(sim._plan, "bounds", lambda parts, cut=cut: [0.0, cut, 1.0])
        cloud = sim.run_frame(0)
        for name, column in reference.columns.items():
            np.testing.assert_array_equal(cloud[name], column, err_msg=f"{name}, cut {cut}")


def test_the_faster_way_is_chosen_and_the_other_tried_now_and_then():
    """Each way in turn (after a first span that only warms the caches) until both were
    measured, then the one with the least seconds per pulse; the other is tried PROBE_EVERY
    spans after the choice, then at spacings that double up to PROBE_MOST while it stays
    slower; a way that becomes slower loses the choice at its next try, and the spacing
    starts again."""
    plan = PiecePlan()
    ways = []

    def span(threads_s: float, caller_s: float) -> bool:
        way = plan.threaded()
        ways.append(way)
        plan.timed(way, threads_s if way else caller_s, 1000)
        return way

    span(9.0, 9.0)  # the first span: on the threads, not recorded
    explored = [span(2e-3, 3e-3) for _ in range(2 * EXPLORE)]
    assert explored == [True, False] * EXPLORE
    spans = 8 * PROBE_MOST
    chosen = [span(2e-3, 3e-3) for _ in range(spans)]
    tries = [i for i, way in enumerate(chosen) if not way]  # spans after the choice
    expected, at, spacing = [], PROBE_EVERY, PROBE_EVERY
    while at < spans:
        expected.append(at)
        at, spacing = at + spacing, min(2 * spacing, PROBE_MOST)
    assert tries == expected
    assert tries[1] - tries[0] == PROBE_EVERY and tries[-1] - tries[-2] == PROBE_MOST
    # the scene shrinks: the calling thread gets faster than the threads, and wins at the
    # next try (within PROBE_MOST spans); the threads are tried again PROBE_EVERY after
    later = [span(2e-3, 1e-3) for _ in range(PROBE_MOST + 2 * PROBE_EVERY)]
    turned = later.index(False)  # the try that turns the choice
    assert turned < PROBE_MOST
    assert later[turned:turned + PROBE_EVERY + 2] == [False] * (PROBE_EVERY + 1) + [True]


def test_the_calling_thread_runs_the_span_when_it_is_faster(monkeypatch):
    """On the calling thread the span is one piece there (no pool thread), and the frame is
    the one-thread frame bit for bit."""
    import threading

    from lidarsim_core.pipeline import simulation as pipeline_module

    sim = Simulation(demo_scenario(duration_s=0.05, detail="coarse"))
    monkeypatch.setenv("LIDARSIM_THREADS", "1")
    reference = sim.run_frame(0)
    monkeypatch.setenv("LIDARSIM_THREADS", "2")
    callers = set()
    culled = pipeline_module.culled_piece

    def spy(*args, **kwargs):  # noqa: ANN002, ANN003, ANN202
        callers.add(threading.get_ident())
        return culled(*args, **kwargs)

    monkeypatch.setattr(pipeline_module, "culled_piece", spy)
    monkeypatch.setattr(sim._plan, "threaded", lambda: False)
    cloud = sim.run_frame(0)
    assert callers == {threading.get_ident()}
    for name, column in reference.columns.items():
        np.testing.assert_array_equal(cloud[name], column, err_msg=name)
