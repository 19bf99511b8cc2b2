"""Compiled (numba) inner loops of the gradient-descent estimator's model (its objective, grid
start, LM sweeps and the posterior's curvature), called through `freqbrdf.estimate.optimise.kernels`, which checks their
arguments and documents them; the light's are in `freqbrdf.estimate.optimise.compiled_light`, the
loops that share nothing with the model (TV, Adam's update, the sources' geometry) in
`freqbrdf.estimate.optimise.compiled_steps`.

Kept in one file on purpose: numba's on-disk cache (``cache=True``) is invalidated by
the defining file's modification only, so a kernel inlining a helper (or reading a constant)
from another file would keep running its stale compiled copy after that helper changed.

Every output element is written by exactly one iteration of a parallel loop and no
reduction crosses iterations, so results do not depend on the number of threads.
"""

from __future__ import annotations

import numba
import numpy as np

__all__ = ["l1_kernel", "grid_kernel", "lm_kernel", "information_kernel"]

# Levenberg-Marquardt damping: x 1/3 after a kept step, x 4 after a rejected one, within [1e-6, 1e6]
_LM_DOWN, _LM_UP, _LM_MIN, _LM_MAX = 1.0 / 3.0, 4.0, 1e-6, 1e6
# Fast math without "reassoc", "nnan" and "ninf" (the Cholesky's positive-pivot test must
# still see a NaN), and for the LM sweeps without "contract" either: with reassociation, and
# in lm_kernel with contraction into fused multiply-adds, the code numba compiled in a process
# and the code it loaded from its cache rounded differently, so a fresh run's numbers depended
# on which of its jobs compiled a kernel first (tests/test_optimise.py runs every method
# compiled, then cached). Contraction makes l1_kernel faster (docs/estimator.md, Cost).
_FAST = {"nsz", "arcp", "afn", "contract"}
_FAST_LM = _FAST - {"contract"}
# The helpers that are neither inlined nor kernels (`_hermite`, `_view_basis`) fix their own
# flags: numba would compile them once, with the flags of whichever kernel calls them first
# (l1_kernel's fast math or grid_kernel's none), and a kernel's numbers then hung on that order.


@numba.njit(cache=True, fastmath=False)  # not inlined: numba's parfor array analysis fails on its tuples
def _hermite(alpha, alpha_min, nodes):  # pragma: no cover - compiled
    """Cubic Hermite interpolation in ``log alpha`` over ``nodes`` even nodes of ``[log alpha_min, 0]``:
    the node i below alpha, and the weights of (value_i, slope_i, value_i+1, slope_i+1), slopes
    in ``d / d log alpha``, for the value (w) and for ``d / d alpha`` (d)."""
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
def _lobe(alpha, alpha_min, table, f, fd):  # pragma: no cover - compiled
    """``f[l]``, the lobe's zonal spectrum at ``alpha``, and ``fd[l] = df/dalpha``.

    An empty ``table`` is the paper's ``exp(-(alpha l)^2)``, with one exp (``q^(l^2)``,
    ``q = exp(-alpha^2)``); otherwise the cubic Hermite interpolant of `freqbrdf.sphere.lobes.lobe_table`
    in ``log alpha`` over ``[log alpha_min, 0]``, its derivative exact for the interpolant.
    """
    if table.shape[0] == 0:
        q = np.exp(-alpha * alpha)
        step = q  # q^(2l - 1)
        value = 1.0
        for l in range(f.shape[0]):
            f[l] = value
            fd[l] = -2.0 * alpha * l * l * value
            value *= step
            step *= q * q
        return
    i, w, d = _hermite(alpha, alpha_min, table.shape[0])
    for l in range(f.shape[0]):
        a, ma, b, mb = table[i, 0, l], table[i, 1, l], table[i + 1, 0, l], table[i + 1, 1, l]
        f[l] = w[0] * a + w[1] * ma + w[2] * b + w[3] * mb
        fd[l] = d[0] * a + d[1] * ma + d[2] * b + d[3] * mb


