"""Does an uncertainty map rank the errors? Sparsification curves and their area (AUSE).

A per-texel uncertainty is useful where its order matches the order of the errors: removing
the most uncertain texels first should lower the mean error of the rest as fast as removing the
largest errors first does (the oracle). The sparsification curve is the mean error of the
texels left after removing a fraction of them, most uncertain first, divided by the mean error
of all; the area between it and the oracle's curve is the AUSE (Ilg et al. 2018, "Uncertainty
estimates and multi-hypotheses networks for optical flow", Sec. 5.1): 0 for an order as good
as the oracle's, that of a random order (a flat curve at 1) for an uninformative one.

Only the order of an uncertainty counts, so any increasing transform of it (``1/sqrt(views)``
of ``-views``) has the same curve. Tied values (a view count) are removed in expectation, as if
in random order among themselves, so a curve does not depend on how a sort breaks ties.
"""

from __future__ import annotations

from collections.abc import Mapping
from statistics import NormalDist

import numpy as np

from freqbrdf.artefacts import Observations
from freqbrdf.util.colour import LUMINANCE

# Fractions of texels removed at which a curve is evaluated: the last keeps 2% of the texels.
FRACTIONS = np.linspace(0.0, 0.98, 50)


def sparsification_curve(uncertainty: np.ndarray, error: np.ndarray, fractions: np.ndarray = FRACTIONS) -> np.ndarray:
    """Mean error of the texels left after removing ``fractions`` of them, most uncertain first.

    Parameters
    ----------
    uncertainty, error : ndarray, shape (N,)
        Per texel; finite. ``error`` >= 0 with a positive mean.
    fractions : ndarray, shape (F,)
        In [0, 1).

    Returns
    -------
    ndarray, shape (F,)
        The mean error of the rest divided by the mean error of all (1 at fraction 0).
        Removing ``k = f N`` texels is taken continuously: within a group of tied
        uncertainties, and across the texel the boundary cuts, the removed error is
        that group's mean times the part removed.
    """
    u, e = _checked(uncertainty, error)
    f = np.asarray(fractions, dtype=np.float64)
    if f.ndim != 1 or f.min() < 0 or f.max() >= 1:
        raise ValueError(f"fractions must be a 1-D array in [0, 1), got {fractions!r}")
    order = np.argsort(-u, kind="stable")
    u, e = u[order], e[order]
    # groups of equal uncertainty, most uncertain first
    starts = np.flatnonzero(np.r_[True, u[1:] != u[:-1]])
    sizes = np.diff(np.r_[starts, len(u)]).astype(np.float64)
    sums = np.add.reduceat(e, starts)
    edges = np.r_[0.0, np.cumsum(sizes)]  # texels removed when whole groups are gone
    removed_at_edges = np.r_[0.0, np.cumsum(sums)]
    k = f * len(e)
    group = np.clip(np.searchsorted(edges, k, side="right") - 1, 0, len(sizes) - 1)
    removed = removed_at_edges[group] + (k - edges[group]) * sums[group] / sizes[group]
    return (e.sum() - removed) / (len(e) - k) / e.mean()


def ause(uncertainty: np.ndarray, error: np.ndarray, fractions: np.ndarray = FRACTIONS) -> float:
    """Area between the sparsification curve of ``uncertainty`` and the oracle's (ordered by ``error``).

    Trapezoids over ``fractions``; 0 for the oracle's order, about the random order's area
    (:func:`random_ause`) for an uninformative one, more for one that ranks errors backwards.
    """
    curve = sparsification_curve(uncertainty, error, fractions)
    oracle = sparsification_curve(error, error, fractions)
    return float(np.trapezoid(curve - oracle, fractions))


def random_ause(error: np.ndarray, fractions: np.ndarray = FRACTIONS) -> float:
    """AUSE of a random order: its expected curve is flat at 1 (every texel tied)."""
    return ause(np.zeros(len(np.asarray(error))), error, fractions)


