"""Counter-based random numbers keyed by (seed, frame, stream) and indexed by ray.

Every random number that affects a ray is a pure function of ``(seed, frame, stream name,
ray index, draw number)``: NumPy's Philox-4×64 generator is keyed by a hash of
``(seed, frame, stream)`` and its counter is set from the ray index. The same ray therefore
receives the same noise whatever the chunk size, backend, thread or worker count. With the
compiled kernels (:mod:`lidarsim_core.kernels`) the same Philox words are computed per ray in
numba, bit for bit.

Normal numbers come from the words in one of two ways (:data:`NORMAL_GENERATORS`, the
scenario's ``normals``): ``inverse_cdf``, the default and the seed paper's stream, is
``ndtri`` of :func:`ray_uniforms`; ``ziggurat`` is Marsaglia & Tsang's Ziggurat on the same
words (:mod:`lidarsim_core.noise.ziggurat`), exact too, with other numbers.
"""

from __future__ import annotations

import functools
import zlib

import numpy as np

from .. import kernels
from . import ziggurat

#: Uniforms are (k + 1/2) / 2**52 for the top 52 bits k of a word: exactly representable, so
#: they lie strictly inside (0, 1), symmetric about 1/2 (with 53 bits, k + 1/2 rounds to 2**53
#: for the largest k and the uniform would be 1.0, whose inverse CDF is infinite).
UNIFORM_BITS = 52
_SCALE = 2.0 ** -UNIFORM_BITS
#: The largest |z| :func:`ray_normals` can return: ndtri of the smallest uniform, 2**-53
#: (8.2095...). Noise models drawing ``z·σ`` are therefore bounded by construction.
MAX_ABS_NORMAL = 8.209536151601387
#: The normal generators of :func:`ray_normals`; the first is the default (the seed paper's).
INVERSE_CDF = "inverse_cdf"
NORMAL_GENERATORS = (INVERSE_CDF, "ziggurat")
#: The largest |z| of the Ziggurat generator (its tail's bound, 12.23).
ZIGGURAT_MAX_ABS = ziggurat.MAX_ABS_NORMAL
_BLOCK = 4  # Philox-4x64 yields four 64-bit words per counter value


def stream_key(seed: int, frame: int, stream: str) -> np.ndarray:
    """The 128-bit Philox key (two uint64, read-only) for one noise stream of one frame."""
    return _stream_key(int(seed) & 0xFFFFFFFFFFFFFFFF, int(frame), stream)


@functools.lru_cache(maxsize=4096)
def _stream_key(seed: int, frame: int, stream: str) -> np.ndarray:
    # hashing the seed costs more than drawing a few thousand numbers: once per stream
    seq = np.random.SeedSequence([seed, frame, zlib.crc32(stream.encode("utf-8"))])
    key = seq.generate_state(2, dtype=np.uint64)
    key.flags.writeable = False
    return key


def ray_words(seed: int, frame: int, stream: str, ray_index: np.ndarray, draws: int
              ) -> np.ndarray:
    """The raw 64-bit Philox words behind :func:`ray_uniforms` (NumPy), ``draws`` per ray.

    Word ``j`` of ray ``i`` is word ``j mod 4`` of the block with counter
    ``i·B + j // 4 + 1`` (``B = ceil(draws / 4)``).

    Returns
    -------
    numpy.ndarray
        (N, draws) uint64.
    """
    ray_index = np.asarray(ray_index, dtype=np.int64)
    if ray_index.size == 0:
        return np.empty((0, draws), dtype=np.uint64)
    lo, hi = int(ray_index.min()), int(ray_index.max())
    if lo < 0:
        raise ValueError("ray indices must be non-negative")
    blocks = -(-draws // _BLOCK)
    gen = np.random.Philox(key=stream_key(seed, frame, stream), counter=[lo * blocks, 0, 0, 0])
    raw = gen.random_raw((hi - lo + 1) * blocks * _BLOCK).reshape(hi - lo + 1, blocks * _BLOCK)
    return raw[ray_index - lo, :draws]


def ray_uniforms(seed: int, frame: int, stream: str, ray_index: np.ndarray, draws: int
                 ) -> np.ndarray:
    """Uniform numbers in the open interval (0, 1), ``draws`` per ray (multiples of 2**-52
    plus 2**-53).

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
    if int(ray_index.min()) < 0:
        raise ValueError("ray indices must be non-negative")
    if kernels.enabled():  # the same words, computed for these rays only
        from ..kernels.philox import ray_uniforms as compiled_uniforms

        key = stream_key(seed, frame, stream)
        return compiled_uniforms(key, np.ascontiguousarray(ray_index), int(draws))
    raw = ray_words(seed, frame, stream, ray_index, draws)
    return ((raw >> np.uint64(64 - UNIFORM_BITS)).astype(np.float64) + 0.5) * _SCALE


def max_abs_normal(generator: str = INVERSE_CDF) -> float:
    """The largest ``|z|`` that :func:`ray_normals` can return with ``generator`` (culling
    margins rely on it)."""
    return MAX_ABS_NORMAL if _check_generator(generator) == INVERSE_CDF else ZIGGURAT_MAX_ABS


def _check_generator(generator: str) -> str:
    if generator not in NORMAL_GENERATORS:
        raise ValueError(f"unknown normal generator {generator!r}; known: "
                         f"{', '.join(NORMAL_GENERATORS)}")
    return generator


def ray_normals(seed: int, frame: int, stream: str, ray_index: np.ndarray, draws: int,
                generator: str = INVERSE_CDF) -> np.ndarray:
    """Standard normal numbers, ``draws`` per ray, from the stream's Philox words.

    Parameters
    ----------
    seed, frame, stream, ray_index, draws
        As :func:`ray_uniforms`.
    generator
        ``"inverse_cdf"`` (default, the seed paper's stream): ``ndtri`` of
        :func:`ray_uniforms`. ``"ziggurat"``: Marsaglia & Tsang's Ziggurat on the same words
        (:mod:`lidarsim_core.noise.ziggurat`): another exact normal stream, different numbers,
        cheaper to draw.

    Returns
    -------
    numpy.ndarray
        (N, draws) float64.
    """
    if _check_generator(generator) == INVERSE_CDF:
        from scipy.special import ndtri

        return ndtri(ray_uniforms(seed, frame, stream, ray_index, draws))
    ray_index = np.asarray(ray_index, dtype=np.int64)
    if ray_index.size == 0:
        return np.empty((0, draws))
    if int(ray_index.min()) < 0:
        raise ValueError("ray indices must be non-negative")
    key = stream_key(seed, frame, stream)
    if kernels.enabled():
        from ..kernels.ziggurat import ray_normals as compiled_normals

        return compiled_normals(key, np.ascontiguousarray(ray_index), int(draws),
                                ziggurat.X_TABLE, ziggurat.F_TABLE)
    words = ray_words(seed, frame, stream, ray_index, draws)
    blocks = -(-draws // _BLOCK)
    column = np.arange(draws, dtype=np.uint64)
    c0 = (ray_index.astype(np.uint64)[:, None] * np.uint64(blocks)
          + column // np.uint64(_BLOCK) + np.uint64(1))
    lane = np.broadcast_to(column % np.uint64(_BLOCK), words.shape)
    return ziggurat.normals_from_words(key, words, c0, lane).reshape(words.shape)
