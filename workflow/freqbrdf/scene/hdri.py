"""Captured HDR light: environment maps of the npm package ``@pmndrs/assets`` and their clean-up.

The package (:mod:`freqbrdf.scene.assets`) holds Poly Haven environment maps as 512 x 256
EXR files (RGB, half float, lossy DWAB compression) in ``package/hdri/<name>.exr.js``. The
project uses only the twelve of :data:`MAPS`; the package's other maps stay unseen, for
judging generalisation. :func:`read_map` decodes one map.

The maps ring around their suns and lamps: every one has negative texels (up to 13% of a
map's power in negative lobes next to a sun), in the alternating pattern of a sharpening
resampling filter. A map is ground truth for rendering and for estimation alike, so
:func:`clean_envmap` removes the negative texels once, keeping the power of the ringing
neighbourhood (clamping alone would add the negative lobes' power back around every sun).
"""

from __future__ import annotations

import io
from pathlib import Path
from dataclasses import dataclass

import numpy as np
from scipy import ndimage

from freqbrdf.scene.assets import LICENCE, PACKAGE, VERSION, read_member
from freqbrdf.sphere.sampling import equirect_solid_angles

CREDIT = f"Poly Haven (polyhaven.com), via the npm package {PACKAGE} {VERSION}, {LICENCE}"
# The maps the project may use (issue 35); the package's others stay out of every config and test.
MAPS = ("studio", "sunset", "forest", "lobby", "city", "dawn", "warehouse", "sky", "sunrise", "venice",
        "apartment", "hall")


def read_map(tarball: Path, name: str) -> np.ndarray:
    """One environment map of the package, as stored (negative texels included).

    Parameters
    ----------
    tarball : Path
        The package's tarball (:func:`freqbrdf.scene.assets.fetch_package`).
    name : str
        One of :data:`MAPS`.

    Returns
    -------
    ndarray, shape (256, 512, 3), float32
        Equirectangular radiance, rows from the zenith down.

    Raises
    ------
    ValueError
        One line: a name outside :data:`MAPS`, or a member that is missing or not an EXR.
    """
    import OpenEXR

    if name not in MAPS:
        raise ValueError(f"map {name!r} is not one of the maps the project uses: {', '.join(MAPS)}")
    member = f"package/hdri/{name}.exr.js"
    data = read_member(tarball, member)
    try:
        with OpenEXR.File(io.BytesIO(data)) as exr:  # the channels are emptied on closing
            rgb = np.array(exr.channels()["RGB"].pixels, dtype=np.float32)
    except (RuntimeError, OSError, KeyError) as exc:
        raise ValueError(f"{tarball}:{member}: not an RGB EXR ({type(exc).__name__}: {exc})") from None
    return rgb


@dataclass(frozen=True)
class Cleaning:
    """What :func:`clean_envmap` changed in a map.

    Attributes
    ----------
    negative : int
        Texels with a negative channel, set to zero.
    nonfinite : int
        Texels with a NaN or infinite channel, filled from their finite neighbours.
    regions : int
        Neighbourhoods of negative texels whose positive texels were scaled down.
    energy_change : float
        Relative change of the map's power (solid-angle weighted sum over channels).
    """

    negative: int
    nonfinite: int
    regions: int
    energy_change: float

    def __bool__(self) -> bool:
        return bool(self.negative or self.nonfinite)

    def describe(self) -> str:
        """One line for logs and warnings."""
        return (f"{self.negative} negative and {self.nonfinite} non-finite texels cleaned "
                f"({self.regions} regions, power changed by {100 * self.energy_change:+.3f}%)")


