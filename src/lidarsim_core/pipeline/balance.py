"""How a span of pulses is cut into pieces for the threads: on the calling thread or one piece
per thread, whichever the last spans measured faster, and then at equal costs.

**Threads or not.** A piece holds the GIL for its Python steps (the culling's plan, the poses'
set-up, the calls into the kernels, ~0.5 ms a piece of the fast path) and the threads take
turns at it; a frame whose compiled work is small next to that runs faster on one thread:
the VLP-16 circling frame (96,452 pulses, 5 % of them cast) took 2.2 ms on either, the
dataset benchmark's frames of 10,000 pulses 0.96 ms on one thread and 1.39 ms on two, while
the tumbling rose's 100,000 pulses take 4.0 ms on one and 2.5 on two. :class:`PiecePlan`
measures the first spans each way in turn, keeps the seconds per pulse of the last spans run
each way (the least of the last :data:`SAMPLES`), runs the next span the faster way (on the
calling thread no pool thread has to wake), and tries the other way now and then so that the
choice follows a scene that grows or shrinks: :data:`PROBE_EVERY` spans after it chose, then
twice as many after each try that left the choice as it was, up to :data:`PROBE_MOST` (a try
costs the difference of the two ways: in a serial dataset of the tumbling Risley scene the
threads took 1.5-2.3 ms a frame against 0.76-0.9 on the calling thread, and a try every 16
frames cost ~5 % of the run).

**Where to cut.** A piece's cost is not proportional to its pulses. Culling drops most pulses
that miss, and a hit costs the cast three to five times a miss: the two halves of a 256 × 256
flash keep 40 % and 60 % of their pulses and one takes 1.8 times the other's time, so with a
cut in the middle one thread waits for the other during a third of the frame. The plan keeps
the cuts of the last span cut into one piece per thread and moves them halfway toward the
cuts that would have made its pieces take equal times, the cost being taken as even within
each piece, unless the times are within :data:`DEAD_BAND` of each other (the threads' start
and the machine's noise).

Frames of a sequence look alike, so the plan follows the scene; every pulse's result depends
on its own index alone, so no choice of the plan changes an output bit.
"""

from __future__ import annotations

import threading
from collections import deque

#: Least share of a chunk's pulses a piece gets, relative to an even share (the cuts stay
#: where a surprise, e.g. a target entering the other half, costs at most twice an even split).
MIN_SHARE = 0.5
#: Chunks whose pieces together took less than this (s) leave the cuts alone: their times are
#: mostly the threads' start and timer noise.
MIN_MEASURED_S = 2e-4
#: Spans between the choice of a way and the first try of the other.
PROBE_EVERY = 16
#: Most spans between two tries of the way that is not the faster one (the spacing doubles
#: from :data:`PROBE_EVERY` with every try that leaves the choice as it was).
PROBE_MOST = 256
#: Spans measured each way before the faster is chosen.
EXPLORE = 2
#: Spans a plan runs before it has chosen: one that fills the caches, then :data:`EXPLORE`
#: each way (a benchmark leaves them untimed).
SPANS_TO_CHOOSE = 1 + 2 * EXPLORE
#: Measured spans kept per way (the least of them is its cost: a span slowed by the machine
#: does not turn the choice for long).
SAMPLES = 3
#: Pieces whose times are all within this fraction of their mean leave the cuts alone: on the
#: two-core test machine evenly loaded halves differ by up to 4 % in the median frame (±6 %
#: from frame to frame), the flash's by 21 %.
DEAD_BAND = 0.06
#: Guards every plan (module-wide, so that a simulation stays picklable).
_lock = threading.Lock()


