"""Seeded procedural ground-truth SVBRDF textures in UV space.

The atlas is partitioned into soft Voronoi cells; each cell is one material
(diffuse or metallic, smooth or rough, with its own base colour). The width of
the transitions between cells varies across the atlas, so every texture has
both sharp edges and smooth blends, and low-frequency periodic noise varies
colour and roughness inside a cell. A fine grain (band-limited noise a few
texels across) modulates the base colour, as paint and print do on real
objects; without it structure from motion finds too few distinctive features
to register the views (docs/captures.md, "Poses"). All fields are periodic in u and v,
so seams of the sphere and torus atlases are invisible.

Texel (i, j) of an (H, W) texture sits at uv = ((j + 0.5)/W, (i + 0.5)/H),
the layout Mitsuba's ``bitmap`` texture reads.
"""

from __future__ import annotations

import numpy as np

# (metallic, roughness range) of the four material classes; every texture
# contains each of them at least once.
MATERIAL_CLASSES: dict[str, tuple[float, tuple[float, float]]] = {
    "diffuse_rough": (0.0, (0.55, 0.9)),
    "diffuse_smooth": (0.0, (0.08, 0.3)),
    "metal_smooth": (1.0, (0.08, 0.3)),
    "metal_rough": (1.0, (0.45, 0.8)),
}
SHARP_WIDTH = 1e-5  # softness (squared UV distance) of a sharp Voronoi edge
SMOOTH_WIDTH = 4e-3  # softness of a smooth transition (a few texels at 256)


def uv_grid(resolution: int) -> tuple[np.ndarray, np.ndarray]:
    """Texel-centre coordinates of a square atlas.

    Parameters
    ----------
    resolution : int
        Texture size R (R x R texels).

    Returns
    -------
    u, v : ndarray, shape (R, R)
        ``u`` varies along columns, ``v`` along rows.
    """
    c = (np.arange(resolution) + 0.5) / resolution
    return np.meshgrid(c, c, indexing="xy")


def periodic_noise(u: np.ndarray, v: np.ndarray, rng: np.random.Generator, max_frequency: int = 3, terms: int = 8) -> np.ndarray:
    """Smooth periodic noise, a sum of random integer-frequency cosines.

    Parameters
    ----------
    u, v : ndarray
        Coordinates in [0, 1] (same shape).
    rng : numpy.random.Generator
        Source of the random frequencies and phases.
    max_frequency : int
        Largest integer frequency along either axis.
    terms : int
        Number of cosines.

    Returns
    -------
    ndarray
        Same shape as ``u``, zero mean, values in [-1, 1].
    """
    out = np.zeros_like(u, dtype=np.float64)
    for _ in range(terms):
        ku, kv = rng.integers(-max_frequency, max_frequency + 1, size=2)
        if ku == 0 and kv == 0:
            ku = 1
        out += np.cos(2.0 * np.pi * (ku * u + kv * v) + rng.uniform(0.0, 2.0 * np.pi))
    return out / terms


def _periodic_sq_distance(u: np.ndarray, v: np.ndarray, sites: np.ndarray) -> np.ndarray:
    """Squared toroidal distances from every texel to every site, shape (S, *u.shape)."""
    du = np.abs(u[None] - sites[:, 0, None, None])
    dv = np.abs(v[None] - sites[:, 1, None, None])
    du = np.minimum(du, 1.0 - du)
    dv = np.minimum(dv, 1.0 - dv)
    return du**2 + dv**2


def _base_colour(rng: np.random.Generator, metallic: float) -> np.ndarray:
    """A random plausible base colour: saturated paints for dielectrics, bright tints for metals."""
    hue = rng.uniform(0.0, 1.0)
    if metallic > 0.5:
        saturation, value = rng.uniform(0.0, 0.6), rng.uniform(0.6, 0.95)
    else:
        saturation, value = rng.uniform(0.3, 0.9), rng.uniform(0.15, 0.85)
    k = (np.array([5.0, 3.0, 1.0]) + hue * 6.0) % 6.0
    return value - value * saturation * np.clip(np.minimum(k, 4.0 - k), 0.0, 1.0)


def grain(resolution: int, rng: np.random.Generator, texels: float) -> np.ndarray:
    """Fine periodic noise: white noise blurred by a Gaussian, scaled to [-1, 1].

    Parameters
    ----------
    resolution : int
        Atlas size R.
    rng : numpy.random.Generator
    texels : float
        Standard deviation of the blur, in texels (> 0).

    Returns
    -------
    ndarray, shape (R, R)
        Zero-mean noise, standard deviation 2/3 before clipping to [-1, 1]: a
        high-contrast, blotchy pattern whose corners SIFT finds in every view.
    """
    from scipy.ndimage import gaussian_filter

    if not texels > 0:
        raise ValueError(f"grain size must be > 0 texels, got {texels}")
    noise = gaussian_filter(rng.standard_normal((resolution, resolution)), texels, mode="wrap")
    return np.clip(noise / (1.5 * noise.std()), -1.0, 1.0)