@numba.njit(cache=True, inline="always")
def _masking(alpha, tan2, masking):  # pragma: no cover - compiled
    """Smith ``G1(theta_o)`` and ``dG1/dalpha`` (1 and 0 without masking)."""
    if not masking:
        return 1.0, 0.0
    root = np.sqrt(1.0 + alpha * alpha * tan2)
    g1 = 2.0 / (1.0 + root)
    return g1, -g1 * g1 * alpha * tan2 / (2.0 * root)


@numba.njit(cache=True, inline="always")
def _view_weights(view, i, w, d, mu, g1, dg1, c5):  # pragma: no cover - compiled
    """``a, b`` and the diffuse factor of `freqbrdf.sphere.lobes.view_table` at the texel's alpha (Hermite
    node ``i``, weights ``w``, ``d`` of `_hermite`) and ``mu = cos theta_o`` (linear), then their
    derivatives in alpha; a one-component table holds the diffuse factor only, ``a`` and ``b``
    are then the paper's ``(1 - c5) G1m`` and ``c5 G1m`` (``g1``, ``dg1``: `_masking` at theta_o)."""
    x = mu * (view.shape[3] - 1)
    j = min(int(x), view.shape[3] - 2)
    tj = x - j
    k = view.shape[2] - 1  # the diffuse factor is the last component
    dif, ddif = _table_point(view, k, i, j, tj, w), _table_point(view, k, i, j, tj, d)
    if k == 0:
        return (1.0 - c5) * g1, c5 * g1, dif, (1.0 - c5) * dg1, c5 * dg1, ddif
    return (_table_point(view, 0, i, j, tj, w), _table_point(view, 1, i, j, tj, w), dif,
            _table_point(view, 0, i, j, tj, d), _table_point(view, 1, i, j, tj, d), ddif)


@numba.njit(cache=True, inline="always")
def _table_point(view, k, i, j, tj, w):  # pragma: no cover - compiled
    """Component k of ``view`` with Hermite weights ``w`` at alpha node i, linear between columns j, j + 1."""
    lo = w[0] * view[i, 0, k, j] + w[1] * view[i, 1, k, j] + w[2] * view[i + 1, 0, k, j] + w[3] * view[i + 1, 1, k, j]
    hi = (w[0] * view[i, 0, k, j + 1] + w[1] * view[i, 1, k, j + 1] + w[2] * view[i + 1, 0, k, j + 1]
          + w[3] * view[i + 1, 1, k, j + 1])
    return (1.0 - tj) * lo + tj * hi


@numba.njit(cache=True, fastmath=False)  # not inlined: numba's parfor array analysis fails on its tuples
def _view_basis(alpha, alpha_min, view):  # pragma: no cover - compiled
    """`_hermite` at alpha on the nodes of ``view`` (unused weights for the paper's empty table)."""
    if view.shape[0] == 0:
        zero = (0.0, 0.0, 0.0, 0.0)
        return 0, zero, zero
    return _hermite(alpha, alpha_min, view.shape[0])


@numba.njit(cache=True, inline="always")
def _model(m, base, e_pi, r0_dielectric, work, c):  # pragma: no cover - compiled
    """``B = (1 - m) base d E / pi + R0 work[0] + work[1]`` of channel c (``d = work[4]``, `_pair_terms`),
    ``R0 = r0_dielectric (1 - m) + m base``."""
    return (1.0 - m) * base * e_pi * work[4, c] + (r0_dielectric * (1.0 - m) + m * base) * work[0, c] + work[1, c]