def clean_envmap(envmap: np.ndarray, radius: int = 3, max_invalid: float = 0.1,
                 source: str = "environment map") -> tuple[np.ndarray, Cleaning]:
    """An equirect map without negative or non-finite texels, its power kept.

    Non-finite texels take the mean of their finite 8-neighbours (repeated
    until none is left). Negative texels are grouped with every texel within
    ``radius`` of them into regions (8-connected, across the map's azimuth seam
    as two regions); in each region and channel, negative values become zero
    and positive ones are scaled by (net sum / positive sum), both sums solid-angle
    weighted, so a region whose ringing averages to a positive value keeps its
    power exactly; a region with a negative net sum becomes black.

    Parameters
    ----------
    envmap : ndarray, shape (H, 2H, 3)
        Radiance.
    radius : int
        Texels around a negative one that share its region, >= 1.
    max_invalid : float
        The largest fraction of texels that may be negative or non-finite.
    source : str
        Names the map in errors.

    Returns
    -------
    cleaned : ndarray, shape (H, 2H, 3), float32
    cleaning : Cleaning

    Raises
    ------
    ValueError
        One line naming ``source`` when more than ``max_invalid`` of its texels
        are negative or non-finite, or all of them are.
    """
    env = np.array(envmap, dtype=np.float64)
    if env.ndim != 3 or env.shape[2] != 3 or env.shape[1] != 2 * env.shape[0]:
        raise ValueError(f"{source}: shape {env.shape}; an RGB equirect map of (H, 2H, 3) is needed")
    if int(radius) < 1:
        raise ValueError(f"radius must be >= 1, got {radius}")
    weights = equirect_solid_angles(*env.shape[:2])[:, None, None]
    nonfinite = ~np.isfinite(env).all(axis=2)
    negative = (np.nan_to_num(env, nan=0.0, posinf=0.0, neginf=0.0) < 0).any(axis=2) & ~nonfinite
    invalid = int(nonfinite.sum() + negative.sum())
    if invalid > max_invalid * nonfinite.size or nonfinite.all():
        raise ValueError(f"{source}: {invalid} of {nonfinite.size} texels are negative or non-finite "
                         f"(more than {max_invalid:.0%}); the map is refused")
    env = _fill_nonfinite(env, nonfinite)
    before = float((env * weights).sum())
    regions = 0
    if negative.any():
        near = ndimage.binary_dilation(negative, structure=np.ones((2 * radius + 1,) * 2, bool))
        labels, regions = ndimage.label(near, structure=np.ones((3, 3), bool))
        weighted = env * weights
        index = labels[near]
        net = np.stack([np.bincount(index, weighted[near][:, c], regions + 1) for c in range(3)], axis=1)
        positive = np.stack([np.bincount(index, np.maximum(weighted[near][:, c], 0.0), regions + 1)
                             for c in range(3)], axis=1)
        factor = np.clip(np.divide(net, positive, out=np.zeros_like(net), where=positive > 0), 0.0, 1.0)
        env[near] = np.maximum(env[near], 0.0) * factor[index]
    after = float((env * weights).sum())
    cleaning = Cleaning(negative=int(negative.sum()), nonfinite=int(nonfinite.sum()), regions=int(regions),
                        energy_change=(after - before) / before if before > 0 else 0.0)
    return env.astype(np.float32), cleaning


def _fill_nonfinite(env: np.ndarray, holes: np.ndarray) -> np.ndarray:
    """``env`` with the texels of ``holes`` (H, W) set to the mean of their finite 8-neighbours, repeatedly."""
    env = env.copy()
    holes = holes.copy()
    kernel = np.ones((3, 3))
    while holes.any():
        valid = (~holes).astype(np.float64)
        counts = ndimage.convolve(valid, kernel, mode="wrap")
        fill = holes & (counts > 0)
        for c in range(3):
            sums = ndimage.convolve(np.where(holes, 0.0, env[..., c]), kernel, mode="wrap")
            env[..., c][fill] = sums[fill] / counts[fill]
        holes &= ~fill
    return env


def downsample(envmap: np.ndarray, height: int) -> np.ndarray:
    """An equirect map averaged down to ``height`` rows: solid-angle weighted means of k x k blocks.

    Parameters
    ----------
    envmap : ndarray, shape (H, 2H, C)
    height : int
        A divisor of H.

    Returns
    -------
    ndarray, shape (height, 2 height, C), float32
    """
    rows = envmap.shape[0]
    if height < 1 or rows % height:
        raise ValueError(f"envmaps.height {height} must divide the map's {rows} rows")
    k = rows // height
    w = equirect_solid_angles(rows, 2 * rows)[:, None, None]
    weighted = (envmap * w).reshape(height, k, 2 * height, k, -1).sum(axis=(1, 3))
    norm = w.reshape(height, k).sum(axis=1)[:, None, None] * k
    return (weighted / norm).astype(np.float32)
