"""The objective's compiled kernel with texels side by side in SIMD lanes (numba), called through
`freqbrdf.estimate.optimise.lanes`, which lays the pairs out and checks the arguments.

`freqbrdf.estimate.optimise.compiled.l1_kernel` walks a texel's pairs one at a time: its per-pair
arithmetic (masking, the view table, the point sources) runs as scalar code, and the degree sums
as six dependent chains. Here ``W`` texels of about as many pairs (`freqbrdf.estimate.optimise.lanes.pair_lanes`
sorts them by pair count) share a group, and a group's k-th pair of every
texel lies side by side in the last axis (``(slots, ..., W)``): each step of the model is a loop
over the lanes, which the compiler turns into vector instructions. The lane count is a run-time
value on purpose (with a compile-time 8, LLVM unrolls the loop fully and then does not vectorise
it), and large enough that each loop's run-time alias checks are paid over several vector
iterations; each loop writes one scratch array, so those checks stay few. The diffuse factor is
read as a sum of products (`freqbrdf.estimate.optimise.lanes.view_factors`) instead of gathered
from the view table.

The same model as ``l1_kernel`` (its docstring and `freqbrdf.estimate.optimise.kernels.l1_loss_gradient`
define it) for the paper's specular weights, in the same order within each pair and across a
texel's pairs, the degree sums in the light terms' precision; padding lanes (a texel with fewer
pairs than its group's most) carry ``valid = 0``. Helpers are this file's own
(numba's on-disk cache follows the defining file only, `freqbrdf.estimate.optimise.compiled`).
Every output element is written by one iteration of the parallel loop, so results do not depend
on the number of threads.
"""

from __future__ import annotations

import numba
import numpy as np

__all__ = ["layout_kernel", "gather_terms_kernel", "l1_lanes_kernel", "grid_lanes_kernel"]

_FAST = {"nsz", "arcp", "afn", "contract"}  # `freqbrdf.estimate.optimise.compiled._FAST`, for the same reasons

# rows of the per-lane parameters ``par``; the diffuse factor's alpha factors and their slopes follow
_ALPHA, _M, _BASE, _EPI, _VA = 0, 1, 2, 5, 8
# rows of the per-pair view factors ``pw``: a, b, da, db, d, dd, G1m, dG1m
_PW_ROWS = 8
# rows of the sums over a texel's pairs: |res|, sign x slope in alpha, diffuse and rise per channel
_SUM_ROWS = 8


@numba.njit(parallel=True, cache=True)
def layout_kernel(pair, radiance, schlick, tan2, geometry, mu_nodes, out_radiance, out_schlick, out_tan2, out_valid,
                  out_geometry, out_mu):  # pragma: no cover - compiled
    # each (N, ...) array at pair[k, q] into out[k, ..., q], 0 where pair < 0; the view's cos theta_o
    # factors interpolated at the pair's cos theta_o as the pair-major kernels read the table
    n_mu = mu_nodes.shape[1]
    for k in numba.prange(pair.shape[0]):
        for q in range(pair.shape[1]):
            n = pair[k, q]
            ok = n >= 0
            m = max(n, 0)
            for c in range(3):
                out_radiance[k, c, q] = radiance[m, c] if ok else 0.0
            out_schlick[k, q] = schlick[m] if ok else 0.0
            t2 = tan2[m] if ok else 0.0
            out_tan2[k, q] = t2
            out_valid[k, q] = 1.0 if ok else 0.0
            for j in range(geometry.shape[1]):
                for h in range(3):
                    out_geometry[k, j, h, q] = geometry[m, j, h] if ok else 0.0
            x = 1.0 / np.sqrt(1.0 + t2) * (n_mu - 1)
            col = min(int(x), n_mu - 2)
            t = x - col
            for r in range(mu_nodes.shape[0]):
                out_mu[k, r, q] = ((1.0 - t) * mu_nodes[r, col] + t * mu_nodes[r, col + 1]) if ok else 0.0


@numba.njit(parallel=True, cache=True)
def gather_terms_kernel(terms, pair, out):  # pragma: no cover - compiled
    # out[k, l, c, q] = terms[pair[k, q], l, c], zero where pair < 0
    for k in numba.prange(pair.shape[0]):
        for q in range(pair.shape[1]):
            n = pair[k, q]
            for l in range(terms.shape[1]):
                for c in range(3):
                    out[k, l, c, q] = terms[n, l, c] if n >= 0 else 0.0


