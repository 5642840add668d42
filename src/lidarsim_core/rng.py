"""Counter-based random numbers keyed by (seed, frame, stream) and indexed by ray.

Every random number that affects a ray is a pure function of ``(seed, frame, stream name,
ray index, draw number)``: NumPy's Philox-4×64 generator is keyed by a hash of
``(seed, frame, stream)`` and its counter is set from the ray index. The same ray therefore
receives the same noise whatever the chunk size, backend, thread or worker count.
"""

from __future__ import annotations

import zlib

import numpy as np

_UINT53 = 2.0 ** -53
_BLOCK = 4  # Philox-4x64 yields four 64-bit words per counter value


def stream_key(seed: int, frame: int, stream: str) -> np.ndarray:
    """The 128-bit Philox key for one noise stream of one frame."""
    seq = np.random.SeedSequence([int(seed) & 0xFFFFFFFFFFFFFFFF, int(frame),
                                  zlib.crc32(stream.encode("utf-8"))])
    return seq.generate_state(2, dtype=np.uint64)


def ray_uniforms(seed: int, frame: int, stream: str, ray_index: np.ndarray, draws: int
                 ) -> np.ndarray:
    """Uniform numbers in the open interval (0, 1), ``draws`` per ray.

    Parameters
    ----------
    seed, frame, stream
        Identify the stream; different streams are statistically independent.
    ray_index
        (N,) non-negative int64 ray indices (any order, may repeat).
    draws
        How many numbers each ray needs.

    Returns
    -------
    numpy.ndarray
        (N, draws) float64; row ``i`` depends only on ``ray_index[i]`` and the stream.
    """
    ray_index = np.asarray(ray_index, dtype=np.int64)
    if ray_index.size == 0:
        return np.empty((0, draws))
    blocks = -(-draws // _BLOCK)
    lo, hi = int(ray_index.min()), int(ray_index.max())
    if lo < 0:
        raise ValueError("ray indices must be non-negative")
    gen = np.random.Philox(key=stream_key(seed, frame, stream), counter=[lo * blocks, 0, 0, 0])
    raw = gen.random_raw((hi - lo + 1) * blocks * _BLOCK).reshape(hi - lo + 1, blocks * _BLOCK)
    raw = raw[ray_index - lo, :draws]
    return ((raw >> np.uint64(11)).astype(np.float64) + 0.5) * _UINT53


def ray_normals(seed: int, frame: int, stream: str, ray_index: np.ndarray, draws: int
                ) -> np.ndarray:
    """Standard normal numbers, ``draws`` per ray, by inverse CDF of :func:`ray_uniforms`."""
    from scipy.special import ndtri

    return ndtri(ray_uniforms(seed, frame, stream, ray_index, draws))
