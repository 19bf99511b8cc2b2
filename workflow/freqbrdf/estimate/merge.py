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
        The merged textures.
    choice : ndarray, shape (R, R), int
        Index of the estimate each texel was taken from; ties go to the earliest
        (put the capture the merge is filed under first).
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
    choice = np.argmin(h, axis=0)
    merged = {}
    for name in TEXTURES:
        stack = np.stack([np.asarray(e[name]) for e in estimates])  # (E, R, R[, 3])
        index = choice.reshape((1,) + shape + (1,) * (stack.ndim - 3))
        merged[name] = np.take_along_axis(stack, index, axis=0)[0]
    return Svbrdf(**merged), choice