@numba.njit(cache=True, fastmath=False)
def _hermite(alpha, alpha_min, nodes):  # pragma: no cover - compiled
    """`freqbrdf.estimate.optimise.compiled._hermite`: node i and the value (w) and d/dalpha (d)
    weights of (value_i, slope_i, value_i+1, slope_i+1) in ``log alpha``."""
    u0 = np.log(alpha_min)
    du = -u0 / (nodes - 1)
    u = (np.log(min(max(alpha, alpha_min), 1.0)) - u0) / du
    i = min(int(u), nodes - 2)
    t = u - i
    t2 = t * t
    t3 = t2 * t
    w = (2 * t3 - 3 * t2 + 1, (t3 - 2 * t2 + t) * du, 3 * t2 - 2 * t3, (t3 - t2) * du)
    d = ((6 * t2 - 6 * t) / (du * alpha), (3 * t2 - 4 * t + 1) / alpha, (6 * t - 6 * t2) / (du * alpha),
         (3 * t2 - 2 * t) / alpha)
    return i, w, d


@numba.njit(cache=True, inline="always")
def _lane_setup(x, order, t0, e_pi, alpha_min, lobe, view_alpha, src, par, node, hw, fl, shade):  # pragma: no cover
    """Per lane q (texel ``order[t0 + q]``; past the observed texels, the last one's values, unused): its
    parameters into ``par``, the lobe and its slope in alpha into ``fl[0]``, ``fl[1]`` (L, 3 W: the
    lane's value once per channel, ``fl[:, l, c W + q]``), the diffuse factor's alpha factors
    (``view_alpha`` at alpha, Hermite in log alpha; 1 without a table) and their slopes into
    ``par[_VA:]``, and the point sources' power times G1(theta_i) and its derivative into
    ``shade`` (J, 6, W). ``node`` (W,) and ``hw`` (8, W): scratch for the lobe's Hermite node and
    weights, so that the lobe's loop over degrees runs over the lanes inside."""
    width = par.shape[1]
    n_deg = fl.shape[1]
    rank = view_alpha.shape[2]
    n_obs = order.shape[0]
    for q in range(width):
        s = order[min(t0 + q, n_obs - 1)]
        r = x[s, 3]
        alpha = max(r * r, alpha_min)
        par[_ALPHA, q] = alpha
        par[_M, q] = x[s, 4]
        for c in range(3):
            par[_BASE + c, q] = x[s, c]
            par[_EPI + c, q] = e_pi[s, c]
        if lobe.shape[0] == 0:  # the paper's exp(-(alpha l)^2), one exp
            a2 = alpha * alpha
            qe = np.exp(-a2)
            step = qe
            value = 1.0
            for l in range(n_deg):
                for c in range(3):
                    fl[0, l, c * width + q] = value
                    fl[1, l, c * width + q] = -2.0 * alpha * l * l * value
                value *= step
                step *= qe * qe
        else:
            i, w, d = _hermite(alpha, alpha_min, lobe.shape[0])
            node[q] = i
            for h in range(4):
                hw[h, q] = w[h]
                hw[4 + h, q] = d[h]
        if view_alpha.shape[0] == 0:  # the paper's Lambertian term: d = 1
            par[_VA, q] = 1.0
            par[_VA + 1, q] = 0.0
        else:
            i, w, d = _hermite(alpha, alpha_min, view_alpha.shape[0])
            for r in range(rank):
                a, ma = view_alpha[i, 0, r], view_alpha[i, 1, r]
                b, mb = view_alpha[i + 1, 0, r], view_alpha[i + 1, 1, r]
                par[_VA + r, q] = w[0] * a + w[1] * ma + w[2] * b + w[3] * mb
                par[_VA + rank + r, q] = d[0] * a + d[1] * ma + d[2] * b + d[3] * mb
    if lobe.shape[0]:
        for l in range(n_deg):
            for q in range(width):
                i = node[q]
                a, ma, b, mb = lobe[i, 0, l], lobe[i, 1, l], lobe[i + 1, 0, l], lobe[i + 1, 1, l]
                value = hw[0, q] * a + hw[1, q] * ma + hw[2, q] * b + hw[3, q] * mb
                slope = hw[4, q] * a + hw[5, q] * ma + hw[6, q] * b + hw[7, q] * mb
                fl[0, l, q] = value
                fl[1, l, q] = slope
            for c in range(1, 3):
                for q in range(width):
                    fl[0, l, c * width + q] = fl[0, l, q]
                    fl[1, l, c * width + q] = fl[1, l, q]
    for j in range(src.shape[1]):
        for q in range(width):
            s = order[min(t0 + q, n_obs - 1)]
            alpha = par[_ALPHA, q]
            t2 = src[s, j, 0]  # 0 without shadowing: G1 = 1
            root = np.sqrt(1.0 + alpha * alpha * t2)
            gi = 2.0 / (1.0 + root)
            dgi = -gi * gi * alpha * t2 / (2.0 * root)
            for c in range(3):
                shade[j, c, q] = src[s, j, 1 + c] * gi
                shade[j, 3 + c, q] = src[s, j, 1 + c] * dgi


