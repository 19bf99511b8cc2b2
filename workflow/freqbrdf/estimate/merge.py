"""Uncertainty-guided merge of one object's estimates from several captures (rule merge_svbrdf).

Wiersma et al. 2024, section 5.6 and Table 6: "for every texel, we use the
parameters from the environment with the lowest entropy at that texel". The
entropy is the spectrum entropy of each capture (:mod:`freqbrdf.estimate.spectrum`),
computed without any ground truth, so the merge needs none either. The
paper merges Mitsuba's optimisation results (its Table 6 "Average" row equals
Mitsuba's Table 2 average); the registry has a merge of ``mitsuba`` and one of
``freq`` (:data:`freqbrdf.methods.METHODS`), each naming the map it merges by:
the entropy, or for estimates that carry one, their fit's posterior
(`freqbrdf.estimate.optimise.posterior.expected_error_atlas`), which needs no
ground truth either.
"""

from __future__ import annotations

from collections.abc import Mapping, Sequence

import numpy as np

from freqbrdf.artefacts import Svbrdf
from freqbrdf.sphere.brdf import TEXTURES

__all__ = ["lowest_merge"]


def lowest_merge(
    estimates: Sequence[Mapping[str, np.ndarray]], scores: Sequence[np.ndarray]
) -> tuple[Svbrdf, np.ndarray]:
    """Per texel, the parameters of the estimate whose uncertainty is lowest there.

    Parameters
    ----------
    estimates : sequence of E SVBRDF mappings
        ``base_color`` (R, R, 3), ``roughness`` and ``metallic`` (R, R) of the same
        object from E captures (the same atlas).
    scores : sequence of E ndarray, shape (R, R)
        Each capture's uncertainty atlas, larger = less sure: the entropy (1 where
        unobserved or outside the atlas) or
        `freqbrdf.estimate.optimise.posterior.expected_error_atlas`.

    Returns
    -------
    merged : Svbrdf
        The merged textures. Where several estimates tie for the lowest score (the entropy is 1
        wherever a capture did not observe the texel), their mean: the merge is the same in
        whatever order the estimates come, so it does not depend on the capture it is filed under.
    choice : ndarray, shape (R, R), int
        Index of the estimate each texel was taken from; -1 where several tied and were averaged.
    """
    if len(estimates) == 0 or len(estimates) != len(scores):
        raise ValueError(f"lowest_merge: {len(estimates)} estimates and {len(scores)} uncertainty maps; "
                         "need the same number, at least one")
    h = np.stack([np.asarray(e, dtype=np.float64) for e in scores])
    shape = h.shape[1:]
    for k, estimate in enumerate(estimates):
        if estimate["roughness"].shape != shape:
            raise ValueError(f"lowest_merge: estimate {k} is {estimate['roughness'].shape}, uncertainty maps {shape}")
    if not np.all(np.isfinite(h)):
        raise ValueError("lowest_merge: uncertainty maps hold NaN/Inf values")
    lowest = h == h.min(axis=0)  # (E, R, R)
    tied = lowest.sum(axis=0)
    choice = np.where(tied > 1, -1, np.argmax(lowest, axis=0))
    merged = {}
    for name in TEXTURES:
        textures = [np.asarray(e[name]) for e in estimates]
        stack = np.stack(textures).astype(np.float64)  # (E, R, R[, 3])
        mask = lowest.reshape(lowest.shape + (1,) * (stack.ndim - 3))
        # summed in sorted order, so that the mean of the tied is the same bits in any order of the estimates
        total = np.sort(np.where(mask, stack, 0.0), axis=0).sum(axis=0)
        merged[name] = (total / tied.reshape(mask.shape[1:])).astype(np.result_type(*textures))
    return Svbrdf(**merged), choice