def partial_pearson(a: np.ndarray, b: np.ndarray, control: np.ndarray) -> float:
    """Pearson's r of ``a`` and ``b`` after removing from each its least-squares line in ``control``.

    What ``a`` says about ``b`` beyond what ``control`` (a view count) already says;
    NaN if a residual is constant.
    """
    from freqbrdf.report.metrics import pearson

    a, b, c = (np.asarray(x, dtype=np.float64).ravel() for x in (a, b, control))
    if not a.shape == b.shape == c.shape:
        raise ValueError(f"samples differ in length: {a.size}, {b.size}, {c.size}")
    design = np.column_stack([np.ones_like(c), c])
    residuals = [x - design @ np.linalg.lstsq(design, x, rcond=None)[0] for x in (a, b)]
    return pearson(*residuals)


def baseline_maps(obs: Observations) -> dict[str, np.ndarray]:
    """Trivial uncertainties of a capture's observed texels (in ``obs.observed`` order), larger = less sure.

    ``views``: minus the number of views that see the texel; ``inv_sqrt_views``: 1/sqrt of it
    (the same order, so the same AUSE, but not the same Pearson r); ``light``: minus the mean
    luminance of the light along the mirror directions of the views that see it.
    """
    observed = obs.observed
    sees = np.asarray(obs.weight)[observed] > 0
    views = sees.sum(axis=1).astype(np.float64)
    luminance = np.asarray(obs.incoming)[observed] @ LUMINANCE
    light = (luminance * sees).sum(axis=1) / views
    return {"views": -views, "inv_sqrt_views": 1.0 / np.sqrt(views), "light": -light}


def uncertainty_scores(maps: Mapping[str, np.ndarray], errors: Mapping[str, np.ndarray]) -> dict[str, float]:
    """``ause_<map>_<error>`` of every uncertainty map against every per-texel error, and
    ``ause_random_<error>``, the expected AUSE of a random order.

    Parameters
    ----------
    maps : mapping
        Name -> per-texel uncertainty, shape (N,), larger = less sure.
    errors : mapping
        Name (``parameter``, ``brdf``) -> per-texel error of the same N texels; an error that
        is 0 everywhere gives NaN scores.
    """
    scores = {}
    for error_name, error in errors.items():
        names = [*maps, "random"]
        if not np.mean(error) > 0:  # a perfect estimate: nothing to rank
            scores |= {f"ause_{name}_{error_name}": float("nan") for name in names}
            continue
        scores |= {f"ause_{name}_{error_name}": ause(values, error) for name, values in maps.items()}
        scores[f"ause_random_{error_name}"] = random_ause(error)
    return scores


def sparsification_curves(maps: Mapping[str, np.ndarray], errors: Mapping[str, np.ndarray],
                          fractions: np.ndarray = FRACTIONS) -> list[dict]:
    """The curves behind :func:`uncertainty_scores`, one record per error, map and fraction.

    Returns
    -------
    list of dict
        ``{"error", "map", "fraction", "value"}``; maps as given, then ``random`` (flat at 1)
        and ``oracle`` (ordered by the error itself).
    """
    records = []
    for error_name, error in errors.items():
        if not np.mean(error) > 0:  # a perfect estimate: no curve
            continue
        curves = {name: sparsification_curve(values, error, fractions) for name, values in maps.items()}
        curves["random"] = np.ones(len(fractions))
        curves["oracle"] = sparsification_curve(error, error, fractions)
        records += [{"error": error_name, "map": name, "fraction": float(f), "value": float(v)}
                    for name, curve in curves.items() for f, v in zip(fractions, curve)]
    return records