@numba.njit(cache=True, inline="always")
def _view_factors(k, tan2, schlick, view_mu, masking, par, pw):  # pragma: no cover - compiled
    """Slot k's view factors per lane into ``pw`` (`_PW_ROWS`, W): the paper's specular weights
    ``a = (1 - c5) G1m``, ``b = c5 G1m``, the diffuse factor ``d`` (its alpha factors in ``par``
    times its cos theta_o factors ``view_mu[k]``, `freqbrdf.estimate.optimise.lanes.view_factors`),
    their derivatives in alpha, and G1m with its own (`freqbrdf.estimate.optimise.compiled._pair_terms`)."""
    width = pw.shape[1]
    rank = view_mu.shape[1]
    for q in range(width):
        t2 = tan2[k, q]
        c5 = schlick[k, q]
        g1 = 1.0
        dg1 = 0.0
        if masking:
            alpha = par[_ALPHA, q]
            root = np.sqrt(1.0 + alpha * alpha * t2)
            g1 = 2.0 / (1.0 + root)
            dg1 = -g1 * g1 * alpha * t2 / (2.0 * root)
        dif = 0.0
        ddif = 0.0
        for r in range(rank):
            dif += par[_VA + r, q] * view_mu[k, r, q]
            ddif += par[_VA + rank + r, q] * view_mu[k, r, q]
        pw[0, q] = (1.0 - c5) * g1
        pw[1, q] = c5 * g1
        pw[2, q] = (1.0 - c5) * dg1
        pw[3, q] = c5 * dg1
        pw[4, q] = dif
        pw[5, q] = ddif
        pw[6, q] = g1
        pw[7, q] = dg1


@numba.njit(cache=True, inline="always")
def _degree_sums(k, terms, fl, sd):  # pragma: no cover - compiled
    """Per channel c and lane q, the lobe-filtered light ``sd[0, c W + q]`` and its slope in alpha
    ``sd[1, c W + q]``, in the terms' precision. Channels and lanes run as one loop of 3 W (``terms``
    (K, L, 3 W)): the sums stay in memory between degrees, and one loop per degree instead of three
    pays its alias checks once."""
    n = sd.shape[1]
    for i in range(n):
        sd[0, i] = 0.0
        sd[1, i] = 0.0
    for l in range(terms.shape[1]):
        for i in range(n):
            t = terms[k, l, i]
            sd[0, i] += fl[0, l, i] * t
            sd[1, i] += fl[1, l, i] * t


