"""Entropy-guided view selection (rules view_selection and view_selection_sweep): beyond the paper.

Wiersma et al. 2024, section 5.6.3 ("Guiding capture"), leaves as future work
the *expected* decrease of entropy of a view whose image is not known yet. Here
it is computed from what is known without the image:

- the geometry: which texels a candidate view would see and from which
  direction (its sample weight cos(theta_o) and local mirror direction);
- the light: the band-limited environment along those mirror directions, so
  the SH fit of L with the candidate's sample added, hence S_L, is exact
  (a Sherman-Morrison update of the regularised fit of section 4.2, Eq. 12);
- the current estimate: the grid likelihood of the spectrum search (section
  4.5, Eq. 23) of the views taken so far, as the posterior over the grid.

If grid hypothesis i were true, the texel would reflect ``S_B(l) = m_i(l) S_L(l)``
(``m_i = K_s^2 exp(-2 (w l)^2)`` at l >= 1, section 4.4), so the search would see
``D_ig = sum_l (m_i(l) - m_g(l))^2 s_l^2`` over the grid (``s`` the light's
spectrum normalised as in `freqbrdf.estimate.spectrum`) and the entropy ``H_i`` of
``p_g ~ exp(-D_ig / (2 sigma^2))`` (Eqs. 24-25). A texel's expected entropy is
``sum_i p_i H_i`` per channel, combined over channels as the search combines
them (the min of expectations, not the expectation of the min). This is the
noise-free expectation: it measures how well the light seen from the views
separates the hypotheses, not how noisy the radiance will be.

A view's expected decrease is the mean over texels of the drop in expected
entropy it brings; texels it does not see keep theirs, so a view that sees no
texel has an expected decrease of exactly 0. An unobserved texel has entropy 1
(as in the search), and one sample of it leaves it at 1: with degree 0
unpenalised (``sh.penalise_dc: false``) a single sample is fitted by a constant.

`greedy_selection` adds the best view k times. Views whose radiance is known
(a capture's own views) update the posterior once chosen: active capture.

The views are :class:`freqbrdf.studies.candidates.CandidateViews`; the
expectation over the hypotheses is
:func:`freqbrdf.studies.expected_entropy.expected_entropy`.
"""

from __future__ import annotations

from collections.abc import Mapping, Sequence
from dataclasses import dataclass

import numpy as np
import pandas as pd

from freqbrdf.util.threads import set_threads  # numba's thread count is per process: one setter for every kernel
from freqbrdf.sphere.sh import n_coeffs, real_sh, sh_degrees
from freqbrdf.estimate.shfit import mirror_directions, regulariser_diagonal
from freqbrdf.estimate.spectrum import combine_entropy, default_grid, model_filters, residual_width, spectrum_search
from freqbrdf.util.validation import check_choice, check_int, check_positive, check_shape
from freqbrdf.studies.candidates import CandidateViews
from freqbrdf.studies.expected_entropy import expected_entropy

__all__ = ["SelectionModel", "Ranking", "rank_views", "greedy_selection", "farthest_views", "set_threads",
           "ranking_table"]

_CHUNK_VALUES = 1 << 20  # float64 values of one texel chunk's (texel, view, coefficient) arrays


