"""The spectrum-only estimate and its entropy (rule spectrum_search).

Wiersma et al. 2024, sections 4.4 and 4.5 (Eqs. 14-25, Fig. 4): from the power
spectra of B and L per texel, a grid search over (K_s, alpha) of the
objective ``D``, the normalised entropy of the likelihood ``exp(-D / sigma)``
over the grid (the uncertainty map), and the diffuse albedo from degree 0
(`diffuse_albedo`, Eq. 14).

Normalisation of the objective D
--------------------------------
Both spectra are divided by the light's total power up to lmax,
``P_L = sum_{l=0..lmax} S_L(l)`` (per texel and channel; by Parseval the
integral of the fitted L^2 over the sphere), before
``D = sum_{l=1..lmax} (S_B(l) - K_s^2 exp(-2 (alpha l)^2) S_L(l))^2`` is formed.
Then

- D is dimensionless and invariant to the light's intensity (B and L scale
  together), so ``sigma`` means the same under bright and dim light;
- the normalised light spectrum at l >= 1 is the fraction of the light's
  energy that varies with direction, so a low-contrast or low-frequency light
  gives small normalised spectra, small differences of D over the grid and a
  flat likelihood (high entropy), as paper Fig. 4 (middle) expects;
- a texel with low K_s keeps a small normalised S_B (at most K_s^2 times the
  light's), so its likelihood is flat as well (Fig. 4, bottom).

Dividing by the power at degrees 1..lmax only (excluding l = 0) was rejected:
it inflates the faint directional part of a nearly constant light to unit
power, so a smooth light (a broad lobe over an ambient term, power at l <= 2
only) comes out more certain than a point light (entropy 0.13 instead of 0.69
on the paper's 10 x 10 grid at lmax 8; point light 0.29 either way). Where the light has no power at l >= 1 (more than
``min_relative_power`` of ``P_L``), e.g. a constant or zero light, nothing
about (K_s, alpha) is identifiable: the channel is flagged and its entropy is
exactly 1.
"""

from __future__ import annotations

import dataclasses
from collections.abc import Mapping
from concurrent.futures import ThreadPoolExecutor
from dataclasses import dataclass

import numpy as np

from freqbrdf.artefacts import ShFit
from freqbrdf.util.colour import LUMINANCE
from freqbrdf.util.validation import check_choice, check_int, check_positive, check_shape

COMBINE_MODES = ("min", "luminance")


NORMALISATIONS = ("light", "reference")


def default_grid(n_ks: int = 8, n_alpha: int = 8, alpha_min: float = 0.0) -> tuple[np.ndarray, np.ndarray]:
    """Evenly spaced grid of specular reflectance and lobe width.

    Parameters
    ----------
    n_ks, n_alpha : int
        Grid sizes (8 x 8 in the authors' code, 10 x 10 in paper Fig. 4).
    alpha_min : float
        Smallest alpha, in ``[0, 1)``; the band limit a' is a natural choice,
        since narrower lobes cannot be told apart from it.

    Returns
    -------
    tuple of numpy.ndarray
        ``ks_values`` (n_ks,) = ``k / n_ks`` for ``k = 1..n_ks`` (in (0, 1]),
        ``alpha_values`` (n_alpha,) evenly spaced in ``[alpha_min, 1]``.
    """
    n_ks = check_int(n_ks, "n_ks", 1)
    n_alpha = check_int(n_alpha, "n_alpha", 1)
    alpha_min = float(alpha_min)
    if not (0.0 <= alpha_min < 1.0):
        raise ValueError(f"alpha_min must be in [0, 1), got {alpha_min!r}")
    ks = np.arange(1, n_ks + 1) / n_ks
    alpha = np.linspace(alpha_min, 1.0, n_alpha) if n_alpha > 1 else np.array([alpha_min])
    return ks, alpha


def _check_grid_values(ks_values: np.ndarray, alpha_values: np.ndarray) -> tuple[np.ndarray, np.ndarray]:
    ks = np.asarray(ks_values, dtype=np.float64)
    alpha = np.asarray(alpha_values, dtype=np.float64)
    for name, v in (("ks_values", ks), ("alpha_values", alpha)):
        check_shape(v, name, (None,))
        if v.size == 0 or not np.all(np.isfinite(v)) or (v < 0).any():
            raise ValueError(f"{name} must be a non-empty 1-D array of finite values >= 0, got {v!r}")
    if ks.size * alpha.size < 2:
        raise ValueError(f"the grid needs at least 2 points, got {ks.size} x {alpha.size}")
    return ks, alpha


