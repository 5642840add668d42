"""The materials' effective reflectance ρ_eff in two compiled passes around NumPy's ``exp``
and ``arccos`` (:meth:`lidarsim_core.scene.materials.MaterialTable.effective` calls them).

The NumPy reference makes about twenty-five array operations on a piece's hits, each holding
the GIL for its set-up, where the pieces of two threads wait for each other (py-spy's samples
of the held GIL put a fifth of a two-thread tumbling frame's there; replaced, the frame took
0.98–0.99 × its time, docs/performance.md, "What the second thread loses, taken apart").
Here the gathers, the masks and the arithmetic are two loops, and the two transcendental
functions stay NumPy's own calls on the arrays that need them, so the bits are NumPy's on
every CPU (NumPy has its own SIMD ``exp`` where the CPU has AVX-512, and the C library's
elsewhere). Every other operation is the reference's IEEE operation on the same values in
the same order (no fused multiply-adds), so the two give the same bits (tests compare them),
a grazing hit's division by zero included (NumPy's error model: infinities and NaNs, not
exceptions).
"""

from __future__ import annotations

import numpy as np
from numba import njit


@njit(nogil=True, cache=True, error_model="numpy")
def reflectance_terms(part, cos_incidence, diffuse, specular, slope2, retro):  # noqa: ANN001, ANN201
    """The diffuse term of every hit and the inputs of the two transcendental functions.

    Returns ``out`` (ρ_d·c per hit), ``c`` (the cosines clipped to [0, 1]), ``lit`` (the
    rows with a specular lobe: specular reflectance > 0 and c > 0), ``exponent`` (``-tan²θ /
    m²`` of those rows, the argument of the lobe's ``exp``), ``on`` (the rows with a
    retro-reflector) and ``c_on`` (their cosines, the argument of ``arccos``).
    """
    n = part.shape[0]
    out = np.empty(n)
    c = np.empty(n)
    lit_count, on_count = 0, 0
    for i in range(n):
        x = cos_incidence[i]
        x = 0.0 if x < 0.0 else x  # np.clip(x, 0, 1) (a NaN stays NaN, as NumPy's)
        x = 1.0 if x > 1.0 else x
        c[i] = x
        p = part[i]
        out[i] = diffuse[p] * x
        if specular[p] > 0.0 and x > 0.0:
            lit_count += 1
        if retro[p] > 0.0:
            on_count += 1
    lit = np.empty(lit_count, dtype=np.int64)
    exponent = np.empty(lit_count)
    on = np.empty(on_count, dtype=np.int64)
    c_on = np.empty(on_count)
    k, j = 0, 0
    for i in range(n):
        p = part[i]
        x = c[i]
        if specular[p] > 0.0 and x > 0.0:
            c2 = x * x
            tan2 = 1.0 - c2
            tan2 = tan2 / c2
            exponent[k] = -tan2 / slope2[p]
            lit[k] = i
            k += 1
        if retro[p] > 0.0:
            on[j] = i
            c_on[j] = x
            j += 1
    return out, c, lit, exponent, on, c_on


@njit(nogil=True, cache=True, error_model="numpy")
def reflectance_sum(out, c, part, lit, lobe, slope2, specular, on, theta, retro,  # noqa: ANN001
                    acceptance):  # noqa: ANN001
    """Add the specular lobes (``lobe``: ``exp`` of :func:`reflectance_terms`' exponents) and
    the retro-reflection (``theta``: ``arccos`` of its cosines) to ``out`` in place."""
    for k in range(lit.shape[0]):
        i = lit[k]
        p = part[i]
        x = c[i]
        c2 = x * x
        m2 = slope2[p]
        denominator = 4.0 * m2
        denominator = denominator * c2
        denominator = denominator * c2
        denominator = denominator * x
        value = lobe[k] / denominator
        out[i] = out[i] + value * specular[p]
    for j in range(on.shape[0]):
        i = on[j]
        p = part[i]
        fall = 1.0 - theta[j] / acceptance[p]
        out[i] = out[i] + retro[p] * (fall if fall > 0.0 else 0.0)
