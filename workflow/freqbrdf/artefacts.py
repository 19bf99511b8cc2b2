"""Typed artefacts that rules hand to each other, with one reader and one writer each.

==============  ====================================  =====================  ==========================================
artefact        directory (`freqbrdf.layout`)         written by             read by
==============  ====================================  =====================  ==========================================
`Observations`  ``OBSERVATIONS``                      extract_observations   fit_sh, spectrum_search, optimise_svbrdf,
                                                                             metrics, capture_figure
`ShFit`         ``SH_FIT``                            fit_sh                 spectrum_search
`Svbrdf`        ``ESTIMATE``,                         the estimating rules,  optimise_svbrdf, mitsuba, relight,
                ``OBJECT_TEXTURE`` (ground truth)     build_object           metrics, capture_figure
`Entropy`       ``ENTROPY``                           spectrum_search        metrics, capture_figure
==============  ====================================  =====================  ==========================================

The shadowed light's table of a map (rule ``light_table``) has its reader and writer beside
the code that fits it (`freqbrdf.estimate.light_table`).

Per-texel arrays are in the order of the observations' texels (``texel``:
flat atlas indices ``i * R + j``). Readers check the ``format`` string of the
directories that carry one, and the shapes against each other, and name the
file when something is wrong. Observation arrays are opened as read-only
memory maps: a capture's arrays can be larger than what a rule needs at once.
"""

from __future__ import annotations

import os
from collections.abc import Iterator, Mapping
from dataclasses import dataclass
from pathlib import Path
from typing import Any

import numpy as np

from freqbrdf.sphere.brdf import TEXTURES
from freqbrdf.util.io import read_exr, read_json, write_exr, write_json
from freqbrdf.util.previews import texture_preview
from freqbrdf.util.validation import check_int
from freqbrdf.scene.textures import scatter_to_atlas

OBSERVATIONS_FORMAT = "freqbrdf-observations/1"
SH_FORMAT = "freqbrdf-sh/1"
_OBSERVATION_ARRAYS = {"radiance": 3, "weight": 0, "wo_local": 3, "incoming": 3}  # name -> channels (0: none)
_TEXEL_FIELDS = ("resolution", "texel", "position", "normal", "tangent", "bitangent", "dilated")


@dataclass(frozen=True)
class SurfaceTexels:
    """Surface points of the valid texels of a UV atlas.

    Attributes
    ----------
    resolution : int
        Atlas size R (R x R texels).
    texel : ndarray, shape (T,), int64
        Flat index ``i * R + j`` (row i at v = (i + 0.5)/R, column j at u = (j + 0.5)/R).
    position, normal, tangent, bitangent : ndarray, shape (T, 3)
        World position and orthonormal local frame.
    dilated : ndarray, shape (T,), bool
        Texels outside every chart, filled from the nearest triangle.
    """

    resolution: int
    texel: np.ndarray
    position: np.ndarray
    normal: np.ndarray
    tangent: np.ndarray
    bitangent: np.ndarray
    dilated: np.ndarray

    def __len__(self) -> int:
        return len(self.texel)

    def subset(self, index: slice | np.ndarray) -> SurfaceTexels:
        """The texels selected by ``index`` (a slice or index array)."""
        return SurfaceTexels(
            self.resolution, self.texel[index], self.position[index], self.normal[index],
            self.tangent[index], self.bitangent[index], self.dilated[index],
        )


def _check_format(path: Path, meta: Mapping[str, Any], expected: str) -> None:
    if meta.get("format") != expected:
        raise ValueError(f"{path}: format is {meta.get('format')!r}, expected {expected!r} (rerun the rule that writes it)")


def observed_texels(weight: np.ndarray) -> np.ndarray:
    """Texels that at least one view observes.

    Parameters
    ----------
    weight : numpy.ndarray
        Shape ``(T, K)``: per-view sample weights, 0 where a view does not see the texel.

    Returns
    -------
    numpy.ndarray
        Shape ``(T,)``, bool.
    """
    w = np.asarray(weight)
    if w.ndim != 2:
        raise ValueError(f"weight must have shape (T, K), got shape {w.shape}")
    return (w > 0).any(axis=1)