@numba.njit(cache=True, inline="always")
def _pair_terms(alpha, f, fd, light, n, schlick, tan2, masking, view, vi, vw, vd, work, geo, shade,
                slopes):  # pragma: no cover - compiled
    """Per channel of pair n, the specular term split as ``R0 work[0] + work[1]``, in ``work[2]``,
    ``work[3]`` their derivatives in alpha, in ``work[4]`` and ``work[5]`` the diffuse factor d and
    its derivative.

    With an empty ``view``, the paper's ``F G1m Spec``: ``work[0] = (1 - c5) G1m Spec``,
    ``work[1] = c5 G1m Spec``, ``d = 1``; otherwise ``a Spec``, ``b Spec`` and ``d``
    (`freqbrdf.sphere.lobes.view_table`; ``vi``, ``vw``, ``vd`` from `_hermite` at alpha), ``a`` and
    ``b`` the paper's if the table holds ``d`` only. Then the point sources add their own
    microfacet terms (`_point_sources`, ``shade`` from `_source_shading` of the pair's texel).
    Without ``slopes`` (a constant at each call, so the compiler drops the other branch) only the
    values: ``work[0]``, ``work[1]`` and ``work[4]``, the same bits, for the callers that need no
    derivative (the grid start, a trial step's cost).
    """
    if view.shape[0] == 0 or view.shape[2] == 1 or shade.shape[0]:
        g1, dg1 = _masking(alpha, tan2[n], masking)  # once: the paper's weight and the sources both need it
    else:
        g1, dg1 = 1.0, 0.0
    if view.shape[0] == 0:
        c5 = schlick[n]
        u, v, du, dv, dif, ddif = (1.0 - c5) * g1, c5 * g1, (1.0 - c5) * dg1, c5 * dg1, 1.0, 0.0
    else:
        u, v, dif, du, dv, ddif = _view_weights(view, vi, vw, vd, 1.0 / np.sqrt(1.0 + tan2[n]), g1, dg1,
                                                schlick[n])
    # the three channels' sums side by side: six independent chains of additions instead of two
    # at a time waiting on each addition's latency; each sum keeps its order
    s0 = s1 = s2 = d0 = d1 = d2 = 0.0
    for l in range(f.shape[0]):
        s0 += f[l] * light[n, l, 0]
        s1 += f[l] * light[n, l, 1]
        s2 += f[l] * light[n, l, 2]
        if slopes:
            d0 += fd[l] * light[n, l, 0]
            d1 += fd[l] * light[n, l, 1]
            d2 += fd[l] * light[n, l, 2]
    _pair_specular(u, v, du, dv, dif, ddif, s0, d0, work, 0, slopes)
    _pair_specular(u, v, du, dv, dif, ddif, s1, d1, work, 1, slopes)
    _pair_specular(u, v, du, dv, dif, ddif, s2, d2, work, 2, slopes)
    if shade.shape[0]:
        _point_sources(alpha, geo, n, g1, dg1, shade, work, slopes)


@numba.njit(cache=True, inline="always")
def _pair_specular(u, v, du, dv, dif, ddif, s, d, work, c, slopes):  # pragma: no cover - compiled
    """Channel c of `_pair_terms`' ``work`` from the lobe-filtered light ``s`` and its derivative ``d``."""
    work[0, c] = u * s
    work[1, c] = v * s
    work[4, c] = dif
    if slopes:
        work[2, c] = du * s + u * d
        work[3, c] = dv * s + v * d
        work[5, c] = ddif


@numba.njit(cache=True, inline="always")
def _source_shading(alpha, src, s, shade):  # pragma: no cover - compiled
    """Per point source j of texel s, its power times ``G1(theta_i)`` at alpha in ``shade[j, :3]``
    and times ``dG1/dalpha`` in ``shade[j, 3:]``: the same for every pair of the texel."""
    for j in range(shade.shape[0]):
        gi, dgi = _masking(alpha, src[s, j, 0], True)  # src[s, j, 0] is 0 without shadowing: G1 = 1
        for c in range(3):
            shade[j, c] = src[s, j, 1 + c] * gi
            shade[j, 3 + c] = src[s, j, 1 + c] * dgi