# --------------------------------------------------------------------------
# the model
# --------------------------------------------------------------------------
@dataclass(frozen=True)
class SelectionModel:
    """The SH fit and spectrum search the expectation mirrors (config ``sh`` and ``spectrum``).

    Attributes
    ----------
    lmax : int
        SH degree of the fits.
    regulariser : numpy.ndarray
        ``((lmax+1)^2,)`` diagonal of W (`freqbrdf.estimate.shfit.regulariser_diagonal`).
    lam : float
        Regularisation weight.
    ks, alpha : numpy.ndarray
        Grid axes ``(n_ks,)`` and lobe widths ``(n_alpha,)`` acting on the band-limited
        light (`freqbrdf.estimate.spectrum.residual_width`).
    sigma : float
        Noise scale of the normalised objective.
    combine : str
        Entropy over channels (`freqbrdf.estimate.spectrum.combine_entropy`).
    posterior_min_views : int
        Texels seen by fewer known views keep a uniform posterior.
    """

    lmax: int
    regulariser: np.ndarray
    lam: float
    ks: np.ndarray
    alpha: np.ndarray
    sigma: float
    combine: str
    posterior_min_views: int
    min_relative_power: float = 1e-9

    @classmethod
    def from_config(cls, sh: Mapping[str, object], spectrum: Mapping[str, object], a_prime: float,
                    posterior_min_views: int) -> SelectionModel:
        """The model of config ``sh`` and ``spectrum`` at band limit ``a_prime`` (as `search_fit`).

        Raises
        ------
        ValueError
            Naming ``sh.regulariser: none`` or ``spectrum.normalise: reference``, which it does not mirror.
        """
        if sh["regulariser"] == "none":
            raise ValueError("view selection needs sh.regulariser exp or constant, got 'none'")
        if spectrum["normalise"] != "light":
            raise ValueError(f"view selection needs spectrum.normalise: light, got {spectrum['normalise']!r}")
        ks, alpha = default_grid(spectrum["n_ks"], spectrum["n_alpha"], alpha_min=a_prime)
        return cls(check_int(sh["lmax"], "lmax", 1), regulariser_diagonal(sh["lmax"], sh["regulariser"],
                                                                           bool(sh["penalise_dc"])),
                   check_positive(sh["lambda"], "lambda"), ks, residual_width(alpha, a_prime),
                   check_positive(spectrum["sigma"], "sigma"), check_choice(spectrum["combine"], "combine",
                                                                            ("min", "luminance")),
                   check_int(posterior_min_views, "posterior_min_views", 0))

    @property
    def filters(self) -> np.ndarray:
        """``(G, lmax)``: ``K_s^2 exp(-2 (w l)^2)`` of every grid point at l = 1..lmax."""
        return model_filters(self.ks, self.alpha, self.lmax).reshape(-1, self.lmax)


# --------------------------------------------------------------------------
# SH fits of the chosen views and of one candidate more
# --------------------------------------------------------------------------
def _fit(y: np.ndarray, w: np.ndarray, f: np.ndarray, reg: np.ndarray, lam: float
         ) -> tuple[np.ndarray, np.ndarray, np.ndarray]:
    """The regularised fits of samples ``y`` (t, k, n), ``w`` (t, k), ``f`` (t, k, C), as `fit_sh`.

    Returns the inverse of ``Y^T S Y + lam W`` (t, n, n), the coefficients (t, n, C) and which
    texels have a sample. Where a texel has none and W_00 = 0 the system is singular; its
    inverse is then that of ``lam W + e_0 e_0^T``, a stand-in its callers do not use.
    """
    yw = (y * w[..., None]).transpose(0, 2, 1)  # (t, n, k)
    a = yw @ y
    a += lam * np.diag(reg)
    seen = (w > 0).any(axis=1)
    if reg[0] == 0.0:
        a[~seen, 0, 0] += 1.0
    inverse = np.linalg.inv(a)
    coeffs = inverse @ (yw @ f)
    return inverse, coeffs, seen


def _degree_sums(a: np.ndarray, lmax: int) -> np.ndarray:
    """Sums over m of ``a`` (..., n, ...) along axis 2, per degree: (..., lmax+1, ...)."""
    return np.add.reduceat(a, np.arange(lmax + 1) ** 2, axis=2)


def _spectra_with(inverse: np.ndarray, coeffs: np.ndarray, y: np.ndarray, w: np.ndarray, f: np.ndarray,
                  lmax: int) -> np.ndarray:
    """Power spectra (t, N, lmax+1, C) of the fits with each of N samples added to (t, n, C) ``coeffs``.

    Sherman-Morrison: adding ``w y y^T`` moves the solution by ``u w r / (1 + w y.u)``
    with ``u = A^-1 y`` and residual ``r = f - y.c``; per degree,
    ``S'(l) = S(l) + 2 beta sum_m c u + beta^2 sum_m u^2`` with that step ``beta``.
    """
    u = y @ inverse  # (t, N, n): A^-1 is symmetric
    q = np.einsum("tkn,tkn->tk", u, y)
    beta = (w / (1.0 + w * q))[..., None] * (f - np.einsum("tkn,tnc->tkc", y, coeffs))  # (t, N, C)
    s = _degree_sums(coeffs[:, None, :, :] ** 2, lmax)  # (t, 1, L+1, C)
    # sum_m c u per degree as one product with the coefficients spread over a (n, L+1, C) block diagonal
    t, n, n_ch = coeffs.shape
    block = np.zeros((t, n, lmax + 1, n_ch))
    block[:, np.arange(n), sh_degrees(lmax)] = coeffs
    cu = (u @ block.reshape(t, n, -1)).reshape(t, -1, lmax + 1, n_ch)  # (t, N, L+1, C)
    uu = _degree_sums(u * u, lmax)[..., None]  # (t, N, L+1, 1)
    return s + 2.0 * beta[:, :, None, :] * cu + beta[:, :, None, :] ** 2 * uu