def sample_texels(candidates: np.ndarray, count: int, seed: int) -> np.ndarray:
    """A seeded random sample of ``count`` of the texel indices ``candidates`` (all if there are fewer).

    Parameters
    ----------
    candidates : numpy.ndarray
        Shape ``(n,)``, int: texel indices to draw from (e.g. the observed ones).
    count : int
        Texels wanted (>= 1).
    seed : int
        Seed of the sample.

    Returns
    -------
    numpy.ndarray
        Sorted texel indices, at most ``count``.

    Raises
    ------
    ValueError
        If there is no candidate.
    """
    candidates = np.asarray(candidates, dtype=np.int64)
    count = check_int(count, "texels", 1)
    if candidates.size == 0:
        raise ValueError("no texel to sample (none observed?)")
    if candidates.size <= count:
        return np.sort(candidates)
    return np.sort(np.random.default_rng(seed).choice(candidates, count, replace=False))


# --------------------------------------------------------------------------
# observations
# --------------------------------------------------------------------------
@dataclass(frozen=True)
class Observations:
    """What each texel of the atlas shows in each view (see :mod:`freqbrdf.capture.observations`).

    Attributes
    ----------
    texels : SurfaceTexels
        The T valid texels and their local frames.
    radiance : numpy.ndarray
        Shape ``(T, K, 3)``: outgoing radiance B, 0 where not observed.
    weight : numpy.ndarray
        Shape ``(T, K)``: cos(theta_o) where observed, else 0.
    wo_local : numpy.ndarray
        Shape ``(T, K, 3)``: unit direction to the camera in the texel frame.
    incoming : numpy.ndarray
        Shape ``(T, K, 3)``: band-limited light along the mirror direction.
    meta : Mapping
        ``views.json``: view names, poses, band limit a', counts.
    """

    texels: SurfaceTexels
    radiance: np.ndarray
    weight: np.ndarray
    wo_local: np.ndarray
    incoming: np.ndarray
    meta: Mapping[str, Any]

    @classmethod
    def from_arrays(cls, radiance: np.ndarray, weight: np.ndarray, wo_local: np.ndarray, frame: np.ndarray,
                    texel: np.ndarray, resolution: int, incoming: np.ndarray | None = None,
                    a_prime: float = 0.0) -> Observations:
        """Observations held in memory (synthetic tests, benchmarks): ``frame`` (T, 3, 3) has rows
        tangent, bitangent, normal; positions are unknown (0) and no texel is dilated."""
        frame = np.asarray(frame)
        texels = SurfaceTexels(int(resolution), np.asarray(texel), np.zeros((len(frame), 3)), frame[:, 2],
                               frame[:, 0], frame[:, 1], np.zeros(len(frame), bool))
        incoming = np.zeros_like(radiance) if incoming is None else incoming
        meta = {"views": [str(k) for k in range(np.shape(weight)[1])], "band_limit": {"a_prime": a_prime}}
        return cls(texels, radiance, weight, wo_local, incoming, meta)

    @property
    def a_prime(self) -> float:
        """Band-limit width a' of the views (paper section 4.2)."""
        return float(self.meta["band_limit"]["a_prime"])

    @property
    def frame(self) -> np.ndarray:
        """Shape ``(T, 3, 3)``: rows tangent, bitangent, normal (world -> local)."""
        t = self.texels
        return np.stack([t.tangent, t.bitangent, t.normal], axis=1)

    @property
    def observed(self) -> np.ndarray:
        """Shape ``(T,)``, bool: texels that at least one view observes."""
        return observed_texels(self.weight)


def read_observations(directory: str | os.PathLike) -> Observations:
    """Read one capture's observations (arrays as read-only memory maps).

    Raises
    ------
    ValueError
        Naming the file whose format or shape is wrong.
    """
    directory = Path(directory)
    meta = read_json(directory / "views.json")
    _check_format(directory / "views.json", meta, OBSERVATIONS_FORMAT)
    with np.load(directory / "texels.npz") as npz:
        missing = [f for f in _TEXEL_FIELDS if f not in npz.files]
        if missing:
            raise ValueError(f"{directory / 'texels.npz'}: lacks {missing}")
        fields = {f: npz[f] for f in _TEXEL_FIELDS}
    texels = SurfaceTexels(int(fields.pop("resolution")), **fields)
    shape = (len(texels), len(meta["views"]))
    arrays = {}
    for name, depth in _OBSERVATION_ARRAYS.items():
        arrays[name] = np.load(directory / f"{name}.npy", mmap_mode="r")
        want = shape + ((depth,) if depth else ())
        if arrays[name].shape != want:
            raise ValueError(f"{directory / name}.npy: shape {arrays[name].shape}, expected {want} (texels, views[, RGB])")
    return Observations(texels=texels, meta=meta, **arrays)