@numba.njit(cache=True, inline="always")
def _point_sources(alpha, geo, n, gm, dgm, shade, work, slopes):  # pragma: no cover - compiled
    """Add the point sources to the specular parts of pair n (`_pair_terms`): each source's GGX
    microfacet BRDF times cos theta_i, ``D G1(theta_i) G1m F / (4 cos theta_o)`` with Schlick's
    ``F = R0 (1 - c5h) + c5h`` at the half vector, times its power; ``geo[n, j]`` the
    half vector's ``sin^2 theta_h``, ``c5h`` and ``1 / (4 cos theta_o)``
    (`freqbrdf.estimate.optimise.model.pair_source_geometry`), ``shade`` the power times G1 and
    its derivative (`_source_shading`), ``gm``, ``dgm`` G1m and its derivative."""
    a2 = alpha * alpha
    # per channel, the sources' sum of power G1 D / (4 cos theta_o) and of its derivative in
    # alpha, each split by Schlick's (1 - c5h) and c5h: in scalars, not through ``work``
    v0 = v1 = v2 = w0 = w1 = w2 = dv0 = dv1 = dv2 = dw0 = dw1 = dw2 = 0.0
    for j in range(shade.shape[0]):
        inv4o = geo[n, j, 2]
        if inv4o <= 0.0:
            continue
        sin2_h = geo[n, j, 0]
        c5h = geo[n, j, 1]
        inv_t = 1.0 / (sin2_h + (1.0 - sin2_h) * a2)
        ndf = a2 * inv_t * inv_t / np.pi * inv4o  # D / (4 cos theta_o)
        dndf = 2.0 * alpha * inv_t * inv_t / np.pi * (1.0 - 2.0 * a2 * (1.0 - sin2_h) * inv_t) * inv4o
        q = ndf * gm
        dq = dndf * gm + ndf * dgm
        value, slope = shade[j, 0] * q, shade[j, 0] * dq + shade[j, 3] * q
        v0 += value * (1.0 - c5h)
        w0 += value * c5h
        dv0 += slope * (1.0 - c5h)
        dw0 += slope * c5h
        value, slope = shade[j, 1] * q, shade[j, 1] * dq + shade[j, 4] * q
        v1 += value * (1.0 - c5h)
        w1 += value * c5h
        dv1 += slope * (1.0 - c5h)
        dw1 += slope * c5h
        value, slope = shade[j, 2] * q, shade[j, 2] * dq + shade[j, 5] * q
        v2 += value * (1.0 - c5h)
        w2 += value * c5h
        dv2 += slope * (1.0 - c5h)
        dw2 += slope * c5h
    _add_sources(v0, w0, dv0, dw0, work, 0, slopes)
    _add_sources(v1, w1, dv1, dw1, work, 1, slopes)
    _add_sources(v2, w2, dv2, dw2, work, 2, slopes)


@numba.njit(cache=True, inline="always")
def _add_sources(v, w, dv, dw, work, c, slopes):  # pragma: no cover - compiled
    """Add channel c of `_point_sources`' sums to ``work`` (the slopes only with ``slopes``)."""
    work[0, c] += v
    work[1, c] += w
    if slopes:
        work[2, c] += dv
        work[3, c] += dw


@numba.njit(cache=True, inline="always")
def _residual(m, x, s, e_pi, r0_dielectric, work, radiance, n, c, write_model, model):  # pragma: no cover - compiled
    """Channel c of pair n in `l1_kernel`: the residual's sign, the residual, and the sign times
    the model's derivative in alpha; the model radiance into ``model`` if ``write_model``."""
    value = _model(m, x[s, c], e_pi[s, c], r0_dielectric, work, c)
    if write_model:
        model[n, c] = value
    res = value - radiance[n, c]
    g = np.sign(res)
    slope = ((r0_dielectric * (1.0 - m) + m * x[s, c]) * work[2, c] + work[3, c]
             + (1.0 - m) * x[s, c] * e_pi[s, c] * work[5, c])
    return g, res, g * slope


@numba.njit(cache=True, inline="always")
def _colour_gradient(m, x, s, e_pi, r0_dielectric, diffuse, rise, c, grad):  # pragma: no cover - compiled
    """Texel s's gradient in base colour c, and channel c's part of it in metallic, from the sums over
    its pairs of the residuals' signs times the diffuse factor (``diffuse``) and the specular rise."""
    grad[s, c] = (1.0 - m) * e_pi[s, c] * diffuse + m * rise
    grad[s, 4] += -x[s, c] * e_pi[s, c] * diffuse + (x[s, c] - r0_dielectric) * rise


