"""Which views of a capture add nothing to its observations, and why, named in one line.

A view can be read, pass every check of the import and still give no observed
(texel, view) pair: its camera looks away from the object, every pixel is
NaN, its mask misses the object. The estimates then rest on fewer views than
the capture has, which nothing downstream shows; `check_views` names every
such view once extraction knows the per-view counts, and stops the extraction
when fewer views than config ``observations.min_usable_views`` are left.
"""

from __future__ import annotations

from collections.abc import Sequence

import numpy as np

# The config key that sets how many views must give observations.
MIN_USABLE_KEY = "observations.min_usable_views"


def unusable_views(names: Sequence[str], images: np.ndarray, coverage: np.ndarray,
                   candidates: np.ndarray | None = None) -> str:
    """Why each of some views gives no observed pair, as one line grouped by reason.

    Parameters
    ----------
    names : sequence of str
        K view names (or the user's frame files).
    images, coverage : ndarray, shape (K, H, W, 3) and (K, H, W)
        The views (NaN/Inf allowed) and their masks in [0, 1].
    candidates : ndarray, shape (K,), int, optional
        Texels each view's camera has in front of it, inside its image and facing it
        (`freqbrdf.capture.observations.observe`'s ``view_candidates``); 0 names a
        camera that sees no part of the mesh.

    Returns
    -------
    str
        E.g. ``"every pixel is NaN/Inf: 000, 001; mask is empty: 002"``.
    """
    groups: dict[str, list[str]] = {}
    for k, name in enumerate(names):
        finite = np.isfinite(images[k]).all(axis=-1)
        covered = coverage[k] > 0
        if not finite.any():
            why = "every pixel is NaN/Inf"
        elif candidates is not None and candidates[k] == 0:
            why = "the camera sees no part of the mesh (it looks away from the object, or its pose is wrong)"
        elif not covered.any():
            why = "mask is empty"
        elif not (finite & covered).any():
            why = "no finite pixel inside the mask"
        else:
            why = "no texel seen inside the mask (poses, mesh and mask disagree)"
        groups.setdefault(why, []).append(name)
    return "; ".join(f"{why}: {', '.join(views)}" for why, views in groups.items())


def nonfinite_views(names: Sequence[str], images: np.ndarray) -> str:
    """The views with NaN/Inf pixels and how many, in one line ('' when there are none).

    Parameters
    ----------
    names : sequence of str
        K view names.
    images : ndarray, shape (K, H, W, 3)

    Returns
    -------
    str
        E.g. ``"2 of 4 views: 0001 (all 1024 pixels), 0003 (12 of 1024 pixels)"``.
    """
    pixels = images.shape[1] * images.shape[2]
    counts = (~np.isfinite(images)).any(axis=-1).sum(axis=(1, 2))
    named = [f"{name} ({'all' if n == pixels else f'{n} of'} {pixels} pixels)"
             for name, n in zip(names, counts.tolist()) if n]
    return f"{len(named)} of {len(names)} views: {', '.join(named)}" if named else ""


def check_views(names: Sequence[str], observed: np.ndarray, images: np.ndarray, coverage: np.ndarray,
                candidates: np.ndarray | None, *, min_usable: int, source: str) -> str:
    """Name every view without an observed pair; stop when too few views are left.

    Parameters
    ----------
    names : sequence of str
        K view names, as the user knows them (an imported capture's frame files).
    observed : ndarray, shape (K,), int
        Observed (texel, view) pairs of each view.
    images, coverage, candidates
        As in :func:`unusable_views`.
    min_usable : int
        Fewest views that must give observations (config :data:`MIN_USABLE_KEY`).
    source : str
        The capture as the user gave it (its ``transforms_train.json``, or its directory).

    Returns
    -------
    str
        One warning line naming the views without observations, or ``''`` if every view has some.

    Raises
    ------
    ValueError
        One line naming ``source`` and every view without observations, when fewer
        than ``min_usable`` views (or none at all) give observations.
    """
    lost = np.flatnonzero(np.asarray(observed) == 0)
    if not len(lost):
        return ""
    why = unusable_views([names[k] for k in lost], images[lost], coverage[lost],
                         None if candidates is None else np.asarray(candidates)[lost])
    usable = len(names) - len(lost)
    if usable == 0:
        # Every later stage would fail on an empty capture, naming its own artefact instead.
        raise ValueError(f"{source}: no (texel, view) pair is observed; {why}")
    if usable < min_usable:
        raise ValueError(f"{source}: only {usable} of {len(names)} views give an observed (texel, view) pair, "
                         f"fewer than {MIN_USABLE_KEY} = {min_usable}; {why}")
    return (f"{source}: {len(lost)} of {len(names)} views give no observed (texel, view) pair and add nothing "
            f"to the estimates; {why}")