class ObservationsWriter:
    """Writes one capture's observations chunk by chunk, straight into memory maps.

    Parameters
    ----------
    directory : path-like
        An existing, empty directory (e.g. from :func:`freqbrdf.util.io.atomic_directory`).
    texels : SurfaceTexels
        The T texels, in the order of the arrays.
    views : sequence of str
        The K view names.
    """

    def __init__(self, directory: str | os.PathLike, texels: SurfaceTexels, views: list[str]) -> None:
        self.directory, self.texels, self.views = Path(directory), texels, list(views)
        shape = (len(texels), len(views))
        self.arrays = {
            name: np.lib.format.open_memmap(self.directory / f"{name}.npy", mode="w+", dtype=np.float32,
                                            shape=shape + ((depth,) if depth else ()))
            for name, depth in _OBSERVATION_ARRAYS.items()
        }

    def write(self, start: int, chunk: Mapping[str, np.ndarray]) -> None:
        """Store the arrays of texels ``start ... start + len(chunk)`` (keys as in `Observations`)."""
        for name, array in self.arrays.items():
            array[start : start + len(chunk[name])] = chunk[name]

    def views_per_texel(self) -> np.ndarray:
        """Shape ``(T,)``: the number of views observing each texel so far."""
        return (np.asarray(self.arrays["weight"]) > 0).sum(axis=1)

    def close(self, meta: Mapping[str, Any]) -> None:
        """Flush the arrays and write ``texels.npz`` and ``views.json`` (``meta`` plus format and views)."""
        for array in self.arrays.values():
            array.flush()
        self.arrays = {}
        t = self.texels
        np.savez(self.directory / "texels.npz", **{f: getattr(t, f) for f in _TEXEL_FIELDS})
        write_json(self.directory / "views.json", {
            "format": OBSERVATIONS_FORMAT,
            "layout": "see freqbrdf.capture.observations module docstring; arrays are (texel, view[, channel])",
            "views": self.views, "texels": len(t), **meta,
        })


# --------------------------------------------------------------------------
# SH fits
# --------------------------------------------------------------------------
@dataclass(frozen=True)
class ShFit:
    """Per-texel SH fits of B and L (rule fit_sh), in the observations' texel order.

    Attributes
    ----------
    coeffs_outgoing, coeffs_incoming : numpy.ndarray
        Shape ``(T, (lmax+1)^2, 3)``, float32: SH of B and of L about the local mirror direction.
    unit_dc : numpy.ndarray
        Shape ``(T,)``: the DC the same fit gives a constant 1 (:func:`freqbrdf.estimate.spectrum.diffuse_albedo`).
    spectra_outgoing, spectra_incoming : numpy.ndarray
        Shape ``(T, lmax+1, 3)``: power per degree.
    meta : Mapping
        ``fit.json``: settings, a', texel counts.
    """

    coeffs_outgoing: np.ndarray
    coeffs_incoming: np.ndarray
    unit_dc: np.ndarray
    spectra_outgoing: np.ndarray
    spectra_incoming: np.ndarray
    meta: Mapping[str, Any]

    @property
    def a_prime(self) -> float:
        """Band-limit width a' of the observations fitted."""
        return float(self.meta["a_prime"])


_SH_ARRAYS = ("coeffs_outgoing", "coeffs_incoming", "unit_dc", "spectra_outgoing", "spectra_incoming")


def write_sh_fit(directory: str | os.PathLike, fit: ShFit) -> None:
    """Write an `ShFit` (arrays as float32 ``.npy``, ``fit.json`` with its format)."""
    directory = Path(directory)
    for name in _SH_ARRAYS:
        np.save(directory / f"{name}.npy", np.asarray(getattr(fit, name), np.float32))
    write_json(directory / "fit.json", {
        "format": SH_FORMAT,
        "layout": "coeffs_* (texel, (lmax+1)^2 l-major, RGB); spectra_* (texel, lmax+1, RGB); unit_dc (texel,); "
                  "texel order as in the observations' texels.npz; directions: local mirror directions",
        **fit.meta,
    })