class PiecePlan:
    """How the spans of one simulation are cut into pieces (see the module docstring); safe
    to share between threads."""

    def __init__(self) -> None:
        #: Fractions of the chunk at which pieces start and end (0 first, 1 last), or None
        #: for even cuts.
        self._bounds: list[float] | None = None
        #: Seconds per pulse of the last spans run on the threads (True) and on the calling
        #: thread (False).
        self._costs: dict[bool, deque[float]] = {True: deque(maxlen=SAMPLES),
                                                 False: deque(maxlen=SAMPLES)}
        self._spans = 0
        self._warm = False  # the first span builds caches: its time is not the way's
        self._faster: bool | None = None  # the way chosen
        self._spacing = PROBE_EVERY  # spans from one try of the other way to the next
        self._probe_at = 0  # the span that tries the other way

    def threaded(self) -> bool:
        """Whether the next span runs in one piece per thread (else on the calling thread):
        each way in turn until both were measured :data:`EXPLORE` times (after a first span
        on the threads, which fills the caches), then the faster, and the other
        :data:`PROBE_EVERY` spans after the choice, then at spacings that double up to
        :data:`PROBE_MOST` while the tries leave the choice as it was."""
        with _lock:
            threads, caller = self._costs[True], self._costs[False]
            if min(len(threads), len(caller)) < EXPLORE:
                return len(threads) <= len(caller)
            self._spans += 1
            faster = min(threads) <= min(caller)
            if faster != self._faster:  # chosen now, or turned by the last try
                self._faster, self._spacing = faster, PROBE_EVERY
                self._probe_at = self._spans + PROBE_EVERY
            if self._spans < self._probe_at:
                return faster
            self._probe_at = self._spans + self._spacing
            self._spacing = min(2 * self._spacing, PROBE_MOST)
            return not faster

    def timed(self, threaded: bool, seconds: float, pulses: int) -> None:
        """Record a span of ``pulses`` run in ``seconds`` the way ``threaded`` says (from its
        first piece to its last as the caller consumed them)."""
        if pulses > 0 and seconds >= 0.0:
            with _lock:
                if self._warm:
                    self._costs[threaded].append(seconds / pulses)
                self._warm = True

    def bounds(self, parts: int) -> list[float]:
        """The fractions ``0 = b0 < b1 < ... < b_parts = 1`` to cut the next chunk at."""
        with _lock:
            bounds = self._bounds
        if bounds is None or len(bounds) != parts + 1:
            return [j / parts for j in range(parts + 1)]
        return list(bounds)

    @staticmethod
    def cuts(start: int, stop: int, bounds: list[float]) -> list[tuple[int, int]]:
        """``[start, stop)`` cut at ``bounds`` (pieces of no pulse are left out)."""
        n = stop - start
        edges = [start + min(n, max(0, round(b * n))) for b in bounds]
        edges[0], edges[-1] = start, stop
        return [(lo, hi) for lo, hi in zip(edges, edges[1:]) if hi > lo]

    def record(self, bounds: list[float], seconds: list[float]) -> None:
        """Move the cuts halfway toward equal times, given the ``seconds`` each piece of a
        chunk cut at ``bounds`` took."""
        parts = len(seconds)
        total = sum(seconds)
        if parts < 2 or len(bounds) != parts + 1 or not total >= MIN_MEASURED_S:
            return
        mean = total / parts
        if max(abs(s - mean) for s in seconds) <= DEAD_BAND * mean:
            return
        # the cost up to each bound, then the fraction at which it reaches j / parts of the
        # total (cost taken as even within each piece)
        target = [0.0]
        done, piece = 0.0, 0
        for j in range(1, parts):
            want = total * j / parts
            while piece < parts - 1 and done + seconds[piece] < want:
                done += seconds[piece]
                piece += 1
            width = bounds[piece + 1] - bounds[piece]
            share = (want - done) / seconds[piece] if seconds[piece] > 0 else 0.5
            target.append(bounds[piece] + width * min(1.0, max(0.0, share)))
        target.append(1.0)
        least = MIN_SHARE / parts
        moved = [0.0]
        for j in range(1, parts):
            b = 0.5 * (bounds[j] + target[j])
            b = max(b, moved[-1] + least)  # every piece keeps at least its least share
            moved.append(min(b, 1.0 - least * (parts - j)))
        moved.append(1.0)
        with _lock:
            self._bounds = moved
