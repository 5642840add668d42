"""Philox-4×64-10 in numba, word for word the generator behind NumPy's ``Philox``.

:func:`lidarsim_core.noise.rng.ray_uniforms` gives ray ``i`` the counter blocks ``i·B + b + 1``
(``b < B``) of a stream's Philox generator. NumPy can only produce a contiguous run of blocks,
so uniforms for scattered rays (the hits of a frame) cost as much as the whole index range;
this kernel computes each ray's blocks directly. All arithmetic is on 64-bit integers, so the
words are identical to NumPy's (the tests compare them).
"""

from __future__ import annotations

import numpy as np
from llvmlite import ir
from numba import njit, types
from numba.extending import intrinsic

# Random123's Philox-4×64 multipliers and Weyl key increments
_M0 = np.uint64(0xD2E7470EE14C6C93)
_M1 = np.uint64(0xCA5A826395121157)
_W0 = np.uint64(0x9E3779B97F4A7C15)
_W1 = np.uint64(0xBB67AE8584CAA73B)
_ZERO = np.uint64(0)
_SHIFT = np.uint64(12)  # rng.UNIFORM_BITS = 52
_UNIT = 2.0 ** -52


@intrinsic
def _mulhi(typingctx, a, b):  # noqa: ANN001, ANN202 - numba intrinsic signature
    """High 64 bits of the 128-bit product ``a·b`` (one machine multiply)."""
    signature = types.uint64(types.uint64, types.uint64)

    def codegen(context, builder, sig, args):  # noqa: ANN001, ANN202
        wide = ir.IntType(128)
        product = builder.mul(builder.zext(args[0], wide), builder.zext(args[1], wide))
        return builder.trunc(builder.lshr(product, ir.Constant(wide, 64)), ir.IntType(64))

    return signature, codegen


@njit(inline="always", cache=True)
def _round(c0, c1, c2, c3, k0, k1):  # noqa: ANN001, ANN202
    return (_mulhi(_M1, c2) ^ c1 ^ k0, _M1 * c2, _mulhi(_M0, c0) ^ c3 ^ k1, _M0 * c0)


@njit(inline="always", cache=True)
def philox_counter(c0, c1, c2, k0, k1):  # noqa: ANN001, ANN201
    """The four words of Philox-4×64-10 for counter ``(c0, c1, c2, 0)`` and key (k0, k1)."""
    v0, v1, v2, v3 = _round(c0, c1, c2, _ZERO, k0, k1)
    for _ in range(9):
        k0 = k0 + _W0
        k1 = k1 + _W1
        v0, v1, v2, v3 = _round(v0, v1, v2, v3, k0, k1)
    return v0, v1, v2, v3


@njit(inline="always", cache=True)
def philox_block(counter, k0, k1):  # noqa: ANN001, ANN201
    """The four words of Philox-4×64-10 for counter ``(counter, 0, 0, 0)`` and key (k0, k1)."""
    return philox_counter(counter, _ZERO, _ZERO, k0, k1)


@njit(inline="always", cache=True)
def to_unit(word):  # noqa: ANN001, ANN201
    """A 64-bit word as a float64 in (0, 1): the top 52 bits, centred (as rng.ray_uniforms)."""
    return (np.float64(word >> _SHIFT) + 0.5) * _UNIT


@njit(nogil=True, cache=True)
def ray_uniforms(key, ray_index, draws):  # noqa: ANN001, ANN201
    """(N, draws) uniforms of :func:`lidarsim_core.noise.rng.ray_uniforms` for ``ray_index``.

    Parameters
    ----------
    key
        (2,) uint64 Philox key of the stream (:func:`lidarsim_core.noise.rng.stream_key`).
    ray_index
        (N,) int64 non-negative ray indices.
    draws
        Numbers per ray.
    """
    blocks = (draws + 3) // 4
    n = ray_index.shape[0]
    out = np.empty((n, draws))
    k0, k1 = key[0], key[1]
    for row in range(n):
        base = np.uint64(ray_index[row]) * np.uint64(blocks) + np.uint64(1)
        for block in range(blocks):
            w = philox_block(base + np.uint64(block), k0, k1)
            for j in range(4):
                column = 4 * block + j
                if column < draws:
                    out[row, column] = to_unit(w[j])
    return out