def read_sh_fit(directory: str | os.PathLike) -> ShFit:
    """Read an `ShFit`, checking its format and that its arrays agree in texels."""
    directory = Path(directory)
    meta = read_json(directory / "fit.json")
    _check_format(directory / "fit.json", meta, SH_FORMAT)
    arrays = {name: np.load(directory / f"{name}.npy") for name in _SH_ARRAYS}
    n = {name: len(a) for name, a in arrays.items()}
    if len(set(n.values())) != 1:
        raise ValueError(f"{directory}: arrays disagree in the number of texels {n}")
    return ShFit(meta=meta, **arrays)


# --------------------------------------------------------------------------
# SVBRDF textures
# --------------------------------------------------------------------------
@dataclass(frozen=True)
class Svbrdf(Mapping):
    """Base colour ``(R, R, 3)``, roughness and metallic ``(R, R)`` textures, float32 in [0, 1].

    A read-only mapping from the names in `TEXTURES` to the textures, so code
    that takes ``textures[name]`` takes an `Svbrdf`.
    """

    base_color: np.ndarray
    roughness: np.ndarray
    metallic: np.ndarray

    def __post_init__(self) -> None:
        size = self.base_color.shape[:2]
        if self.base_color.shape != size + (3,):
            raise ValueError(f"base_color must have shape (R, R, 3), got {self.base_color.shape}")
        for name in ("roughness", "metallic"):
            if getattr(self, name).shape != size:
                raise ValueError(f"{name} must have shape {size}, got {getattr(self, name).shape}")

    def __getitem__(self, name: str) -> np.ndarray:
        if name not in TEXTURES:
            raise KeyError(name)
        return getattr(self, name)

    def __iter__(self) -> Iterator[str]:
        return iter(TEXTURES)

    def __len__(self) -> int:
        return len(TEXTURES)

    @property
    def resolution(self) -> int:
        """Atlas size R."""
        return int(self.base_color.shape[0])

    @classmethod
    def from_texels(cls, resolution: int, texel: np.ndarray, values: Mapping[str, np.ndarray],
                    known: np.ndarray | None = None) -> Svbrdf:
        """Textures from per-texel values (``base_color`` (T, 3), others (T,)), clipped to [0, 1];
        texels not ``known`` and outside the atlas take their nearest known texel's values."""
        return cls(**{name: np.clip(scatter_to_atlas(resolution, texel, values[name], known), 0.0, 1.0)
                      for name in TEXTURES})

    def at_texels(self, texel: np.ndarray) -> dict[str, np.ndarray]:
        """Per-texel values at flat atlas indices ``texel`` (T,): ``base_color`` (T, 3), others (T,)."""
        n = self.resolution**2
        return {"base_color": self.base_color.reshape(n, 3)[texel],
                "roughness": self.roughness.reshape(n)[texel], "metallic": self.metallic.reshape(n)[texel]}


def write_texture(path: str | os.PathLike, name: str, texture: np.ndarray,
                  preview: str | os.PathLike | None = None) -> None:
    """One texture as EXR at ``path`` and its PNG preview (sRGB for the base colour) at
    ``preview``, by default beside it."""
    path = Path(path)
    write_exr(path, texture)
    texture_preview(path.with_suffix(".png") if preview is None else preview, texture, srgb=(name == "base_color"))


def write_svbrdf(directory: str | os.PathLike, svbrdf: Mapping[str, np.ndarray]) -> None:
    """``{name}.exr`` and ``{name}.png`` of every texture in `TEXTURES`, in ``directory``."""
    for name in TEXTURES:
        write_texture(Path(directory) / f"{name}.exr", name, svbrdf[name])