def residual_width(alpha: np.ndarray, a_prime: float) -> np.ndarray:
    """Lobe width that acts on a light already low-passed by ``exp(-(a' l)^2)``.

    Gaussian SH filters compose by adding squared widths, so the lobe
    ``exp(-(alpha l)^2)`` of the unfiltered light is ``exp(-(w l)^2)`` of the
    pre-filtered one with ``w = sqrt(alpha^2 - a'^2)`` (paper section 4.2: the
    pre-filter a' on the incoming light only). Widths at or below a' give 0:
    the pre-filtered light is itself the narrowest lobe the views resolve.

    Parameters
    ----------
    alpha : numpy.ndarray
        Lobe widths, any shape.
    a_prime : float
        Width of the pre-filter (>= 0).

    Returns
    -------
    numpy.ndarray
        Same shape, float64, in ``[0, alpha]``.
    """
    a = np.asarray(alpha, dtype=np.float64)
    return np.sqrt(np.maximum(a * a - float(a_prime) ** 2, 0.0))


def model_filters(ks_values: np.ndarray, alpha_values: np.ndarray, lmax: int) -> np.ndarray:
    """Spectral filters ``K_s^2 exp(-2 (alpha l)^2)`` of every grid point, degrees 1..lmax.

    Parameters
    ----------
    ks_values : numpy.ndarray
        Shape ``(n_ks,)``.
    alpha_values : numpy.ndarray
        Shape ``(n_alpha,)``.
    lmax : int
        Maximum degree, ``>= 1``.

    Returns
    -------
    numpy.ndarray
        Shape ``(n_ks, n_alpha, lmax)``, float64; last axis is l = 1..lmax.
    """
    ks, alpha = _check_grid_values(ks_values, alpha_values)
    lmax = check_int(lmax, "lmax", 1)
    l = np.arange(1, lmax + 1, dtype=np.float64)
    return ks[:, None, None] ** 2 * np.exp(-2.0 * (alpha[None, :, None] * l) ** 2)


def _to_rows(a: np.ndarray) -> np.ndarray:
    """(T, L, C) -> (T C, L): one row per texel and channel, contiguous."""
    return a.transpose(0, 2, 1).reshape(-1, a.shape[1])


def _from_rows(a: np.ndarray, n_tex: int) -> np.ndarray:
    """(T C, L) -> (T, L, C), inverse of `_to_rows`."""
    return a.reshape(n_tex, -1, a.shape[1]).transpose(0, 2, 1)


def _normalise_rows(
    sb: np.ndarray, sl: np.ndarray, min_relative_power: float
) -> tuple[np.ndarray, np.ndarray, np.ndarray]:
    """`normalised_spectra` on (N, lmax+1) rows (one texel and channel per row)."""
    total = sl.sum(axis=1)
    varying = total - sl[:, 0]
    ok = np.isfinite(total) & (total > 0) & (varying > min_relative_power * total)
    ok &= np.isfinite(sb).all(axis=1)
    scale = np.where(ok, 1.0 / np.where(ok, total, 1.0), 0.0)[:, None]
    return sb[:, 1:] * scale, sl[:, 1:] * scale, ok


def _reference_rows(sb: np.ndarray, sl: np.ndarray) -> tuple[np.ndarray, np.ndarray, np.ndarray, np.ndarray]:
    """The authors' scaling (svbrdf_uncertainty, uncertainty/entropy.py) of (N, lmax+1) spectra rows:
    per-degree power divided by (l + 1).

    Returns the rows at degrees 1..lmax, the weight ``S_B'(0)^2 / lmax`` that
    turns their sum of squared residuals into the reference code's D (the mean
    over degrees times the outgoing DC power squared), and the usable rows.
    """
    scale = 1.0 / np.arange(1, sb.shape[1] + 1)
    b, l = sb * scale, sl * scale
    ok = np.isfinite(b).all(axis=1) & np.isfinite(l).all(axis=1) & (l[:, 1:].sum(axis=1) > 0)
    weight = np.where(ok, b[:, 0] ** 2 / (sb.shape[1] - 1), 0.0)
    return np.where(ok[:, None], b[:, 1:], 0.0), np.where(ok[:, None], l[:, 1:], 0.0), weight, ok