@numba.njit(cache=True, inline="always")
def _sources(k, geo, shade, par, pw, tmp, acc):  # pragma: no cover - compiled
    """The point sources' GGX terms of slot k per lane (`freqbrdf.estimate.optimise.compiled._point_sources`):
    per channel c the sums split by Schlick's factor, ``acc[4 c:4 c + 4]`` = value (1 - c5h), value c5h
    and their slopes. A source below either horizon has ``1 / (4 cos theta_o) = 0`` and adds 0.
    Per source, first its D G1m / (4 cos theta_o) and slope into ``tmp`` (2, W), then the channels:
    one loop doing both was not vectorised."""
    width = acc.shape[1]
    for r in range(12):
        for q in range(width):
            acc[r, q] = 0.0
    for j in range(geo.shape[1]):
        for q in range(width):
            inv4o = geo[k, j, 2, q]
            sin2_h = geo[k, j, 0, q]
            alpha = par[_ALPHA, q]
            a2 = alpha * alpha
            inv_t = 1.0 / (sin2_h + (1.0 - sin2_h) * a2 if inv4o > 0.0 else 1.0)
            ndf = a2 * inv_t * inv_t / np.pi * inv4o
            dndf = 2.0 * alpha * inv_t * inv_t / np.pi * (1.0 - 2.0 * a2 * (1.0 - sin2_h) * inv_t) * inv4o
            tmp[0, q] = ndf * pw[6, q]
            tmp[1, q] = dndf * pw[6, q] + ndf * pw[7, q]
        for c in range(3):
            for q in range(width):
                c5h = geo[k, j, 1, q]
                value = shade[j, c, q] * tmp[0, q]
                slope = shade[j, c, q] * tmp[1, q] + shade[j, 3 + c, q] * tmp[0, q]
                acc[4 * c, q] += value * (1.0 - c5h)
                acc[4 * c + 1, q] += value * c5h
                acc[4 * c + 2, q] += slope * (1.0 - c5h)
                acc[4 * c + 3, q] += slope * c5h


@numba.njit(cache=True, inline="always")
def _residuals(k, radiance, valid, r0_dielectric, n_src, par, pw, sd, acc, sums):  # pragma: no cover - compiled
    """Slot k's residuals per lane, added into the texel's sums (`_SUM_ROWS`, W): |res|, sign times
    the model's slope in alpha, and per channel sign times d E / pi's factor and times the specular rise."""
    width = sums.shape[1]
    for c in range(3):  # channel outermost: one plain loop over the lanes each, the sums in the pair's channel order
        for q in range(width):
            ok = valid[k, q]
            m = par[_M, q]
            u, v, du, dv, dif, ddif = pw[0, q], pw[1, q], pw[2, q], pw[3, q], pw[4, q], pw[5, q]
            s = sd[0, c * width + q]
            d = sd[1, c * width + q]
            w0 = u * s
            w1 = v * s
            w2 = du * s + u * d
            w3 = dv * s + v * d
            if n_src > 0:
                w0 += acc[4 * c, q]
                w1 += acc[4 * c + 1, q]
                w2 += acc[4 * c + 2, q]
                w3 += acc[4 * c + 3, q]
            base = par[_BASE + c, q]
            e = par[_EPI + c, q]
            r0 = r0_dielectric * (1.0 - m) + m * base
            res = (1.0 - m) * base * e * dif + r0 * w0 + w1 - radiance[k, c, q]
            g = ok if res > 0.0 else (-ok if res < 0.0 else 0.0)
            sums[0, q] += ok * abs(res)
            sums[1, q] += g * (r0 * w2 + w3 + (1.0 - m) * base * e * ddif)
            sums[2 + c, q] += g * dif
            sums[5 + c, q] += g * w0


