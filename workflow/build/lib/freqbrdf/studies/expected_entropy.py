"""Expected entropy of the spectrum search's grid posterior given a light spectrum (numba kernel, NumPy reference).

What it computes and why is explained in :mod:`freqbrdf.studies.view_selection`.
"""

from __future__ import annotations

import numba
import numpy as np

from freqbrdf.util.validation import check_positive, check_shape

__all__ = ["expected_entropy"]

_P_MIN = 1e-9  # hypotheses less likely than this are skipped: error <= n_grid * 1e-9
_X_MIN = -40.0  # exp(-40) = 4e-18: such grid points add nothing to a row's sums
_ROWS = 16  # rows of the expected-entropy kernel per parallel iteration


# exp(x) = 2^k exp(q), |q| <= ln 2 / 2: degree-9 Taylor (relative error 7e-12) and 2^k from
# the exponent bits, arithmetic LLVM vectorises (libm's exp is called one value at a time).
_LOG2E = 1.4426950408889634
_LN2_HI = 0.693145751953125  # ln 2 split so that k * _LN2_HI is exact
_LN2_LO = 1.42860682030941723212e-6


@numba.njit(parallel=True, cache=True, fastmath=True)  # sums reassociated: vectorised
def _expected_entropy(s2, posterior, rows, filters, scale, out):  # pragma: no cover - compiled
    n_rows, n_l = s2.shape
    n_grid = filters.shape[0]
    log_n = np.log(n_grid)
    for blk in numba.prange((n_rows + _ROWS - 1) // _ROWS):
        z = np.empty(n_grid)  # sum_g exp(x_ig) per hypothesis i
        ex = np.empty(n_grid)  # sum_g exp(x_ig) x_ig
        x = np.empty(n_grid)
        e = np.empty(n_grid)
        bits = np.empty(n_grid, np.int64)
        two = bits.view(np.float64)
        likely = np.empty(n_grid, np.int64)
        for r in range(blk * _ROWS, min(n_rows, (blk + 1) * _ROWS)):
            p = posterior[rows[r]]
            z[:] = 1.0  # D_ii = 0: exp(0)
            ex[:] = 0.0
            # D is symmetric: each pair's exp serves both rows
            n_likely = 0
            for i in range(n_grid):
                if p[i] >= _P_MIN:
                    likely[n_likely] = i
                    n_likely += 1
            for i in range(n_grid - 1):
                if p[i] < _P_MIN:
                    # only the pairs with a likely hypothesis j are needed (for row j)
                    for a in range(n_likely):
                        j = likely[a]
                        if j > i:
                            d = 0.0
                            for l in range(n_l):
                                t = filters[i, l] - filters[j, l]
                                d += t * t * s2[r, l]
                            xj = max(-d * scale, _X_MIN)
                            v = np.exp(xj)
                            z[j] += v
                            ex[j] += v * xj
                    continue
                for j in range(i + 1, n_grid):
                    d = 0.0
                    for l in range(n_l):
                        t = filters[i, l] - filters[j, l]
                        d += t * t * s2[r, l]
                    x[j] = max(-d * scale, _X_MIN)  # below, exp adds < 4e-18: clamped, not skipped
                for j in range(i + 1, n_grid):
                    k = np.floor(x[j] * _LOG2E + 0.5)
                    q = x[j] - k * _LN2_HI - k * _LN2_LO
                    e[j] = 1.0 + q * (1.0 + q * (1 / 2 + q * (1 / 6 + q * (1 / 24 + q * (1 / 120 + q * (
                        1 / 720 + q * (1 / 5040 + q * (1 / 40320 + q / 362880))))))))
                    bits[j] = (np.int64(k) + 1023) << 52
                zi, exi = 0.0, 0.0
                for j in range(i + 1, n_grid):
                    v = e[j] * two[j]
                    zi += v
                    exi += v * x[j]
                    z[j] += v
                    ex[j] += v * x[j]
                z[i] += zi
                ex[i] += exi
            h = 0.0
            for i in range(n_grid):
                if p[i] >= _P_MIN:
                    h += p[i] * (np.log(z[i]) - ex[i] / z[i])
            out[r] = min(max(h / log_n, 0.0), 1.0)


def _expected_entropy_numpy(s2: np.ndarray, posterior: np.ndarray, rows: np.ndarray, filters: np.ndarray,
                            scale: float) -> np.ndarray:
    """Reference of `_expected_entropy`: every pair of hypotheses, no skipping."""
    delta = (filters[:, None, :] - filters[None, :, :]) ** 2  # (G, G, L)
    x = -np.einsum("ijl,rl->rij", delta, s2) * scale  # log of the unnormalised p_g given hypothesis i
    log_z = np.log(np.exp(x).sum(axis=2))
    h = log_z - (np.exp(x) * x).sum(axis=2) / np.exp(log_z)
    return np.clip((posterior[rows] * h).sum(axis=1) / np.log(filters.shape[0]), 0.0, 1.0)


def expected_entropy(s2: np.ndarray, posterior: np.ndarray, rows: np.ndarray, filters: np.ndarray, sigma: float,
                     compiled: bool = True) -> np.ndarray:
    """``sum_i p_i H_i``: the normalised entropy the search would find, averaged over the hypotheses.

    Parameters
    ----------
    s2 : numpy.ndarray
        ``(R, lmax)``: squared normalised light spectrum ``(S_L(l) / P_L)^2`` at l = 1..lmax per row.
    posterior : numpy.ndarray
        ``(P, G)``: probabilities over the grid (rows sum to 1).
    rows : numpy.ndarray
        ``(R,)`` int: the posterior row of each spectrum row.
    filters : numpy.ndarray
        ``(G, lmax)``: `freqbrdf.studies.view_selection.SelectionModel.filters`.
    sigma : float
        Noise scale of the normalised objective.
    compiled : bool
        The numba kernel (default; skips hypotheses with p < 1e-9, and its exp is a
        polynomial of relative error 7e-12) or its NumPy reference.

    Returns
    -------
    numpy.ndarray
        ``(R,)`` in [0, 1].
    """
    s2 = np.ascontiguousarray(s2, np.float64)
    posterior = np.ascontiguousarray(posterior, np.float64)
    filters = np.ascontiguousarray(filters, np.float64)
    check_shape(filters, "filters", (None, s2.shape[1]))
    check_shape(posterior, "posterior", (None, filters.shape[0]))
    rows = np.ascontiguousarray(rows, np.int64)
    check_shape(rows, "rows", (s2.shape[0],))
    scale = 0.5 / check_positive(sigma, "sigma") ** 2
    if not compiled:
        return _expected_entropy_numpy(s2, posterior, rows, filters, scale)
    out = np.empty(len(s2))
    _expected_entropy(s2, posterior, rows, filters, scale, out)
    return out