def _checked(uncertainty: np.ndarray, error: np.ndarray) -> tuple[np.ndarray, np.ndarray]:
    u = np.asarray(uncertainty, dtype=np.float64).ravel()
    e = np.asarray(error, dtype=np.float64).ravel()
    if u.shape != e.shape or len(e) == 0:
        raise ValueError(f"uncertainty and error must be equally long and non-empty, got {u.size} and {e.size}")
    if not (np.isfinite(u).all() and np.isfinite(e).all()):
        raise ValueError("uncertainty and error must be finite")
    if e.min() < 0 or not e.mean() > 0:
        raise ValueError(f"error must be >= 0 with a positive mean, got min {e.min():g}, mean {e.mean():g}")
    return u, e


# Nominal levels of the reliability diagram: a calibrated posterior's central intervals hold these shares.
LEVELS = (0.5, 0.68, 0.8, 0.9, 0.95, 0.99)


def _check_levels(levels: tuple[float, ...]) -> None:
    if not all(0.0 < level < 1.0 for level in levels):
        raise ValueError(f"levels must lie in (0, 1), got {levels}")


def gaussian_widths(levels: tuple[float, ...] = LEVELS) -> np.ndarray:
    """Half-widths, in standard deviations, of a Gaussian's central intervals at ``levels``: (L,)."""
    _check_levels(levels)
    return np.array([NormalDist().inv_cdf(0.5 + level / 2) for level in levels])


def reliability(estimate: np.ndarray, truth: np.ndarray, std: np.ndarray, widths: np.ndarray | None = None,
                levels: tuple[float, ...] = LEVELS) -> dict[float, float]:
    """Observed coverage of the posterior's central intervals at each nominal level.

    A calibrated posterior gives coverage equal to the level at every level (the diagonal of a
    reliability diagram); too narrow intervals fall below it.

    Parameters
    ----------
    estimate, truth, std : numpy.ndarray
        The same shape ``(N, C)`` or ``(N,)``: estimated values, true values, standard deviations (> 0).
    widths : numpy.ndarray, optional
        Half-width of each level's interval in standard deviations, ``(L,)`` or per column ``(L, C)``
        (`conformal_widths`); default the Gaussian's (`gaussian_widths`).
    levels : tuple of float
        Nominal coverages in (0, 1), ``L`` of them.

    Returns
    -------
    dict of float to float
        Level -> share of the values whose truth lies within the level's interval.
    """
    widths = gaussian_widths(levels) if widths is None else np.asarray(widths, dtype=np.float64)
    if widths.shape[0] != len(levels) or not np.all(widths > 0):
        raise ValueError(f"reliability: widths must be > 0, one row per level {levels}, got {widths.tolist()}")
    z = np.abs(np.asarray(estimate, dtype=np.float64) - np.asarray(truth, dtype=np.float64)) / np.asarray(std)
    return {level: float(np.mean(z <= width)) for level, width in zip(levels, widths)}


def conformal_widths(standardised: np.ndarray, levels: tuple[float, ...] = LEVELS) -> np.ndarray:
    """Split-conformal half-widths from calibration errors: for each level p the
    ``ceil((n + 1) p)``-th smallest of the ``n`` standardised errors ``|estimate - truth| / std``.

    An interval of that many standard deviations holds at least the share p of a new value
    exchangeable with the calibration ones (Vovk et al. 2005; Lei et al. 2018, Theorem 2.1).

    Parameters
    ----------
    standardised : numpy.ndarray
        ``(n,)``, finite and >= 0.
    levels : tuple of float
        Nominal coverages in (0, 1).

    Returns
    -------
    numpy.ndarray
        ``(L,)`` half-widths in standard deviations.
    """
    z = np.sort(np.asarray(standardised, dtype=np.float64).ravel())
    if z.size == 0 or not np.all(np.isfinite(z)) or z[0] < 0:
        raise ValueError(f"conformal_widths: standardised errors must be finite and >= 0, got {z.size} values")
    _check_levels(levels)
    ranks = np.minimum(np.ceil((z.size + 1) * np.asarray(levels)).astype(int), z.size)
    return z[ranks - 1]