def read_svbrdf(source: str | os.PathLike | Mapping[str, str | os.PathLike]) -> Svbrdf:
    """Read the textures of `TEXTURES`: ``{name}.exr`` in a directory, or a name -> EXR path mapping.

    Raises
    ------
    ValueError
        Naming the file whose channel count, size or value range is wrong.
    """
    if isinstance(source, Mapping):
        paths = {name: Path(source[name]) for name in TEXTURES}
    else:
        paths = {name: Path(source) / f"{name}.exr" for name in TEXTURES}
    textures = {}
    for name, path in paths.items():
        texture = read_exr(path)
        if name != "base_color" and texture.ndim == 3 and texture.shape[2] == 1:
            texture = texture[..., 0]
        channels = 1 if texture.ndim == 2 else texture.shape[2]
        if channels != (3 if name == "base_color" else 1):
            raise ValueError(f"{path}: {name} texture has {channels} channels, expected {3 if name == 'base_color' else 1}")
        if texture.min() < -1e-6 or texture.max() > 1.0 + 1e-6:
            raise ValueError(f"{path}: {name} values span [{texture.min():.3g}, {texture.max():.3g}], expected [0, 1]")
        textures[name] = texture
    size = textures["base_color"].shape[:2]
    for name in ("roughness", "metallic"):
        if textures[name].shape != size:
            raise ValueError(f"{paths[name]}: {name} texture is {textures[name].shape}, but base_color is {size}")
    return Svbrdf(**textures)


def write_posterior_std(directory: str | os.PathLike, resolution: int, texel: np.ndarray,
                        std: Mapping[str, np.ndarray], prior_std: float) -> None:
    """``std_{name}.exr`` of every texture in `TEXTURES`: each parameter's posterior standard
    deviation (`freqbrdf.estimate.optimise.solve.Fit.std`) at the texels ``texel`` (T,) of a
    ``resolution``-texel atlas, ``prior_std`` at the atlas's other texels."""
    n = check_int(resolution, "resolution", 1) ** 2
    for name in TEXTURES:
        values = np.asarray(std[name], dtype=np.float32)
        atlas = np.full((n,) + values.shape[1:], prior_std, np.float32)
        atlas[texel] = values
        write_exr(Path(directory) / f"std_{name}.exr", atlas.reshape((resolution, resolution) + values.shape[1:]))


def read_posterior_std(directory: str | os.PathLike) -> dict[str, np.ndarray]:
    """The atlases `write_posterior_std` wrote: ``base_color`` (R, R, 3), the others (R, R)."""
    out = {}
    for name in TEXTURES:
        atlas = read_exr(Path(directory) / f"std_{name}.exr")
        out[name] = atlas[..., 0] if name != "base_color" and atlas.ndim == 3 else atlas
    return out


# --------------------------------------------------------------------------
# entropy
# --------------------------------------------------------------------------
@dataclass(frozen=True)
class Entropy:
    """The spectrum entropy of one capture (rule spectrum_search).

    Attributes
    ----------
    texel_entropy : numpy.ndarray
        Shape ``(T,)``, float32 in [0, 1], in the observations' texel order.
    unobserved : numpy.ndarray
        Shape ``(T,)``, bool: texels without a usable spectrum (entropy 1).
    atlas : numpy.ndarray
        Shape ``(R, R)``: the same on the atlas, 1 outside it.
    """

    texel_entropy: np.ndarray
    unobserved: np.ndarray
    atlas: np.ndarray


def write_entropy(directory: str | os.PathLike, texels: SurfaceTexels, entropy: np.ndarray,
                  unobserved: np.ndarray) -> Entropy:
    """Write the per-texel entropy, its unobserved flags and its atlas (``entropy.exr``)."""
    directory = Path(directory)
    r = texels.resolution
    atlas = np.ones(r * r, np.float32)
    atlas[texels.texel] = entropy
    result = Entropy(np.asarray(entropy, np.float32), np.asarray(unobserved, bool), atlas.reshape(r, r))
    write_exr(directory / "entropy.exr", result.atlas)
    np.save(directory / "entropy.npy", result.texel_entropy)
    np.save(directory / "unobserved.npy", result.unobserved)
    return result


def read_entropy(directory: str | os.PathLike) -> Entropy:
    """Read an `Entropy`, checking that its arrays agree."""
    directory = Path(directory)
    atlas = read_exr(directory / "entropy.exr")
    if atlas.ndim == 3:
        atlas = atlas[..., 0]
    entropy, unobserved = np.load(directory / "entropy.npy"), np.load(directory / "unobserved.npy")
    if entropy.shape != unobserved.shape:
        raise ValueError(f"{directory}: entropy.npy {entropy.shape} and unobserved.npy {unobserved.shape} disagree")
    return Entropy(entropy, unobserved, atlas)