@numba.njit(parallel=True, cache=True, fastmath=_FAST)
def l1_lanes_kernel(x, order, slot_start, bounds, terms, radiance, schlick, tan2, valid, view_mu, e_pi, masking,
                    alpha_min, r0_dielectric, lobe, view_alpha, geo, src, grad, loss):  # pragma: no cover - compiled
    width = valid.shape[1]
    n_obs = e_pi.shape[0]
    n_deg = terms.shape[1]
    n_src = src.shape[1]
    dtype = terms.dtype
    # blocks of groups (``bounds``) of about equal slot counts, so that each thread's share holds as many pairs
    for blk in numba.prange(bounds.shape[0] - 1):
        par = np.zeros((_VA + 2 * view_mu.shape[1], width))
        fl = np.empty((2, n_deg, 3 * width), dtype)
        node = np.zeros(width, np.int64)
        hw = np.empty((8, width))
        shade = np.empty((n_src, 6, width))
        pw = np.empty((_PW_ROWS, width))
        sd = np.empty((2, 3 * width), dtype)
        acc = np.zeros((12, width))
        tmp = np.empty((2, width))
        sums = np.empty((_SUM_ROWS, width))
        for grp in range(bounds[blk], bounds[blk + 1]):
            t0 = grp * width
            _lane_setup(x, order, t0, e_pi, alpha_min, lobe, view_alpha, src, par, node, hw, fl, shade)
            for r in range(_SUM_ROWS):
                for q in range(width):
                    sums[r, q] = 0.0
            for k in range(slot_start[grp], slot_start[grp + 1]):
                _view_factors(k, tan2, schlick, view_mu, masking, par, pw)
                _degree_sums(k, terms, fl, sd)
                if n_src > 0:
                    _sources(k, geo, shade, par, pw, tmp, acc)
                _residuals(k, radiance, valid, r0_dielectric, n_src, par, pw, sd, acc, sums)
            for q in range(min(width, n_obs - t0)):
                s = order[t0 + q]
                m = x[s, 4]
                grad[s, 4] = 0.0
                for c in range(3):
                    e = e_pi[s, c]
                    grad[s, c] = (1.0 - m) * e * sums[2 + c, q] + m * sums[5 + c, q]
                    grad[s, 4] += -x[s, c] * e * sums[2 + c, q] + (x[s, c] - r0_dielectric) * sums[5 + c, q]
                grad[s, 3] = sums[1, q] * 2.0 * max(x[s, 3], np.sqrt(alpha_min))
                loss[s] = sums[0, q]


@numba.njit(cache=True, inline="always")
def _shared_setup(alpha, alpha_min, lobe, view_alpha, n_deg, f, va):  # pragma: no cover - compiled
    """At one alpha for every lane (the grid start's): the lobe ``f`` (L,) and the diffuse factor's
    alpha factors ``va`` (R,) (1 without a table), values only."""
    if lobe.shape[0] == 0:
        qe = np.exp(-alpha * alpha)
        step = qe
        value = 1.0
        for l in range(n_deg):
            f[l] = value
            value *= step
            step *= qe * qe
    else:
        i, w, _ = _hermite(alpha, alpha_min, lobe.shape[0])
        for l in range(n_deg):
            f[l] = w[0] * lobe[i, 0, l] + w[1] * lobe[i, 1, l] + w[2] * lobe[i + 1, 0, l] + w[3] * lobe[i + 1, 1, l]
    if view_alpha.shape[0] == 0:
        va[0] = 1.0
    else:
        i, w, _ = _hermite(alpha, alpha_min, view_alpha.shape[0])
        for r in range(va.shape[0]):
            va[r] = (w[0] * view_alpha[i, 0, r] + w[1] * view_alpha[i, 1, r] + w[2] * view_alpha[i + 1, 0, r]
                     + w[3] * view_alpha[i + 1, 1, r])


@numba.njit(cache=True, inline="always")
def _grid_metallic(m, r, lo, n_slots, t0, order, radiance, r0_dielectric, rise, fixed, diffuse, sums, cost, best,
                   out):  # pragma: no cover - compiled
    """One metallic value of the grid at roughness r for a group's lanes: ``B = base slope + offset``
    per channel is linear in the base colour once (r, m) are fixed, so each lane's base colour is its
    least-squares one, clipped to [0, 1]; a lane whose L1 cost beats ``best`` takes (base, r, m)
    into ``out`` (`freqbrdf.estimate.optimise.compiled.grid_kernel`'s order: first of ties)."""
    width = cost.shape[0]
    n_obs = order.shape[0]
    for i in range(6):
        for q in range(width):
            sums[i, q] = 0.0
    for k in range(n_slots):
        for c in range(3):
            for q in range(width):
                slope = (1.0 - m) * diffuse[k, c, q] + m * rise[k, c, q]
                offset = r0_dielectric * (1.0 - m) * rise[k, c, q] + fixed[k, c, q]
                sums[c, q] += slope * (radiance[lo + k, c, q] - offset)
                sums[3 + c, q] += slope * slope
    for c in range(3):
        for q in range(width):
            sums[c, q] = min(1.0, max(0.0, sums[c, q] / max(sums[3 + c, q], 1e-12)))  # the base colour
    for q in range(width):
        cost[q] = 0.0
    for k in range(n_slots):
        for c in range(3):
            for q in range(width):
                slope = (1.0 - m) * diffuse[k, c, q] + m * rise[k, c, q]
                offset = r0_dielectric * (1.0 - m) * rise[k, c, q] + fixed[k, c, q]
                cost[q] += abs(slope * sums[c, q] + offset - radiance[lo + k, c, q])
    for q in range(min(width, n_obs - t0)):
        if cost[q] < best[q]:
            best[q] = cost[q]
            s = order[t0 + q]
            out[s, 0] = sums[0, q]
            out[s, 1] = sums[1, q]
            out[s, 2] = sums[2, q]
            out[s, 3] = r
            out[s, 4] = m