def svbrdf_textures(
    resolution: int, seed: int, cells: int = 10, grain_amplitude: float = 0.0, grain_texels: float = 1.5
) -> dict[str, np.ndarray]:
    """Ground-truth base colour, roughness and metallic textures.

    Parameters
    ----------
    resolution : int
        Texture size R; textures are R x R.
    seed : int
        Seed of every random choice; equal seeds give identical textures.
    cells : int
        Number of material regions (>= 4, one per material class at least).
    grain_amplitude : float
        Relative modulation of the base colour by :func:`grain`, in [0, 1):
        each texel's colour is multiplied by a factor in [1 - a, 1 + a].
    grain_texels : float
        Size of the grain (blur standard deviation, texels).

    Returns
    -------
    dict
        ``base_color`` (R, R, 3), ``roughness`` (R, R) and ``metallic`` (R, R),
        float32 in [0, 1] (Disney/Mitsuba principled parameters; linear base colour).
    """
    if resolution < 8:
        raise ValueError(f"texture resolution must be >= 8, got {resolution}")
    if cells < len(MATERIAL_CLASSES):
        raise ValueError(f"cells must be >= {len(MATERIAL_CLASSES)}, got {cells}")
    if not 0.0 <= grain_amplitude < 1.0:
        raise ValueError(f"grain amplitude must be in [0, 1), got {grain_amplitude}")
    rng = np.random.default_rng(seed)
    u, v = uv_grid(resolution)

    classes = list(MATERIAL_CLASSES)
    kinds = [classes[i % len(classes)] for i in rng.permutation(cells)]
    sites = rng.uniform(0.0, 1.0, size=(cells, 2))
    metallic = np.array([MATERIAL_CLASSES[k][0] for k in kinds])
    roughness = np.array([rng.uniform(*MATERIAL_CLASSES[k][1]) for k in kinds])
    colour = np.stack([_base_colour(rng, m) for m in metallic])

    # Softness varies smoothly over the atlas: about half of the edges are
    # sharp (a step from one texel to the next), the rest blend over several texels.
    blend = np.clip(0.5 + 1.5 * periodic_noise(u, v, rng, max_frequency=1, terms=3), 0.0, 1.0)
    softness = SHARP_WIDTH * (SMOOTH_WIDTH / SHARP_WIDTH) ** blend
    d2 = _periodic_sq_distance(u, v, sites)
    logits = -(d2 - d2.min(axis=0, keepdims=True)) / softness[None]
    weights = np.exp(logits)
    weights /= weights.sum(axis=0, keepdims=True)

    rough_tex = np.einsum("s,s...->...", roughness, weights)
    rough_tex += 0.08 * periodic_noise(u, v, rng)
    metal_tex = np.einsum("s,s...->...", metallic, weights)
    base_tex = np.einsum("sc,s...->...c", colour, weights)
    base_tex *= 1.0 + 0.15 * periodic_noise(u, v, rng)[..., None]
    if grain_amplitude > 0:
        # Drawn last, so the textures without grain are unchanged by it.
        base_tex *= 1.0 + grain_amplitude * grain(resolution, rng, grain_texels)[..., None]
    return {
        "base_color": np.clip(base_tex, 0.0, 1.0).astype(np.float32),
        "roughness": np.clip(rough_tex, 0.0, 1.0).astype(np.float32),
        "metallic": np.clip(metal_tex, 0.0, 1.0).astype(np.float32),
    }


def scatter_to_atlas(resolution: int, texel: np.ndarray, values: np.ndarray, known: np.ndarray | None = None) -> np.ndarray:
    """Per-texel values as an atlas texture, every other texel filled from its nearest known one.

    Filling (instead of leaving zeros) keeps bilinear texture lookups at chart
    borders and in unobserved regions from mixing in meaningless values.

    Parameters
    ----------
    resolution : int
        Atlas size R.
    texel : ndarray, shape (T,)
        Flat texel indices ``i * R + j``.
    values : ndarray, shape (T,) or (T, C)
    known : ndarray, shape (T,), bool, optional
        Which of the T values are estimates (default: all). Unknown ones are
        filled like texels outside the atlas.

    Returns
    -------
    ndarray, shape (R, R) or (R, R, C), float32
    """
    from scipy.ndimage import distance_transform_edt

    values = np.asarray(values, dtype=np.float32)
    known = np.ones(len(texel), dtype=bool) if known is None else np.asarray(known, dtype=bool)
    if not known.any():
        raise ValueError("scatter_to_atlas: no texel has a known value")
    atlas = np.zeros((resolution * resolution,) + values.shape[1:], np.float32)
    have = np.zeros(resolution * resolution, dtype=bool)
    atlas[texel[known]] = values[known]
    have[texel[known]] = True
    have = have.reshape(resolution, resolution)
    atlas = atlas.reshape((resolution, resolution) + values.shape[1:])
    _, (rows, cols) = distance_transform_edt(~have, return_indices=True)
    return atlas[rows, cols]