def _check_min_relative_power(value: float) -> float:
    value = float(value)
    if not (np.isfinite(value) and 0.0 <= value < 1.0):
        raise ValueError(f"min_relative_power must be in [0, 1), got {value!r}")
    return value


def normalised_spectra(
    s_b: np.ndarray, s_l: np.ndarray, min_relative_power: float = 1e-9
) -> tuple[np.ndarray, np.ndarray, np.ndarray]:
    """Spectra at degrees 1..lmax divided by the light's total power (degrees 0..lmax).

    Parameters
    ----------
    s_b, s_l : numpy.ndarray
        Shape ``(T, lmax+1, C)``: outgoing and incoming power spectra.
    min_relative_power : float
        A channel is identifiable only if the light's power at degrees >= 1
        exceeds this fraction of its total power (and the total is > 0).

    Returns
    -------
    tuple of numpy.ndarray
        ``b`` and ``l`` of shape ``(T, lmax, C)`` (degrees 1..lmax,
        dimensionless, 0 where not identifiable) and ``identifiable`` ``(T, C)`` bool.
    """
    sb = np.asarray(s_b, dtype=np.float64)
    sl = np.asarray(s_l, dtype=np.float64)
    check_shape(sl, "s_l", (None, None, None))
    check_shape(sb, "s_b", sl.shape)
    if sl.shape[1] < 2:
        raise ValueError(f"spectra need degrees 0..lmax with lmax >= 1, got shape {sl.shape}")
    min_relative_power = _check_min_relative_power(min_relative_power)
    n_tex, _, n_ch = sl.shape
    b, l, ok = _normalise_rows(_to_rows(sb), _to_rows(sl), min_relative_power)
    return _from_rows(b, n_tex), _from_rows(l, n_tex), ok.reshape(n_tex, n_ch)


_SINGLE_THREAD_GEMM = 1 << 17  # M*N*K under which OpenBLAS runs a product on one thread