@numba.njit(parallel=True, cache=True, fastmath=_FAST)
def l1_kernel(x, start, light, radiance, schlick, tan2, e_pi, masking, alpha_min, r0_dielectric, lobe, view, geo,
              src, bounds, grad, loss, model):  # pragma: no cover - compiled
    n_deg = light.shape[1]
    write_model = model.shape[0] > 0
    # blocks of texels (``bounds``: `freqbrdf.estimate.optimise.compiled_steps.block_bounds`), so that
    # the scratch arrays are allocated once per block, and each thread's share holds as many pairs
    for blk in numba.prange(bounds.shape[0] - 1):
        f = np.empty(n_deg)
        fd = np.empty(n_deg)
        work = np.empty((6, 3))  # per channel: the model's view-dependent factors and their derivatives (`_pair_terms`)
        shade = np.empty((src.shape[1], 6))  # per point source: power times G1 and its derivative (`_source_shading`)
        for s in range(bounds[blk], bounds[blk + 1]):
            r = x[s, 3]
            m = x[s, 4]
            alpha = max(r * r, alpha_min)
            _lobe(alpha, alpha_min, lobe, f, fd)
            _source_shading(alpha, src, s, shade)
            vi, vw, vd = _view_basis(alpha, alpha_min, view)
            sum_d = 0.0
            total = 0.0
            # the sums over pairs in scalars, not in an array the compiler must store at every pair
            diffuse0 = diffuse1 = diffuse2 = rise0 = rise1 = rise2 = 0.0
            for n in range(start[s], start[s + 1]):
                _pair_terms(alpha, f, fd, light, n, schlick, tan2, masking, view, vi, vw, vd, work, geo, shade, True)
                g0, res0, d0 = _residual(m, x, s, e_pi, r0_dielectric, work, radiance, n, 0, write_model, model)
                g1, res1, d1 = _residual(m, x, s, e_pi, r0_dielectric, work, radiance, n, 1, write_model, model)
                g2, res2, d2 = _residual(m, x, s, e_pi, r0_dielectric, work, radiance, n, 2, write_model, model)
                total += abs(res0)
                total += abs(res1)
                total += abs(res2)
                sum_d += d0
                sum_d += d1
                sum_d += d2
                diffuse0 += g0 * work[4, 0]
                diffuse1 += g1 * work[4, 1]
                diffuse2 += g2 * work[4, 2]
                rise0 += g0 * work[0, 0]
                rise1 += g1 * work[0, 1]
                rise2 += g2 * work[0, 2]
            grad[s, 4] = 0.0
            _colour_gradient(m, x, s, e_pi, r0_dielectric, diffuse0, rise0, 0, grad)
            _colour_gradient(m, x, s, e_pi, r0_dielectric, diffuse1, rise1, 1, grad)
            _colour_gradient(m, x, s, e_pi, r0_dielectric, diffuse2, rise2, 2, grad)
            grad[s, 3] = sum_d * 2.0 * max(r, np.sqrt(alpha_min))
            loss[s] = total