def _normalised(spectra: np.ndarray, min_relative_power: float) -> tuple[np.ndarray, np.ndarray]:
    """Squared spectra at l >= 1 over the total power (..., lmax) and identifiable (...), as
    `freqbrdf.estimate.spectrum.normalised_spectra` (last-but-one axis: degree)."""
    total = spectra.sum(axis=-2)
    ok = np.isfinite(total) & (total > 0) & (total - spectra[..., 0, :] > min_relative_power * total)
    s = spectra[..., 1:, :] / np.where(ok, total, 1.0)[..., None, :]
    return np.moveaxis(s * s, -2, -1), ok


def _posterior(model: SelectionModel, spectra: np.ndarray, seen: np.ndarray, known_views: np.ndarray) -> np.ndarray:
    """Grid posterior (t, C, G) of the spectrum search (Eq. 23) on the known chosen views' spectra
    of B and L (t, L+1, 6); uniform where fewer than ``posterior_min_views`` of them (``known_views``
    (t,)) see the texel."""
    t, n_grid = len(spectra), model.ks.size * model.alpha.size
    search = spectrum_search(spectra[..., 3:], spectra[..., :3], model.ks, model.alpha, sigma=model.sigma,
                             observed=seen, return_objective=True, min_relative_power=model.min_relative_power)
    d = search.objective.reshape(t, n_grid, 3).transpose(0, 2, 1)  # (t, C, G), 0 where not identifiable
    p = np.exp(-(d - d.min(axis=2, keepdims=True)) / (2.0 * model.sigma**2))
    p /= p.sum(axis=2, keepdims=True)
    enough = known_views >= max(model.posterior_min_views, 1)
    return np.where(enough[:, None, None], p, 1.0 / n_grid)


@dataclass(frozen=True)
class Ranking:
    """Expected mean entropy over the texels now and with each candidate added.

    Attributes
    ----------
    current : float
        Expected mean entropy of the chosen views.
    expected : numpy.ndarray
        ``(N,)``: with each view added (``current`` for views already chosen).
    coverage : numpy.ndarray
        ``(N,)``: sum over the texels of each view's sample weight (ties go to the larger).
    """

    current: float
    expected: np.ndarray
    coverage: np.ndarray

    @property
    def decrease(self) -> np.ndarray:
        """``(N,)``: expected decrease of the mean entropy."""
        return self.current - self.expected


def _entropies(model: SelectionModel, views: CandidateViews, chosen: np.ndarray, texels: np.ndarray,
               compiled: bool) -> tuple[np.ndarray, np.ndarray]:
    """Expected entropy (t,) of ``texels`` with the chosen views and (t, N) with each view added
    (the current one for views chosen or not seeing the texel)."""
    known = chosen[views.known[chosen]]
    others = np.setdiff1d(np.arange(len(views)), chosen)
    y = real_sh(mirror_directions(views.wo_local[texels]), model.lmax)  # (t, N, n)
    w = np.asarray(views.weight[texels], np.float64)
    # channels: L, then B (0 for views without an image), sharing directions and weights
    f = np.concatenate([views.incoming[texels], views.radiance[texels]], axis=2)
    inverse, coeffs, seen = _fit(y[:, chosen], w[:, chosen], f[:, chosen], model.regulariser, model.lam)
    spectra_now = _degree_sums(coeffs[:, None] ** 2, model.lmax)  # (t, 1, L+1, 6)
    if len(known) < len(chosen):  # the posterior from the views with images only
        _, known_coeffs, known_seen = _fit(y[:, known], w[:, known], f[:, known], model.regulariser, model.lam)
        spectra_known = _degree_sums(known_coeffs[:, None] ** 2, model.lmax)[:, 0]
    else:
        spectra_known, known_seen = spectra_now[:, 0], seen
    posterior = _posterior(model, spectra_known, known_seen, (w[:, known] > 0).sum(axis=1))  # (t, C, G)
    filters = model.filters
    now = _texel_entropy(model, spectra_now[..., :3], seen[:, None], posterior, filters, compiled)[:, 0]
    spectra = _spectra_with(inverse, coeffs[..., :3], y[:, others], w[:, others], f[:, others, :3], model.lmax)
    # A first sample of a texel (W_00 = 0) is fitted by a constant: not identifiable, entropy stays 1.
    sees = (w[:, others] > 0) & (seen[:, None] | (model.regulariser[0] > 0))
    after = np.repeat(now[:, None], len(views), axis=1)
    after[:, others] = np.where(sees, _texel_entropy(model, spectra, sees, posterior, filters, compiled), now[:, None])
    return now, after


