"""Ziggurat normals on the counter-based Philox words (the ``ziggurat`` normal generator).

Marsaglia and Tsang's Ziggurat method (G. Marsaglia, W. W. Tsang, "The Ziggurat Method for
Generating Random Variables", *Journal of Statistical Software* 5(8), 2000) with 256 layers of
equal area ``v`` under the half-normal curve ``f(x) = exp(-x²/2)``. Most draws cost one
64-bit word, one multiplication and one comparison; the rest go through the exact rejection
steps of the paper (the wedge test against ``f``, Marsaglia's exponential tail beyond ``r``),
so the distribution is the standard normal's, not an approximation of it (to the resolution
of 52-bit uniforms, as for the inverse CDF).

Where the words come from (every number a pure function of the stream and the ray):

* Draw ``j`` of ray ``i`` starts from the same word as :func:`lidarsim_core.noise.rng.ray_uniforms`:
  word ``j mod 4`` of the Philox block with counter ``(c0, 0, 0, 0)``, ``c0 = i·B + j // 4 + 1``
  (``B`` blocks per ray). Its bits 0–7 choose the layer, bit 8 the sign and bits 12–63 the
  uniform (the top 52 bits, as ``ray_uniforms``), so the three are independent.
* A draw that is not accepted by its first word continues on its own sub-stream: its ``k``-th
  further word (``k = 1, 2, ...``) is word ``(k - 1) mod 4`` of the block with counter
  ``(c0, 1 + (k - 1) // 4, j mod 4, 0)``. No other draw, ray or stream ever uses these
  counters (first words have ``c1 = 0``), so however many rejections a draw meets, the result
  depends only on ``(seed, frame, stream, ray, draw)``, never on chunks, threads or order.

The tables are built here from the closed form (``math`` functions: the C library, as the
compiled kernel's), once, and handed to :func:`lidarsim_core.kernels.ziggurat.ray_normals`.
The NumPy functions below are the reference; the kernel gives the same bits.
"""

from __future__ import annotations

import math

import numpy as np

#: Layers of the Ziggurat (a power of two: the layer is the low 8 bits of a word).
LAYERS = 256
#: Start of the tail, and the area of every layer (base strip + tail included) under
#: exp(-x²/2): the root of the closure condition solved to 25 digits (mpmath) for 256 layers.
#: Marsaglia & Tsang print r = 3.6541528853610088, v = 0.00492867323399; their v is rounded
#: in the 12th digit, which would make the top layer's area wrong by 1e-9 relative.
R = 3.654152885361009
V = 0.004928673233974655
_UNIT = 2.0 ** -52
_LAYER_MASK = np.uint64(LAYERS - 1)
_SIGN_SHIFT = np.uint64(8)
_ONE = np.uint64(1)
_UNIFORM_SHIFT = np.uint64(12)
#: |z| of a Ziggurat normal is below this: r + sqrt(2·53·ln 2), the tail's largest accepted
#: excess when its uniforms are at least 2**-53 (culling margins use it, as MAX_ABS_NORMAL).
MAX_ABS_NORMAL = R + math.sqrt(2.0 * 53.0 * math.log(2.0))


def _density(x: float) -> float:
    return math.exp(-0.5 * x * x)


def _build_tables() -> tuple[np.ndarray, np.ndarray]:
    xs = np.empty(LAYERS + 1)
    xs[0] = V / _density(R)  # the base strip's width: its rectangle plus the tail have area V
    xs[1] = R
    for i in range(1, LAYERS - 1):
        xs[i + 1] = math.sqrt(-2.0 * math.log(V / xs[i] + _density(xs[i])))
    xs[LAYERS] = 0.0
    fs = np.array([_density(x) for x in xs])
    fs[LAYERS] = 1.0
    xs.flags.writeable = False
    fs.flags.writeable = False
    return xs, fs


#: Layer edges x[0..256]: x[0] = V / f(R) (base strip), x[1] = R, decreasing to x[256] = 0;
#: f at each edge (f[256] = 1). Read-only.
X_TABLE, F_TABLE = _build_tables()


def closure_residual() -> float:
    """How far the top layer's area is from ``V``, relative (the tables' consistency)."""
    top = X_TABLE[LAYERS - 1] * (1.0 - F_TABLE[LAYERS - 1])
    return abs(top - V) / V


# -- Philox-4×64-10 for arbitrary counters, vectorised (NumPy's Philox runs one counter on)

_M0 = np.uint64(0xD2E7470EE14C6C93)
_M1 = np.uint64(0xCA5A826395121157)
_W0 = np.uint64(0x9E3779B97F4A7C15)
_W1 = np.uint64(0xBB67AE8584CAA73B)
_LOW32 = np.uint64(0xFFFFFFFF)
_S32 = np.uint64(32)