@numba.njit(parallel=True, cache=True)
def grid_kernel(start, light, radiance, schlick, tan2, e_pi, masking, alpha_min, r0_dielectric, lobe, view, geo, src,
                bounds, r_grid, m_grid, max_pairs, out):  # pragma: no cover - compiled
    n_deg = light.shape[1]
    for blk in numba.prange(bounds.shape[0] - 1):
        f = np.empty(n_deg)
        fd = np.empty(n_deg)
        base = np.empty(3)
        work = np.empty((6, 3))
        shade = np.empty((src.shape[1], 6))
        rise = np.empty((max_pairs, 3))  # the specular term's two parts (`_pair_terms`)
        fixed = np.empty((max_pairs, 3))
        diffuse = np.empty((max_pairs, 3))  # d E / pi
        slope = np.empty((max_pairs, 3))  # B = base slope + offset per pair and channel
        offset = np.empty((max_pairs, 3))
        for s in range(bounds[blk], bounds[blk + 1]):
            lo = start[s]
            k = start[s + 1] - lo
            best = np.inf
            for r in r_grid:
                alpha = max(r * r, alpha_min)
                _lobe(alpha, alpha_min, lobe, f, fd)
                _source_shading(alpha, src, s, shade)
                vi, vw, vd = _view_basis(alpha, alpha_min, view)
                for i in range(k):
                    _pair_terms(alpha, f, fd, light, lo + i, schlick, tan2, masking, view, vi, vw, vd, work, geo, shade, False)
                    for c in range(3):
                        rise[i, c] = work[0, c]
                        fixed[i, c] = work[1, c]
                        diffuse[i, c] = e_pi[s, c] * work[4, c]
                for m in m_grid:
                    # B = base a + b per channel: linear in the base colour once (r, m) are fixed
                    for c in range(3):
                        num = 0.0
                        den = 0.0
                        for i in range(k):
                            slope[i, c] = (1.0 - m) * diffuse[i, c] + m * rise[i, c]
                            offset[i, c] = r0_dielectric * (1.0 - m) * rise[i, c] + fixed[i, c]
                            num += slope[i, c] * (radiance[lo + i, c] - offset[i, c])
                            den += slope[i, c] * slope[i, c]
                        base[c] = min(1.0, max(0.0, num / max(den, 1e-12)))
                    cost = 0.0
                    for i in range(k):
                        for c in range(3):
                            cost += abs(slope[i, c] * base[c] + offset[i, c] - radiance[lo + i, c])
                    if cost < best:
                        best = cost
                        out[s, 0] = base[0]
                        out[s, 1] = base[1]
                        out[s, 2] = base[2]
                        out[s, 3] = r
                        out[s, 4] = m


@numba.njit(cache=True, inline="always")
def _solve_spd5(a, rhs, out):  # pragma: no cover - compiled
    """Solve ``a out = rhs`` for a symmetric positive definite 5x5 ``a`` (Cholesky, in place on ``a``);
    False if a pivot is not positive."""
    for j in range(5):
        d = a[j, j]
        for k in range(j):
            d -= a[j, k] * a[j, k]
        if not d > 0.0:
            return False
        d = np.sqrt(d)
        a[j, j] = d
        for i in range(j + 1, 5):
            v = a[i, j]
            for k in range(j):
                v -= a[i, k] * a[j, k]
            a[i, j] = v / d
    for i in range(5):
        v = rhs[i]
        for k in range(i):
            v -= a[i, k] * out[k]
        out[i] = v / a[i, i]
    for i in range(4, -1, -1):
        v = out[i]
        for k in range(i + 1, 5):
            v -= a[k, i] * out[k]
        out[i] = v / a[i, i]
    return True


@numba.njit(cache=True, inline="always")
def _jacobian_row(m, base, e_pi, r0_dielectric, work, c, dalpha):  # pragma: no cover - compiled
    """Channel c's model radiance (`_model`) differentiated in the texel's base colour c, roughness
    and metallic (the other base colours do not enter it); ``work`` of `_pair_terms` with slopes,
    ``dalpha`` = d alpha / d roughness."""
    j_base = (1.0 - m) * e_pi * work[4, c] + m * work[0, c]
    j_r = ((r0_dielectric * (1.0 - m) + m * base) * work[2, c] + work[3, c]
           + (1.0 - m) * base * e_pi * work[5, c]) * dalpha
    j_m = -base * e_pi * work[4, c] + (base - r0_dielectric) * work[0, c]
    return j_base, j_r, j_m


@numba.njit(cache=True, inline="always")
def _add_outer(h, c, w, j_base, j_r, j_m):  # pragma: no cover - compiled
    """Add ``w`` times the outer product of a Jacobian row (`_jacobian_row`, channel c) to the upper
    triangle of ``h`` (5, 5)."""
    h[c, c] += w * j_base * j_base
    h[c, 3] += w * j_base * j_r
    h[c, 4] += w * j_base * j_m
    h[3, 3] += w * j_r * j_r
    h[3, 4] += w * j_r * j_m
    h[4, 4] += w * j_m * j_m


@numba.njit(cache=True, inline="always")
def _mirror_upper(h):  # pragma: no cover - compiled
    """Copy the upper triangle of the square ``h`` onto its lower one."""
    for q in range(h.shape[0]):
        for q2 in range(q):
            h[q, q2] = h[q2, q]