def _objective_rows(b: np.ndarray, l: np.ndarray, ks: np.ndarray, alpha: np.ndarray) -> np.ndarray:
    """D of (N, lmax) normalised spectra rows on the grid, (N, n_ks * n_alpha), float64.

    The square is expanded, ``D = sum_l b_l^2 + sum_l [b_l s_l, s_l^2] . [-2 m_gl, m_gl^2]``
    with ``m_gl = K_s^2 exp(-2 (alpha l)^2)``, so the grid costs one product
    with a (2 lmax, G) matrix. The product runs in row blocks small enough for
    OpenBLAS to stay on one thread: its worker threads keep spinning after a
    threaded call and slowed the following elementwise work several times on
    2 cores. float64 keeps the cancellation error far below 2 sigma^2.
    """
    lmax = b.shape[1]
    m = model_filters(ks, alpha, lmax).reshape(-1, lmax)
    a = np.concatenate([-2.0 * m, m * m], axis=1).T.copy()  # (2 lmax, G)
    u = np.concatenate([b * l, l * l], axis=1)  # (N, 2 lmax)
    n_rows, n_grid = u.shape[0], a.shape[1]
    d = np.empty((n_rows, n_grid))
    block = max(1, _SINGLE_THREAD_GEMM // (n_grid * a.shape[0]))
    for r in range(0, n_rows, block):
        np.matmul(u[r : r + block], a, out=d[r : r + block])
    d += np.einsum("nl,nl->n", b, b)[:, None]
    np.maximum(d, 0.0, out=d)
    return d


def spectrum_objective(b: np.ndarray, l: np.ndarray, ks_values: np.ndarray, alpha_values: np.ndarray) -> np.ndarray:
    """Objective ``D = sum_{l>=1} (b_l - K_s^2 exp(-2 (alpha l)^2) s_l)^2`` on the grid.

    Parameters
    ----------
    b, l : numpy.ndarray
        Shape ``(T, lmax, C)``: normalised outgoing and incoming spectra at
        degrees 1..lmax (`normalised_spectra`).
    ks_values, alpha_values : numpy.ndarray
        Grid axes ``(n_ks,)`` and ``(n_alpha,)``.

    Returns
    -------
    numpy.ndarray
        Shape ``(T, n_ks, n_alpha, C)``, float64, ``>= 0``.
    """
    b = np.asarray(b, dtype=np.float64)
    l = np.asarray(l, dtype=np.float64)
    check_shape(b, "b", (None, None, None))
    check_shape(l, "l", b.shape)
    ks, alpha = _check_grid_values(ks_values, alpha_values)
    n_tex, _, n_ch = b.shape
    d = _objective_rows(_to_rows(b), _to_rows(l), ks, alpha)
    return d.reshape(n_tex, n_ch, ks.size, alpha.size).transpose(0, 2, 3, 1)


def _entropy_rows(d: np.ndarray, sigma: float, d_min: np.ndarray | None = None) -> np.ndarray:
    """Normalised entropy of ``p ~ exp(-d / (2 sigma^2))`` along the last axis of ``d``.

    ``d_min`` (``d.min(-1)``, if already known) saves a reduction.
    """
    if d_min is None:
        d_min = d.min(axis=-1)
    # x = log p + log z <= 0; float32 is ample once the minimum is subtracted.
    # Clipping at -1e4 (p < e^-10000, i.e. 0) keeps huge D from becoming -inf,
    # whose product with p = 0 would be NaN.
    with np.errstate(over="ignore"):
        x = (d_min[..., None] - d).astype(np.float32)
    x *= np.float32(0.5 / sigma**2)
    np.maximum(x, np.float32(-1e4), out=x)
    e = np.exp(x)
    z = e.sum(axis=-1).astype(np.float64)
    # sum p log p = sum p x - log z, with p = e / z and log p = x - log z
    ex = np.einsum("...g,...g->...", e, x).astype(np.float64)
    h = (np.log(z) - ex / z) / np.log(d.shape[-1])
    return np.where(np.isfinite(h), np.clip(h, 0.0, 1.0), 1.0)


def grid_entropy(objective: np.ndarray, sigma: float = 1e-2) -> np.ndarray:
    """Normalised entropy of the grid likelihood ``p_i ~ exp(-D_i / (2 sigma^2))``.

    Parameters
    ----------
    objective : numpy.ndarray
        Shape ``(T, n_ks, n_alpha, C)``, D from `spectrum_objective`.
    sigma : float
        Noise scale of the (normalised) objective (paper: 1e-2).

    Returns
    -------
    numpy.ndarray
        Shape ``(T, C)``, in ``[0, 1]``: ``-(1/log n) sum_i p_i log p_i`` over
        the ``n = n_ks n_alpha`` grid points (uniform prior, log-sum-exp).
    """
    d = np.asarray(objective, dtype=np.float64)
    check_shape(d, "objective", (None, None, None, None))
    sigma = check_positive(sigma, "sigma")
    n_tex, n_ks, n_alpha, n_ch = d.shape
    if n_ks * n_alpha < 2:
        raise ValueError(f"the grid needs at least 2 points, got {n_ks} x {n_alpha}")
    rows = d.transpose(0, 3, 1, 2).reshape(n_tex, n_ch, n_ks * n_alpha)
    return _entropy_rows(rows, sigma)


def combine_entropy(entropy_rgb: np.ndarray, combine: str = "min") -> np.ndarray:
    """One entropy per texel from per-channel entropies.

    Parameters
    ----------
    entropy_rgb : numpy.ndarray
        Shape ``(T, 3)``.
    combine : {"min", "luminance"}
        ``min``: the most certain channel (authors' code); ``luminance``:
        Rec. 709 weighted mean of the channel entropies.

    Returns
    -------
    numpy.ndarray
        Shape ``(T,)``, in ``[0, 1]``.
    """
    h = np.asarray(entropy_rgb, dtype=np.float64)
    check_shape(h, "entropy_rgb", (None, 3))
    check_choice(combine, "combine", COMBINE_MODES)
    if combine == "min":
        return h.min(axis=1)
    return h @ LUMINANCE


@dataclass(frozen=True)
class SpectrumSearch:
    """Result of `spectrum_search` (T texels, C channels).

    Attributes
    ----------
    ks_index, alpha_index : numpy.ndarray
        ``(T, C)`` int: per-channel argmin of D on the grid.
    ks : numpy.ndarray
        ``(T, C)``: K_s per channel at the joint alpha (argmin of D_c(., alpha)).
    alpha : numpy.ndarray
        ``(T,)``: joint alpha, argmin over the grid of ``sum_c min_ks D_c(ks, alpha)``
        over the identifiable channels (profile likelihood; one lobe width per texel).
    entropy_rgb : numpy.ndarray
        ``(T, C)`` in [0, 1]; exactly 1 where not identifiable or unobserved.
    entropy : numpy.ndarray
        ``(T,)`` in [0, 1], combined over channels (`combine_entropy`; for
        ``C != 3`` the minimum); exactly 1 for unobserved texels.
    identifiable : numpy.ndarray
        ``(T, C)`` bool: the light has power at degrees >= 1 (`normalised_spectra`).
    unobserved : numpy.ndarray
        ``(T,)`` bool: no view observes the texel.
    objective : numpy.ndarray or None
        ``(T, n_ks, n_alpha, C)`` normalised D if requested, else None.

    Where a channel is not identifiable (or the texel unobserved) its D is 0
    everywhere and its estimates are the first grid point: meaningless, see
    the flags.
    """

    ks_index: np.ndarray
    alpha_index: np.ndarray
    ks: np.ndarray
    alpha: np.ndarray
    entropy_rgb: np.ndarray
    entropy: np.ndarray
    identifiable: np.ndarray
    unobserved: np.ndarray
    objective: np.ndarray | None = None


def _check_spectra(s_b: np.ndarray, s_l: np.ndarray) -> tuple[np.ndarray, np.ndarray]:
    """Outgoing and incoming spectra of the same shape (T, lmax+1, C) with lmax >= 1."""
    sb, sl = np.asarray(s_b), np.asarray(s_l)
    check_shape(sl, "s_l", (None, None, None))
    check_shape(sb, "s_b", sl.shape)
    if sl.shape[1] < 2:
        raise ValueError(f"spectra need degrees 0..lmax with lmax >= 1, got shape {sl.shape}")
    return sb, sl


def spectrum_search(
    s_b: np.ndarray,
    s_l: np.ndarray,
    ks_values: np.ndarray,
    alpha_values: np.ndarray,
    sigma: float = 1e-2,
    combine: str = "min",
    observed: np.ndarray | None = None,
    min_relative_power: float = 1e-9,
    chunk: int = 2048,
    workers: int = 1,
    return_objective: bool = False,
    normalise: str = "light",
) -> SpectrumSearch:
    """Spectrum-only estimate of (K_s, alpha) and its entropy (paper sections 4.4-4.5: D of Eq. 19, likelihood Eq. 23, entropy Eqs. 24-25).

    Parameters
    ----------
    s_b, s_l : numpy.ndarray
        Shape ``(T, lmax+1, C)``, lmax >= 1: outgoing and incoming power spectra of the same texels.
    ks_values, alpha_values : numpy.ndarray
        Grid axes ``(n_ks,)`` and ``(n_alpha,)`` (e.g. `default_grid`).
    sigma : float
        ``normalise="light"``: noise scale of the normalised D, ``p ~ exp(-D / (2 sigma^2))``
        (paper: 1e-2); ``"reference"``: the temperature of ``p ~ exp(-(D - D_min) / sigma)``.
    combine : {"min", "luminance"}
        How channel entropies are combined (`combine_entropy`; "luminance" needs C == 3).
    observed : numpy.ndarray, optional
        ``(T,)`` bool; unobserved texels get entropy 1. Default: every texel is observed.
    min_relative_power : float
        See `normalised_spectra`.
    chunk, workers : int
        Texels per chunk (about 1 KB per texel and channel on an 8 x 8 grid) and threads.
    return_objective : bool
        Also return the full normalised D (``T n_ks n_alpha C`` float64 values).
    normalise : {"light", "reference"}
        ``light``: both spectra divided by the light's total power (module
        docstring); ``reference``: as the authors' code (`_reference_rows`).

    Returns
    -------
    SpectrumSearch
    """
    sb, sl = _check_spectra(s_b, s_l)
    n_tex, _, n_ch = sl.shape
    grid = _check_grid_values(ks_values, alpha_values)
    sigma = check_positive(sigma, "sigma")
    check_choice(combine, "combine", COMBINE_MODES)
    if combine == "luminance" and n_ch != 3:
        raise ValueError(f"combine='luminance' needs 3 channels, got {n_ch}")
    chunk, workers = check_int(chunk, "chunk", 1), check_int(workers, "workers", 1)
    min_relative_power = _check_min_relative_power(min_relative_power)
    check_choice(normalise, "normalise", NORMALISATIONS)
    seen = np.ones(n_tex, bool) if observed is None else np.asarray(observed)
    check_shape(seen, "observed", (n_tex,))
    seen = seen.astype(bool)
    out = {"ks_index": np.zeros((n_tex, n_ch), np.int64), "alpha_index": np.zeros((n_tex, n_ch), np.int64),
           "ks": np.zeros((n_tex, n_ch)), "alpha": np.zeros(n_tex), "entropy_rgb": np.ones((n_tex, n_ch)),
           "identifiable": np.zeros((n_tex, n_ch), bool)}
    if return_objective:
        out["objective"] = np.empty((n_tex, grid[0].size, grid[1].size, n_ch))

    def search(start: int) -> None:
        rows = slice(start, min(n_tex, start + chunk))
        found = _search_chunk(sb[rows], sl[rows], seen[rows], grid, sigma, normalise, min_relative_power)
        for name, array in out.items():
            array[rows] = found[name]

    starts = range(0, n_tex, chunk)
    if workers == 1 or len(starts) <= 1:
        for start in starts:
            search(start)
    else:
        # chunks write disjoint slices of the outputs, so threads need no locking
        with ThreadPoolExecutor(max_workers=workers) as pool:
            list(pool.map(search, starts))
    h_rgb = out["entropy_rgb"]
    h_tex = combine_entropy(h_rgb, "luminance") if combine == "luminance" else h_rgb.min(axis=1)
    return SpectrumSearch(entropy=np.where(seen, h_tex, 1.0), unobserved=~seen, objective=out.pop("objective", None),
                          **out)


def _search_chunk(
    sb: np.ndarray, sl: np.ndarray, seen: np.ndarray, grid: tuple[np.ndarray, np.ndarray], sigma: float,
    normalise: str, min_relative_power: float,
) -> dict[str, np.ndarray]:
    """`spectrum_search` of t texels: its per-texel arrays, keyed like `SpectrumSearch`'s fields."""
    ks, alpha = grid
    t, _, n_ch = sl.shape
    n_ks, n_alpha = ks.size, alpha.size
    # one row per (texel, channel): reductions run along contiguous rows
    rows_b, rows_l = _to_rows(sb.astype(np.float64)), _to_rows(sl.astype(np.float64))
    if normalise == "reference":
        b, l, weight, ok = _reference_rows(rows_b, rows_l)
    else:
        b, l, ok = _normalise_rows(rows_b, rows_l, min_relative_power)
    ok = ok.reshape(t, n_ch) & seen[:, None]
    d = _objective_rows(b, l, ks, alpha)
    if normalise == "reference":
        d *= weight[:, None]
    d = d.reshape(t, n_ch, n_ks * n_alpha)
    if not ok.all():
        d[~ok] = 0.0  # flat (uniform) likelihood where nothing is identifiable
    d4 = d.reshape(t, n_ch, n_ks, n_alpha)
    best = d.argmin(axis=2)
    ks_index, alpha_index = np.divmod(best, n_alpha)
    d_min = np.take_along_axis(d, best[..., None], axis=2)[..., 0]
    # the reference code's temperature as the sigma of exp(-D / (2 sigma^2))
    sigma_eff = np.sqrt(sigma / 2.0) if normalise == "reference" else sigma
    # Profile likelihood over channels: one alpha per texel, K_s per channel.
    # The min over K_s runs as a loop of elementwise minima because numpy
    # reduces a short middle axis slowly.
    prof = d4[:, :, 0, :].copy()
    for k in range(1, n_ks):
        np.minimum(prof, d4[:, :, k, :], out=prof)
    a_best = prof.sum(axis=1).argmin(axis=1)  # (t,)
    k_best = d4[np.arange(t), :, :, a_best].argmin(axis=2)  # (t, C)
    return {"ks_index": ks_index, "alpha_index": alpha_index, "ks": ks[k_best], "alpha": alpha[a_best],
            "entropy_rgb": np.where(ok, _entropy_rows(d, sigma_eff, d_min), 1.0), "identifiable": ok,
            "objective": d4.transpose(0, 2, 3, 1)}


def diffuse_albedo(
    b00: np.ndarray, l00: np.ndarray, ks: np.ndarray, irradiance: np.ndarray, unit_dc: np.ndarray | None = None
) -> np.ndarray:
    """Diffuse albedo K_d from degree 0 once K_s is known.

    A Lambertian texel reflects the constant radiance ``K_d E / pi``; the
    specular lobe adds ``K_s L_00`` at degree 0 (its filter is 1 there). So
    ``B_00 = u K_d E / pi + K_s L_00``, where ``u`` is the degree-0 coefficient
    of the constant 1: ``sqrt(4 pi)`` for an exact transform, which is the paper's Eq. 14
    ``B_00 = pi^(-1/2) K_d E' + K_s L_00`` with the paper's hemispherical
    normalisation ``E' = 2 E``. But samples of reflected light cover one
    hemisphere at most, and a fit does not extend constant data on it to a
    constant on the sphere (measured at lmax 6: DC = 0.86 sqrt(4 pi) for 24
    views and ``exp``, 0.97 sqrt(4 pi) for 400 views and ``none``). So pass
    ``unit_dc``, the DC that the same fit gives a channel of ones (append it
    to the B and L channels of `fit_sh`; the fit is linear, so the diffuse
    part is then undone exactly).

    Parameters
    ----------
    b00, l00 : numpy.ndarray
        Shape ``(T, C)``: degree-0 coefficients of the fits of B and L.
    ks : numpy.ndarray
        Shape ``(T,)`` or ``(T, C)``: specular reflectance.
    irradiance : numpy.ndarray
        Shape ``(T, C)``: E (`irradiance_at_normals` or `irradiance_from_coeffs`).
    unit_dc : numpy.ndarray, optional
        Shape ``(T,)``: fitted degree-0 coefficient of the constant 1 (default
        ``sqrt(4 pi)``).

    Returns
    -------
    numpy.ndarray
        Shape ``(T, C)``, float64, unclipped; 0 where ``u E`` is not positive.
    """
    b = np.asarray(b00, dtype=np.float64)
    check_shape(b, "b00", (None, None))
    lc = np.asarray(l00, dtype=np.float64)
    check_shape(lc, "l00", b.shape)
    e = np.asarray(irradiance, dtype=np.float64)
    check_shape(e, "irradiance", b.shape)
    k = np.asarray(ks, dtype=np.float64)
    if k.ndim == 1:
        check_shape(k, "ks", (b.shape[0],))
        k = k[:, None]
    else:
        check_shape(k, "ks", b.shape)
    if unit_dc is None:
        u = np.full((b.shape[0], 1), np.sqrt(4.0 * np.pi))
    else:
        u = np.asarray(unit_dc, dtype=np.float64)
        check_shape(u, "unit_dc", (b.shape[0],))
        u = u[:, None]
    denom = u * e / np.pi
    ok = np.isfinite(denom) & (denom > 0)
    return np.where(ok, (b - k * lc) / np.where(ok, denom, 1.0), 0.0)


def search_fit(fit: ShFit, observed: np.ndarray, settings: Mapping[str, object], workers: int = 1) -> SpectrumSearch:
    """`spectrum_search` of an SH fit with config ``spectrum`` settings (rule spectrum_search).

    The grid's alpha starts at the views' band limit a'. ``S_L`` is of the light pre-filtered
    by a' and ``S_B`` is not, so the grid's lobes act on ``S_L`` with the width that remains
    once a' is accounted for (`residual_width`); the returned ``alpha`` is the lobe's own.
    """
    ks_values, alpha_values = default_grid(settings["n_ks"], settings["n_alpha"], alpha_min=fit.a_prime)
    search = spectrum_search(fit.spectra_outgoing, fit.spectra_incoming, ks_values,
                             residual_width(alpha_values, fit.a_prime), sigma=settings["sigma"],
                             combine=settings["combine"], observed=observed, workers=workers,
                             normalise=settings["normalise"])
    return dataclasses.replace(search, alpha=np.sqrt(search.alpha**2 + fit.a_prime**2))
