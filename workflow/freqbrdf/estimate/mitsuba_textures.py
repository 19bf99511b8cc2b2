"""The textures of the differentiable-rendering baseline: its constant start, the check of a start,
and the coarse levels of coarse-to-fine (config ``mitsuba.coarse_levels``), all plain arrays."""

from __future__ import annotations

from collections.abc import Mapping

import numpy as np

from freqbrdf.sphere.brdf import TEXTURES
from freqbrdf.util.validation import check_int

__all__ = ["check_textures", "coarse_textures", "constant_textures", "full_size"]


def constant_textures(resolution: int, value: float = 0.5) -> dict[str, np.ndarray]:
    """Constant start textures (the baseline starts from 0.5, as in the paper's section 5.1).

    Returns
    -------
    dict
        ``base_color`` (R, R, 3), ``roughness`` and ``metallic`` (R, R), float32.
    """
    check_int(resolution, "resolution", 1)
    if not 0.0 <= value <= 1.0:
        raise ValueError(f"constant texture value must be in [0, 1], got {value!r}")
    return {
        "base_color": np.full((resolution, resolution, 3), value, np.float32),
        "roughness": np.full((resolution, resolution), value, np.float32),
        "metallic": np.full((resolution, resolution), value, np.float32),
    }


def check_textures(textures: Mapping[str, np.ndarray]) -> dict[str, np.ndarray]:
    """Validate start textures and return them as float32.

    Parameters
    ----------
    textures : mapping
        ``base_color`` (R, R, 3), ``roughness`` (R, R), ``metallic`` (R, R),
        finite, in [0, 1].

    Raises
    ------
    ValueError
        Naming the texture whose shape or values are wrong.
    """
    missing = [name for name in TEXTURES if name not in textures]
    if missing:
        raise ValueError(f"start textures: missing {missing}")
    out = {name: np.asarray(textures[name], dtype=np.float32) for name in TEXTURES}
    size = out["base_color"].shape[:2]
    for name, texture in out.items():
        wanted = size + ((3,) if name == "base_color" else ())
        if texture.shape != wanted or size[0] != size[1] or size[0] < 1:
            raise ValueError(f"start textures: {name} is {texture.shape}, expected {wanted} with a square size")
        if not np.isfinite(texture).all() or texture.min() < 0.0 or texture.max() > 1.0:
            raise ValueError(f"start textures: {name} values are not finite numbers in [0, 1]")
    return out


def coarse_textures(textures: Mapping[str, np.ndarray], levels: int) -> dict[str, np.ndarray]:
    """The textures at ``1 / 2**levels`` of their resolution: means of ``2**levels`` square blocks.

    Parameters
    ----------
    textures : mapping
        ``base_color`` (R, R, 3), ``roughness`` and ``metallic`` (R, R) (:func:`check_textures`).
    levels : int
        Halvings, >= 0; R must be divisible by ``2**levels``.

    Raises
    ------
    ValueError
        Naming the resolution and the levels when R is not divisible.
    """
    textures = check_textures(textures)
    block = 2 ** check_int(levels, "coarse_levels", 0)
    if block == 1:
        return textures
    r = textures["roughness"].shape[0]
    if r % block:
        raise ValueError(f"mitsuba.coarse_levels {levels}: the textures' {r} texels are not divisible by {block}")
    return {name: t.reshape(r // block, block, r // block, block, *t.shape[2:]).mean(axis=(1, 3)).astype(t.dtype)
            for name, t in textures.items()}


def full_size(texture: np.ndarray, resolution: int) -> np.ndarray:
    """A coarse level's texture (r, r[, C]) at ``resolution`` texels: each texel repeated over its
    block, as the next doublings will (the renderer filters it bilinearly meanwhile)."""
    factor = resolution // texture.shape[0]
    return texture.repeat(factor, axis=0).repeat(factor, axis=1) if factor > 1 else texture