def _chunk_size(n_views: int, model: SelectionModel, chunk: int | None) -> int:
    """Texels per chunk: ``chunk``, or about `_CHUNK_VALUES` (texel, view, coefficient) values."""
    return chunk or max(1, _CHUNK_VALUES // (n_views * n_coeffs(model.lmax)))


def _check_chosen(chosen: Sequence[int], n_views: int) -> np.ndarray:
    chosen = np.asarray(sorted({check_int(int(v), "view", 0) for v in chosen}), np.int64)
    if len(chosen) and chosen[-1] >= n_views:
        raise ValueError(f"chosen view {chosen[-1]} out of range: there are {n_views} views")
    return chosen


def rank_views(model: SelectionModel, views: CandidateViews, chosen: Sequence[int], compiled: bool = True,
               chunk: int | None = None) -> Ranking:
    """Expected mean entropy over the T texels of the chosen views and of each other view added.

    Parameters
    ----------
    model : SelectionModel
    views : CandidateViews
        T texels x N views: the chosen ones and the candidates.
    chosen : sequence of int
        Views taken so far; the known ones among them give the posterior, all of them the light.
    compiled : bool
        The compiled expected-entropy kernel (default) or its NumPy reference.
    chunk : int, optional
        Texels at once (bounds memory); default about 8 MB per (texel, view, coefficient) array.

    Returns
    -------
    Ranking
    """
    n_tex, n_views = views.weight.shape
    chosen = _check_chosen(chosen, n_views)
    now, after = np.empty(n_tex), np.empty((n_tex, n_views))
    step = _chunk_size(n_views, model, chunk)
    for start in range(0, n_tex, step):
        texels = np.arange(start, min(n_tex, start + step))
        now[texels], after[texels] = _entropies(model, views, chosen, texels, compiled)
    return Ranking(float(now.mean()), after.mean(axis=0), views.weight.sum(axis=0))


def _texel_entropy(model: SelectionModel, spectra: np.ndarray, sees: np.ndarray, posterior: np.ndarray,
                   filters: np.ndarray, compiled: bool) -> np.ndarray:
    """Expected entropy (t, N) of light spectra (t, N, L+1, C) under the posterior (t, C, G);
    1 where a view does not see the texel (``sees`` (t, N)) or the light is not identifiable."""
    s2, ok = _normalised(spectra, model.min_relative_power)  # (t, N, C, L), (t, N, C)
    t, n_views, n_ch = ok.shape
    use = ok & sees[..., None]
    h = np.ones((t, n_views, n_ch))
    ti, _, ci = np.nonzero(use)
    h[use] = expected_entropy(s2[use], posterior.reshape(t * n_ch, -1), ti * n_ch + ci, filters, model.sigma,
                              compiled)
    return combine_entropy(h.reshape(-1, n_ch), model.combine).reshape(t, n_views)


def greedy_selection(model: SelectionModel, views: CandidateViews, k: int, chosen: Sequence[int] = (),
                     compiled: bool = True, chunk: int | None = None) -> tuple[list[int], list[Ranking]]:
    """k views added one at a time, each the largest expected decrease of mean entropy.

    Ties (e.g. the first view of an empty set, which leaves every texel at entropy 1) go
    to the larger coverage, then to the lower index. After a pick only the texels it sees
    are evaluated again: elsewhere the fits, the posterior and every expectation are unchanged.

    Parameters
    ----------
    model : SelectionModel
    views : CandidateViews
        The chosen views and the candidates.
    k : int
        Views to add (at most the candidates left).
    chosen : sequence of int
        Views taken already.
    compiled, chunk
        See `rank_views`.

    Returns
    -------
    picks : list of int
        The added views in order.
    rankings : list of Ranking
        The ranking each pick was made from, and the ranking after the last pick (k + 1 in all),
        each equal to `rank_views` of the views chosen by then.
    """
    n_tex, n_views = views.weight.shape
    chosen = list(_check_chosen(chosen, n_views))
    k = min(check_int(k, "k", 0), n_views - len(chosen))
    step = _chunk_size(n_views, model, chunk)
    coverage = views.weight.sum(axis=0)
    now, after = np.empty(n_tex), np.empty((n_tex, n_views))
    stale = np.arange(n_tex)
    picks, rankings = [], []
    for _ in range(k + 1):
        for start in range(0, len(stale), step):
            texels = stale[start : start + step]
            now[texels], after[texels] = _entropies(model, views, np.array(sorted(chosen), np.int64), texels,
                                                    compiled)
        rankings.append(Ranking(float(now.mean()), after.mean(axis=0), coverage))
        if len(picks) == k:
            break
        free = np.setdiff1d(np.arange(n_views), chosen)
        best = int(free[np.lexsort((free, -coverage[free], rankings[-1].expected[free]))[0]])
        picks.append(best)
        chosen.append(best)
        stale = np.nonzero(views.weight[:, best] > 0)[0]
    return picks, rankings


def farthest_views(directions: np.ndarray, k: int) -> np.ndarray:
    """k evenly spread views: farthest-point sampling of their directions from the object.

    Starts from the view nearest the mean direction, then adds the view whose smallest
    angle to those chosen is largest (ties: lower index).

    Parameters
    ----------
    directions : numpy.ndarray
        ``(N, 3)`` unit directions from the object to each camera.
    k : int
        Views to choose (at most N).

    Returns
    -------
    numpy.ndarray
        ``(k,)`` view indices in the order chosen.
    """
    d = np.asarray(directions, np.float64)
    check_shape(d, "directions", (None, 3))
    k = min(check_int(k, "k", 1), len(d))
    picks = [int(np.argmax(d @ d.mean(axis=0)))]
    nearest = d @ d[picks[0]]  # cosine to the nearest chosen view
    for _ in range(k - 1):
        nxt = int(np.argmin(np.where(np.isin(np.arange(len(d)), picks), np.inf, nearest)))
        picks.append(nxt)
        nearest = np.maximum(nearest, d @ d[nxt])
    return np.array(picks, np.int64)


# --------------------------------------------------------------------------
# the ranked candidates (rule view_selection)
# --------------------------------------------------------------------------
def ranking_table(views: CandidateViews, first: int, picks: Sequence[int], rankings: Sequence[Ranking]
                  ) -> pd.DataFrame:
    """The candidates ranked: the greedy picks in order, then the rest by the expected mean entropy
    with each added to the picks.

    Parameters
    ----------
    views : CandidateViews
        The capture's views (the first ``first``) and the candidates.
    first : int
        Number of the capture's views.
    picks, rankings
        `greedy_selection` of the candidates.

    Returns
    -------
    pandas.DataFrame
        One row per candidate: ``rank`` (1 = best), ``view``, ``selected`` (a greedy pick),
        ``expected_mean_entropy`` (after adding it: for a pick, to the capture and the picks before
        it; otherwise to the capture and every pick), ``expected_decrease`` of that addition and
        ``seen_texels`` (the fraction of the sampled texels the view sees).
    """
    last = rankings[-1]
    rest = [v for v in np.argsort(last.expected, kind="stable") if v >= first and v not in picks]
    seen = (views.weight > 0).mean(axis=0)
    rows = [{"view": views.names[v], "selected": True, "expected_mean_entropy": rankings[i + 1].current,
             "expected_decrease": rankings[i].decrease[v], "seen_texels": seen[v]} for i, v in enumerate(picks)]
    rows += [{"view": views.names[v], "selected": False, "expected_mean_entropy": last.expected[v],
              "expected_decrease": last.decrease[v], "seen_texels": seen[v]} for v in rest]
    return pd.DataFrame(rows).rename_axis("rank").reset_index().assign(rank=lambda t: t["rank"] + 1)