@numba.njit(parallel=True, cache=True, fastmath=_FAST)
def information_kernel(x, start, light, radiance, schlick, tan2, e_pi, masking, alpha_min, r0_dielectric, lobe, view,
                       geo, src, bounds, info, squares):  # pragma: no cover - compiled
    no_edges = np.zeros(x.shape[0] + 1, np.int64)  # the posterior's curvature is the data term's alone
    for blk in numba.prange(bounds.shape[0] - 1):
        f = np.empty(light.shape[1])
        fd = np.empty(light.shape[1])
        work = np.empty((6, 3))
        shade = np.empty((src.shape[1], 6))
        g = np.empty(5)
        for s in range(bounds[blk], bounds[blk + 1]):
            squares[s] = _irls_system(x[s], x, s, start, light, radiance, schlick, tan2, e_pi, masking, alpha_min,
                                      r0_dielectric, lobe, view, geo, src, no_edges, no_edges, 1.0, 0.0, 0.0, 0.0, f,
                                      fd, work, shade, info[s], g, True)


@numba.njit(cache=True, inline="always")
def _irls_system(xs, x, s, start, light, radiance, schlick, tan2, e_pi, masking, alpha_min, r0_dielectric, lobe,
                 view, geo, src, nb_start, nb, data_scale, tv_scale, irls_floor, tv_floor, f, fd, work, shade,
                 h, g, plain):  # pragma: no cover - compiled
    """Texel s's objective at parameters ``xs`` (5,), its neighbours held at ``x`` (S, 5), and in
    ``h`` (5, 5) and ``g`` (5,) the Gauss-Newton matrix and gradient of its reweighted quadratic
    (see `lm_sweep`); the rest is scratch. A trial step's cost is its objective too: the same sums.
    ``plain`` (a constant at each call): the posterior's ``J^T J`` in ``h``, with the model's own
    derivative in roughness (flat where alpha is clamped, where the solvers' takes ``2 sqrt(alpha_min)``
    so that a texel can leave the clamp), and the squared residual's sum returned."""
    h[:] = 0.0
    g[:] = 0.0
    cost = 0.0
    if s < start.shape[0] - 1:
        lo, hi = start[s], start[s + 1]
        floor = 0.0  # the plain form reweights nothing
        if not plain:
            # IRLS floor relative to the texel's own radiance, so that it means the same in any units
            level = 0.0
            for p in range(lo, hi):
                level += abs(radiance[p, 0]) + abs(radiance[p, 1]) + abs(radiance[p, 2])
            floor = max(irls_floor * level / (3.0 * (hi - lo)), 1e-12)
        r = xs[3]
        m = xs[4]
        alpha = max(r * r, alpha_min)
        dalpha = (2.0 * r if r * r > alpha_min else 0.0) if plain else 2.0 * max(r, np.sqrt(alpha_min))
        _lobe(alpha, alpha_min, lobe, f, fd)
        _source_shading(alpha, src, s, shade)
        vi, vw, vd = _view_basis(alpha, alpha_min, view)
        for p in range(lo, hi):
            _pair_terms(alpha, f, fd, light, p, schlick, tan2, masking, view, vi, vw, vd, work, geo, shade, True)
            for c in range(3):
                res = _model(m, xs[c], e_pi[s, c], r0_dielectric, work, c) - radiance[p, c]
                j_base, j_r, j_m = _jacobian_row(m, xs[c], e_pi[s, c], r0_dielectric, work, c, dalpha)
                if plain:
                    cost += res * res
                    _add_outer(h, c, 1.0, j_base, j_r, j_m)
                    continue
                cost += abs(res)
                # the reweighted quadratic's own gradient: sign(res) above the floor, Huber below
                w = data_scale / max(abs(res), floor)
                g[c] += w * res * j_base
                g[3] += w * res * j_r
                g[4] += w * res * j_m
                _add_outer(h, c, w, j_base, j_r, j_m)
        cost *= data_scale
    for k in range(nb_start[s], nb_start[s + 1]):
        j = nb[k]
        for q in range(5):
            d = xs[q] - x[j, q]
            cost += tv_scale * abs(d)
            w = tv_scale / max(abs(d), tv_floor)
            g[q] += w * d
            h[q, q] += w
    _mirror_upper(h)
    return cost


