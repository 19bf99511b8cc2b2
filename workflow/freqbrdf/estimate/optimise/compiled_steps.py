"""Compiled (numba) loops of the gradient-descent estimator that share no helper with its model:
the blocks of the model's parallel loops, the TV term, Adam's update and the point sources' pair
geometry, called through `freqbrdf.estimate.optimise.kernels`, which checks their arguments and
documents them.

Apart from `freqbrdf.estimate.optimise.compiled` because none inlines anything of it (numba's
on-disk cache follows the defining file only, which is why the model's kernels and helpers
share one file).
"""

from __future__ import annotations

import numba
import numpy as np

__all__ = ["block_bounds", "tv_kernel", "adam_kernel", "source_geometry_kernel"]

_TEXELS = 64  # texels per parallel iteration on average (one set of scratch arrays each)
_TEXEL_WORK = 4  # a texel's own work (lobe, view basis, sources) in pairs' worth, for balancing blocks


@numba.njit(cache=True)
def block_bounds(start, texels):  # pragma: no cover - compiled
    """Contiguous blocks of ``texels`` (rows of ``start``) with about equal work each, about
    ``_TEXELS`` texels on average: block b takes ``texels[bounds[b]:bounds[b + 1]]``.

    A texel's work is its pairs (none past the observed texels) plus ``_TEXEL_WORK``, the per-texel
    part (lobe, view basis, sources) in pairs' worth. The texels are sorted by pair count (most
    first) and numba splits a parallel loop into one run of iterations per thread, so blocks of
    equal texel counts gave the first thread most of the pairs; contiguous, because every pair
    a block reads then follows the last one in memory (texels taken strided, for balance, cost
    each thread more in scattered reads than the balance saved: docs/estimator.md, Cost).
    """
    n = texels.shape[0]
    n_obs = start.shape[0] - 1
    cum = np.empty(n + 1, np.int64)
    cum[0] = 0
    for i in range(n):
        t = texels[i]
        cum[i + 1] = cum[i] + _TEXEL_WORK + (start[t + 1] - start[t] if t < n_obs else 0)
    n_blk = max((n + _TEXELS - 1) // _TEXELS, 1)
    bounds = np.empty(n_blk + 1, np.int64)
    i = 0
    for b in range(n_blk):
        target = (cum[n] * b) // n_blk
        while cum[i] < target:
            i += 1
        bounds[b] = i
    bounds[n_blk] = n
    return bounds


@numba.njit(cache=True)
def tv_kernel(x, edges, grad):  # pragma: no cover - compiled
    # serial: each texel's gradient sums its edges in edge order, whatever the threads
    m = edges.shape[0]
    total = 0.0
    grad[:] = 0.0
    for e in range(m):
        i, j = edges[e, 0], edges[e, 1]
        for q in range(x.shape[1]):
            d = x[i, q] - x[j, q]
            total += abs(d)
            step = np.sign(d) / m  # sign(0) = 0: a flat pair pulls neither texel
            grad[i, q] += step
            grad[j, q] -= step
    return total / m


@numba.njit(parallel=True, cache=True)
def adam_kernel(x, grad, m1, m2, lr, c1, c2, b1, b2, eps, floor):  # pragma: no cover - compiled
    # no fast math: the same operations in the same order as `solve.adam_step`'s NumPy, so the
    # same bits, in one pass over the five arrays instead of a dozen temporaries
    for i in numba.prange(x.shape[0]):
        for q in range(x.shape[1]):
            g = grad[i, q]
            a = b1 * m1[i, q] + (1.0 - b1) * g
            b = b2 * m2[i, q] + (1.0 - b2) * g * g
            m1[i, q] = a
            m2[i, q] = b
            v = min(max(x[i, q] - lr * (a / c1) / (np.sqrt(b / c2) + eps), 0.0), 1.0)
            x[i, q] = max(v, floor[q])


@numba.njit(parallel=True, cache=True)
def source_geometry_kernel(wo, incoming, slot, out):  # pragma: no cover - compiled
    for n in numba.prange(wo.shape[0]):
        t = slot[n]
        for j in range(incoming.shape[1]):
            h0 = incoming[t, j, 0] + wo[n, 0]
            h1 = incoming[t, j, 1] + wo[n, 1]
            h2 = incoming[t, j, 2] + wo[n, 2]
            norm2 = h0 * h0 + h1 * h1 + h2 * h2
            lit = incoming[t, j, 2] > 0.0 and wo[n, 2] > 0.0 and norm2 > 0.0
            if not lit:
                norm2 = 1.0
            c = min(max((h0 * wo[n, 0] + h1 * wo[n, 1] + h2 * wo[n, 2]) / np.sqrt(norm2), 0.0), 1.0)
            out[n, j, 0] = (h0 * h0 + h1 * h1) / norm2
            out[n, j, 1] = (1.0 - c) ** 5
            out[n, j, 2] = 0.25 / wo[n, 2] if lit else 0.0