def _mulhilo(m: np.uint64, a: np.ndarray) -> tuple[np.ndarray, np.ndarray]:
    """High and low 64 bits of ``m·a`` (128-bit product) from 32-bit halves."""
    m_lo, m_hi = m & _LOW32, m >> _S32
    a_lo, a_hi = a & _LOW32, a >> _S32
    ll, lh, hl, hh = a_lo * m_lo, a_lo * m_hi, a_hi * m_lo, a_hi * m_hi
    mid = (ll >> _S32) + (lh & _LOW32) + (hl & _LOW32)
    return hh + (lh >> _S32) + (hl >> _S32) + (mid >> _S32), a * m


def philox_blocks(key: np.ndarray, c0: np.ndarray, c1: np.ndarray, c2: np.ndarray
                  ) -> np.ndarray:
    """(N, 4) words of Philox-4×64-10 for counters ``(c0, c1, c2, 0)`` under ``key``: the words
    NumPy's ``Philox(key=key, counter=[c0 - 1, c1, c2, 0]).random_raw(4)`` gives (NumPy
    increments its counter before each block).
    """
    c0 = np.asarray(c0, dtype=np.uint64)
    v1 = np.broadcast_to(np.asarray(c1, dtype=np.uint64), c0.shape)
    v2 = np.broadcast_to(np.asarray(c2, dtype=np.uint64), c0.shape)
    v0, v3 = c0, np.zeros_like(c0)
    k0, k1 = np.uint64(key[0]), np.uint64(key[1])
    with np.errstate(over="ignore"):
        for round_ in range(10):
            if round_:
                k0, k1 = k0 + _W0, k1 + _W1
            hi0, lo0 = _mulhilo(_M0, v0)
            hi1, lo1 = _mulhilo(_M1, v2)
            v0, v1, v2, v3 = hi1 ^ v1 ^ k0, lo1, hi0 ^ v3 ^ k1, lo0
    return np.stack([v0, v1, v2, v3], axis=-1)


def _unit(words: np.ndarray) -> np.ndarray:
    return ((words >> _UNIFORM_SHIFT).astype(np.float64) + 0.5) * _UNIT


def _libm(function: object, values: np.ndarray) -> np.ndarray:
    # the C library's exp/log, as numba's math.exp/math.log call (NumPy's own SIMD versions
    # may differ in the last bit); only the rare rejection steps come here
    return np.array([function(float(v)) for v in values], dtype=np.float64)


def normals_from_words(key: np.ndarray, words: np.ndarray, c0: np.ndarray,
                       lane: np.ndarray) -> np.ndarray:
    """Ziggurat normals, one per first word (the NumPy reference).

    Parameters
    ----------
    key
        (2,) uint64 Philox key of the stream.
    words
        (M,) uint64 first word of each draw.
    c0, lane
        (M,) uint64 counter of the block the word came from and its place in it (0–3): they
        name the draw's own sub-stream of further words (module docstring).

    Returns
    -------
    numpy.ndarray
        (M,) float64 standard normals.
    """
    words = np.asarray(words, dtype=np.uint64).ravel()
    c0 = np.asarray(c0, dtype=np.uint64).ravel()
    lane = np.asarray(lane, dtype=np.uint64).ravel()
    layer = (words & _LAYER_MASK).astype(np.intp)
    negative = ((words >> _SIGN_SHIFT) & _ONE).astype(bool)
    x = _unit(words) * X_TABLE[layer]
    out = x.copy()
    pending = np.flatnonzero(x >= X_TABLE[layer + 1])  # outside the layer's inner rectangle
    taken = np.zeros(len(words), dtype=np.int64)       # further words used, per draw

    def further(rows: np.ndarray) -> np.ndarray:
        k = taken[rows]  # the next word of each draw's sub-stream is its (k + 1)-th
        blocks = philox_blocks(key, c0[rows], (k // 4 + 1).astype(np.uint64), lane[rows])
        taken[rows] = k + 1
        return blocks[np.arange(len(rows)), k % 4]

    while len(pending):
        lay = layer[pending]
        tail, wedge = pending[lay == 0], pending[lay != 0]
        again = []
        if len(tail):  # Marsaglia's tail beyond R: a = -ln(u1)/R accepted when -2 ln(u2) > a²
            a = -_libm(math.log, _unit(further(tail))) / R
            b = -_libm(math.log, _unit(further(tail)))
            ok = b + b > a * a
            out[tail[ok]] = R + a[ok]
            again.append(tail[~ok])  # another tail try (the layer stays 0)
        if len(wedge):  # a uniform height in the layer's wedge, under the curve or not
            i, xw = layer[wedge], x[wedge]
            y = F_TABLE[i] + _unit(further(wedge)) * (F_TABLE[i + 1] - F_TABLE[i])
            ok = y < _libm(math.exp, -0.5 * xw * xw)
            redo = wedge[~ok]
            if len(redo):  # rejected: start over with the draw's next word
                w = further(redo)
                layer[redo] = (w & _LAYER_MASK).astype(np.intp)
                negative[redo] = ((w >> _SIGN_SHIFT) & _ONE).astype(bool)
                x[redo] = out[redo] = _unit(w) * X_TABLE[layer[redo]]
                again.append(redo[x[redo] >= X_TABLE[layer[redo] + 1]])
        pending = np.sort(np.concatenate(again)) if again else pending[:0]
    return np.where(negative, -out, out)
