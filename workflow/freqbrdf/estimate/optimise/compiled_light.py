"""Compiled (numba) inner loops of the shadowed light's SH fits and evaluations, called through
`freqbrdf.estimate.optimise.kernels`, which checks their arguments and documents them.

Apart from the model's kernels (`freqbrdf.estimate.optimise.compiled`), because no kernel of
either file inlines a helper of the other: numba's on-disk cache (``cache=True``) is
invalidated by the defining file's modification only, so a kernel inlining a helper, or
reading a constant, from another file would keep running its stale compiled copy after that
changed. Hence this file's own ``_TEXELS`` and ``_FAST``.

Every output element is written by exactly one iteration of a parallel loop and no
reduction crosses iterations, so results do not depend on the number of threads.
"""

from __future__ import annotations

import numba
import numpy as np

__all__ = ["degree_sums_kernel", "shadowing_kernel", "basis_factors_kernel", "table_sums_kernel"]

_INV_SQRT_4PI = 1.0 / np.sqrt(4.0 * np.pi)
_SQRT2 = np.sqrt(2.0)
_BLOCK = 256  # pairs per parallel iteration (one SH buffer each)
_TEXELS = 64  # texels per parallel iteration (one set of scratch arrays each)
_FAST = {"nsz", "arcp", "afn", "contract"}  # as `freqbrdf.estimate.optimise.compiled`'s, which says why (tested equal)


@numba.njit(cache=True, inline="always")
def _order_scratch(lmax):  # pragma: no cover - compiled
    """Scratch of `_real_sh_point` (6, lmax + 2): per order m, ``cos m phi``, ``sin m phi`` and the
    recurrence's last two values (rows 0-3, written per direction), and its two square roots,
    ``sqrt((2m + 1) / 2m)`` and ``sqrt(2m + 3)`` (rows 4, 5), once per buffer, not per direction."""
    scratch = np.zeros((6, lmax + 2))
    for m in range(1, lmax + 1):
        scratch[4, m] = np.sqrt((2.0 * m + 1.0) / (2.0 * m))
        scratch[5, m] = np.sqrt(2.0 * m + 3.0)
    return scratch


@numba.njit(cache=True, inline="always")
def _real_sh_point(x, y, z, lmax, a, b, out, scratch):  # pragma: no cover - compiled
    """Real SH of one unit direction into ``out`` ((lmax+1)^2,), the convention of
    `freqbrdf.sphere.sh.real_sh` (Y-up, no Condon-Shortley phase), by its recurrence
    (``scratch``: `_order_scratch`). Each order's first two degrees are seeded, then every
    degree advances all its orders' three-term recurrences side by side: independent
    operations, where one order after another would wait on each step's latency."""
    t = y
    u = -z
    v = x
    cm, sm, p1, p2 = scratch[0], scratch[1], scratch[2], scratch[3]  # p1: degree l - 1, p2: l - 2
    out[0] = _INV_SQRT_4PI
    p2[0] = _INV_SQRT_4PI
    if lmax >= 1:
        out[2] = t * np.sqrt(3.0) * _INV_SQRT_4PI
        p1[0] = out[2]
    c_m = u  # Re (u + i v)^m
    s_m = v  # Im (u + i v)^m
    qmm = _INV_SQRT_4PI
    for m in range(1, lmax + 1):
        if m > 1:
            c_new = u * c_m - v * s_m
            s_m = s_m * u + v * c_m
            c_m = c_new
        qmm *= scratch[4, m]
        q2 = _SQRT2 * qmm  # sqrt(2) q_m^m
        cm[m], sm[m], p2[m] = c_m, s_m, q2
        out[m * m + 2 * m] = q2 * c_m
        out[m * m] = q2 * s_m
        if m + 1 <= lmax:
            q1 = t * q2 * scratch[5, m]
            i = (m + 1) * (m + 1) + m + 1
            out[i + m] = q1 * c_m
            out[i - m] = q1 * s_m
            p1[m] = q1
    for l in range(2, lmax + 1):
        for m in range(l - 1):
            q = a[l, m] * (t * p1[m] - b[l, m] * p2[m])
            p2[m] = p1[m]
            p1[m] = q
        i = l * l + l
        out[i] = p1[0]
        for m in range(1, l - 1):
            out[i + m] = p1[m] * cm[m]
            out[i - m] = p1[m] * sm[m]