@numba.njit(cache=True, inline="always")
def _bounded_system(xs, h, g, lam_s, lower, upper, a, rhs):  # pragma: no cover - compiled
    """Fill ``a`` and ``rhs`` with the damped system ``(h + lam_s diag(h)) step = -g`` in which a
    parameter at a bound that the gradient pushes outwards is held there; False if none may move."""
    moving = False
    for q in range(5):
        for q2 in range(5):
            a[q, q2] = h[q, q2]
        a[q, q] += lam_s * h[q, q] + 1e-12
        rhs[q] = -g[q]
    for q in range(5):
        if (xs[q] <= lower[q] and g[q] > 0.0) or (xs[q] >= upper[q] and g[q] < 0.0):
            for q2 in range(5):
                a[q, q2] = 0.0
                a[q2, q] = 0.0
            a[q, q] = 1.0
            rhs[q] = 0.0
        elif g[q] != 0.0:
            moving = True
    return moving


@numba.njit(cache=True, inline="always")
def _predicted_gain(h, g, step):  # pragma: no cover - compiled
    """Decrease of the quadratic ``g.step + step.h.step / 2`` predicts for ``step``."""
    gain = 0.0
    for q in range(5):
        gain -= g[q] * step[q]
        for q2 in range(5):
            gain -= 0.5 * step[q] * h[q, q2] * step[q2]
    return gain


@numba.njit(parallel=True, cache=True, fastmath=_FAST_LM)
def lm_kernel(x, texels, start, light, radiance, schlick, tan2, e_pi, masking, alpha_min, r0_dielectric, lobe, view,
              geo, src, bounds, nb_start, nb, data_scale, tv_scale, lower, upper, irls_floor, tv_floor, lam, tries,
              cost_out):  # pragma: no cover - compiled
    n_deg = light.shape[1]
    for blk in numba.prange(bounds.shape[0] - 1):
        f = np.empty(n_deg)
        fd = np.empty(n_deg)
        work = np.empty((6, 3))
        shade = np.empty((src.shape[1], 6))
        h = np.empty((5, 5))
        g = np.empty(5)
        h_trial = np.empty((5, 5))  # a trial's system, unused: its cost is what counts
        g_trial = np.empty(5)
        a = np.empty((5, 5))
        rhs = np.empty(5)
        step = np.empty(5)
        trial = np.empty(5)
        for i in range(bounds[blk], bounds[blk + 1]):
            s = texels[i]
            cost = _irls_system(x[s], x, s, start, light, radiance, schlick, tan2, e_pi, masking, alpha_min,
                                r0_dielectric, lobe, view, geo, src, nb_start, nb, data_scale, tv_scale, irls_floor,
                                tv_floor, f, fd, work, shade, h, g, False)
            cost_out[i] = cost
            lam_s = lam[s]
            for _ in range(tries):
                if not _bounded_system(x[s], h, g, lam_s, lower, upper, a, rhs):
                    break  # converged, or held by its bounds: nothing to try, damping kept
                if not _solve_spd5(a, rhs, step):
                    lam_s = min(lam_s * _LM_UP, _LM_MAX)
                    continue
                if not _predicted_gain(h, g, step) > 1e-12 * cost:
                    break  # none worth a try once converged
                for q in range(5):
                    trial[q] = min(upper[q], max(lower[q], x[s, q] + step[q]))
                new = _irls_system(trial, x, s, start, light, radiance, schlick, tan2, e_pi, masking, alpha_min,
                                   r0_dielectric, lobe, view, geo, src, nb_start, nb, data_scale, tv_scale,
                                   irls_floor, tv_floor, f, fd, work, shade, h_trial, g_trial, False)
                if new < cost:
                    x[s, :] = trial
                    lam_s = max(lam_s * _LM_DOWN, _LM_MIN)
                    break
                lam_s = min(lam_s * _LM_UP, _LM_MAX)
            lam[s] = lam_s