@numba.njit(parallel=True, cache=True)  # no fast math, as `compiled.grid_kernel`: a start is a discrete choice
def grid_lanes_kernel(order, slot_start, bounds, terms, radiance, schlick, tan2, view_mu, e_pi, masking, alpha_min,
                      r0_dielectric, lobe, view_alpha, geo, src, r_grid, m_grid, max_slots, out):  # pragma: no cover
    width = tan2.shape[1]
    n_obs = e_pi.shape[0]
    n_deg = terms.shape[1]
    n_src = src.shape[1]
    rank = view_mu.shape[1]
    dtype = terms.dtype
    for blk in numba.prange(bounds.shape[0] - 1):
        f = np.empty(n_deg, dtype)
        va = np.empty(rank)
        par = np.zeros((_VA + 2 * rank, width))
        shade = np.empty((n_src, 6, width))
        pw = np.empty((_PW_ROWS, width))
        sd = np.empty((2, 3 * width), dtype)
        acc = np.zeros((12, width))
        tmp = np.empty((2, width))
        # per slot, channel and lane: the specular term's two parts and d E / pi (`compiled.grid_kernel`)
        rise = np.empty((max_slots, 3, width))
        fixed = np.empty((max_slots, 3, width))
        diffuse = np.empty((max_slots, 3, width))
        sums = np.empty((6, width))  # per channel: the base colour's numerator and denominator
        cost = np.empty(width)
        best = np.empty(width)
        for grp in range(bounds[blk], bounds[blk + 1]):
            t0 = grp * width
            lo, hi = slot_start[grp], slot_start[grp + 1]
            for q in range(width):
                best[q] = np.inf
            for r in r_grid:
                alpha = max(r * r, alpha_min)
                _shared_setup(alpha, alpha_min, lobe, view_alpha, n_deg, f, va)
                for q in range(width):
                    s = order[min(t0 + q, n_obs - 1)]
                    par[_ALPHA, q] = alpha
                    for j in range(n_src):
                        t2 = src[s, j, 0]
                        gi = 2.0 / (1.0 + np.sqrt(1.0 + alpha * alpha * t2))
                        for c in range(3):
                            shade[j, c, q] = src[s, j, 1 + c] * gi
                            shade[j, 3 + c, q] = 0.0
                for h in range(rank):
                    for q in range(width):
                        par[_VA + h, q] = va[h]
                        par[_VA + rank + h, q] = 0.0
                for k in range(lo, hi):
                    _view_factors(k, tan2, schlick, view_mu, masking, par, pw)
                    for i in range(3 * width):
                        sd[0, i] = 0.0
                    for l in range(n_deg):
                        for i in range(3 * width):
                            sd[0, i] += f[l] * terms[k, l, i]
                    if n_src > 0:
                        _sources(k, geo, shade, par, pw, tmp, acc)
                    for c in range(3):
                        for q in range(width):
                            spec = sd[0, c * width + q]
                            a = pw[0, q] * spec
                            b = pw[1, q] * spec
                            if n_src > 0:
                                a += acc[4 * c, q]
                                b += acc[4 * c + 1, q]
                            rise[k - lo, c, q] = a
                            fixed[k - lo, c, q] = b
                            diffuse[k - lo, c, q] = e_pi[order[min(t0 + q, n_obs - 1)], c] * pw[4, q]
                for m in m_grid:
                    _grid_metallic(m, r, lo, hi - lo, t0, order, radiance, r0_dielectric, rise, fixed, diffuse, sums,
                                   cost, best, out)