@numba.njit(cache=True, inline="always")
def _mirror_sums(lg, d, a, b, y, scratch, out, p):  # pragma: no cover - compiled
    """``out[p, l, c] = sum_m lg[lm, c] Y_lm(d)`` per degree, RGB (``y``, ``scratch``: scratch of
    `_real_sh_point`): six running sums, two per channel, one pass over each degree's coefficients."""
    lmax = out.shape[1] - 1
    norm = np.sqrt(d[0] * d[0] + d[1] * d[1] + d[2] * d[2])
    _real_sh_point(d[0] / norm, d[1] / norm, d[2] / norm, lmax, a, b, y, scratch)
    for l in range(lmax + 1):
        k0 = l * l
        r_sum, g_sum, b_sum = lg[k0, 0] * y[k0], lg[k0, 1] * y[k0], lg[k0, 2] * y[k0]
        r2, g2, b2 = 0.0, 0.0, 0.0
        for k in range(k0 + 1, (l + 1) * (l + 1), 2):  # the other 2l terms as two chains of l
            r_sum += lg[k, 0] * y[k]
            g_sum += lg[k, 1] * y[k]
            b_sum += lg[k, 2] * y[k]
            r2 += lg[k + 1, 0] * y[k + 1]
            g2 += lg[k + 1, 1] * y[k + 1]
            b2 += lg[k + 1, 2] * y[k + 1]
        out[p, l, 0], out[p, l, 1], out[p, l, 2] = r_sum + r2, g_sum + g2, b_sum + b2


@numba.njit(parallel=True, cache=True, fastmath=_FAST)
def degree_sums_kernel(lg, rows, pairs, mirror, a, b, out):  # pragma: no cover - compiled
    n = pairs.shape[0]
    for blk in numba.prange((n + _BLOCK - 1) // _BLOCK):
        y = np.empty(out.shape[1] * out.shape[1])
        scratch = _order_scratch(out.shape[1] - 1)
        for i in range(blk * _BLOCK, min(n, (blk + 1) * _BLOCK)):
            _mirror_sums(lg[rows[i]], mirror[pairs[i]], a, b, y, scratch, out, pairs[i])


@numba.njit(parallel=True, cache=True, fastmath=_FAST)
def shadowing_kernel(normals, directions, alpha, out):  # pragma: no cover - compiled
    one = np.float32(1.0)
    for t in numba.prange(normals.shape[0]):
        nx, ny, nz = normals[t, 0], normals[t, 1], normals[t, 2]
        a2 = np.float32(alpha[t] * alpha[t])
        for q in range(directions.shape[1]):
            c = nx * directions[0, q] + ny * directions[1, q] + nz * directions[2, q]
            cc = max(c, np.float32(1e-6))
            g = np.float32(2.0) / (one + np.sqrt(one + a2 * (one / (cc * cc) - one)))
            out[t, q] = g if c > 0 else np.float32(0.0)


@numba.njit(parallel=True, cache=True, fastmath=_FAST)
def basis_factors_kernel(normals, directions, u, out):  # pragma: no cover - compiled
    rank = u.shape[0]
    last = u.shape[1] - 1
    zero = np.float32(0.0)
    for t in numba.prange(normals.shape[0]):
        nx, ny, nz = normals[t, 0], normals[t, 1], normals[t, 2]
        for q in range(directions.shape[1]):
            c = nx * directions[0, q] + ny * directions[1, q] + nz * directions[2, q]
            if c <= zero:
                for k in range(rank):
                    out[t * rank + k, q] = zero
                continue
            x = min(c, np.float32(1.0)) * last
            j = min(int(x), last - 1)
            f = x - j
            for k in range(rank):
                out[t * rank + k, q] = u[k, j] + f * (u[k, j + 1] - u[k, j])


@numba.njit(parallel=True, cache=True, fastmath=_FAST)
def table_sums_kernel(coefficients, corner, corner_weight, v, slots, start, mirror, a, b, out):  # pragma: no cover
    rank, size = coefficients.shape[1], coefficients.shape[2]  # size: (lmax + 1)^2 x 3, coefficient-major
    n = slots.shape[0]
    for blk in numba.prange((n + _TEXELS - 1) // _TEXELS):
        lg = np.empty(size, np.float32)
        lg64 = np.empty(size)
        y = np.empty(out.shape[1] * out.shape[1])
        scratch = _order_scratch(out.shape[1] - 1)
        for i in range(blk * _TEXELS, min(n, (blk + 1) * _TEXELS)):
            lg[:] = 0.0
            for j in range(corner.shape[1]):
                for r in range(rank):
                    w = np.float32(corner_weight[i, j] * v[i, r])
                    if w != 0.0:
                        row = coefficients[corner[i, j], r]
                        for q in range(size):
                            lg[q] += w * row[q]
            for q in range(size):
                lg64[q] = lg[q]  # exact: each pair's products then read doubles, not singles to convert
            for p in range(start[slots[i]], start[slots[i] + 1]):
                _mirror_sums(lg64.reshape(y.shape[0], 3), mirror[p], a, b, y, scratch, out, p)
