"""Fewer views, higher error and entropy: the views sweep of paper Fig. 8 (rule views_sweep).

Wiersma et al. 2024, section 5.4 and Fig. 8: the paper drops views from its
synthetic captures and finds parameter MSE and mean entropy rising together,
so the entropy, computed without ground truth, tracks how well a capture
constrains the material. Here a capture's observations are restricted to
seeded random subsets of its training views; each subset gets the band limit
a' of its own count (the incoming light is drawn again from the map) and runs
through the same SH fit, spectrum search and ``freq`` estimator as the pipeline.
"""

from __future__ import annotations

import math
from collections.abc import Mapping, Sequence

import numpy as np

from freqbrdf.artefacts import Observations
from freqbrdf.estimate.light import LightQuadrature
from freqbrdf.estimate.light_table import ShadowedLightTable
from freqbrdf.capture.observations import band_limit_parameter, band_limited_envmap, sample_equirect
from freqbrdf.estimate.optimise.settings import OptimiseSettings
from freqbrdf.estimate.optimise.solve import optimise
from freqbrdf.estimate.shfit import fit_observations, mirror_directions
from freqbrdf.estimate.spectrum import SpectrumSearch, search_fit
from freqbrdf.util.validation import check_int

__all__ = ["view_subsets", "view_subset", "mirror_light", "estimate_subset"]


def view_subsets(n_views: int, counts: Sequence[int], seed: int, subsets: int = 1) -> dict[int, list[np.ndarray]]:
    """Seeded random subsets of ``range(n_views)`` for each count (sorted view indices).

    Parameters
    ----------
    n_views : int
        Views of the capture.
    counts : sequence of int
        Views kept; counts at or above ``n_views`` all mean every view, keyed ``n_views``.
    seed : int
    subsets : int
        Distinct subsets drawn per count (fewer where there are fewer: every view is one subset).

    Returns
    -------
    dict of int to list of ndarray
        Per count, in increasing order, its subsets.

    Raises
    ------
    ValueError
        Naming a count or a number of subsets below 1.
    """
    n_views = check_int(n_views, "n_views", 1)
    subsets = check_int(subsets, "evaluate.views_subsets", 1)
    rng = np.random.default_rng(seed)
    out = {}
    for count in sorted({min(check_int(c, "views count", 1), n_views) for c in counts}):
        drawn: dict[tuple[int, ...], np.ndarray] = {}
        # distinct subsets, as many as there are (2 of 4 views: 6)
        while len(drawn) < min(subsets, math.comb(n_views, count)):
            views = np.sort(rng.choice(n_views, count, replace=False))
            drawn.setdefault(tuple(views.tolist()), views)
        out[count] = list(drawn.values())
    return out


def view_subset(obs: Observations, views: np.ndarray, envmap: np.ndarray, band_limit: str) -> Observations:
    """The observations of the views ``views`` only, as extraction would give them.

    Parameters
    ----------
    obs : Observations
        T texels x K views.
    views : ndarray, shape (k,)
        Indices of the views kept, in order.
    envmap : ndarray, shape (H, W, 3)
        The capture's environment map.
    band_limit : {"paper", "reference"}
        Rule of the band limit a' of k views (:func:`freqbrdf.capture.observations.band_limit_parameter`).

    Returns
    -------
    Observations
        Radiance, weights and directions of the kept views, and the incoming light along
        their mirror directions from the map low-passed at the a' of k views.
    """
    views = np.asarray(views, dtype=np.int64)
    a_prime = band_limit_parameter(len(views), band_limit)
    wo = np.asarray(obs.wo_local[:, views])
    incoming = mirror_light(obs.frame, wo, band_limited_envmap(envmap, a_prime)).astype(np.float32)
    names = [obs.meta["views"][v] for v in views]
    meta = {**obs.meta, "views": names, "band_limit": {"rule": band_limit, "a_prime": a_prime}}
    return Observations(obs.texels, np.asarray(obs.radiance[:, views]), np.asarray(obs.weight[:, views]), wo,
                        incoming, meta)


def mirror_light(frame: np.ndarray, wo_local: np.ndarray, incoming_map: np.ndarray) -> np.ndarray:
    """The light along each pair's world mirror direction (paper section 4.2: L sampled where B is).

    Parameters
    ----------
    frame : ndarray, shape (T, 3, 3)
        Rows tangent, bitangent, normal (world -> local).
    wo_local : ndarray, shape (T, K, 3)
        Unit directions to the cameras in the texel frames.
    incoming_map : ndarray, shape (H, W, 3)
        The band-limited environment map (`band_limited_envmap`).

    Returns
    -------
    ndarray, shape (T, K, 3)
    """
    world = np.einsum("tji,tkj->tki", frame, mirror_directions(wo_local))  # local -> world mirror directions
    return sample_equirect(incoming_map, world)


def estimate_subset(obs: Observations, views: np.ndarray, envmap: np.ndarray, band_limit: str,
                    sh: Mapping[str, object], spectrum: Mapping[str, object], settings: OptimiseSettings,
                    light: LightQuadrature, irradiance: np.ndarray, workers: int = 1,
                    table: ShadowedLightTable | None = None,
                    ) -> tuple[Observations, SpectrumSearch, dict[str, np.ndarray]]:
    """``freq`` on the views ``views`` of a capture, as the pipeline runs it on a whole capture.

    Parameters
    ----------
    obs : Observations
        T texels x K views.
    views : ndarray, shape (k,)
        Indices of the views kept.
    envmap, band_limit
        As in `view_subset`.
    sh, spectrum : mapping
        Config ``sh`` and ``spectrum`` (SH fit, spectrum search and entropy).
    settings, light, irradiance
        The ``freq`` optimiser's settings, light and irradiance
        (:func:`freqbrdf.estimate.optimise.estimate_light` of the whole capture: neither depends on the views).
    workers : int
        Threads.
    table : ShadowedLightTable, optional
        ``light``'s shadowed light tabulated (rule ``light_table``'s; `optimise`'s ``table``).

    Returns
    -------
    sub : Observations
        The subset (`view_subset`).
    search : SpectrumSearch
        Its spectrum search (entropy 1 where no kept view observes a texel).
    estimate : dict
        Per-texel ``base_color`` (T, 3), ``roughness`` and ``metallic`` (T,) of ``freq``.
    """
    sub = view_subset(obs, views, envmap, band_limit)
    search = search_fit(fit_observations(sub, sh, workers), sub.observed, spectrum, workers)
    estimate = optimise(sub, irradiance, light, method="freq", settings=settings, table=table).params
    return sub, search, estimate
