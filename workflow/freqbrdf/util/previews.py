"""Previews the rules write beside their outputs: contact sheets, texture previews, and the
figures of environment spectra, coverage, entropy and loss (matplotlib, non-interactive backend).

On the lowest floor (docs/modules.md, "Floors") because renderers and estimators write these
previews: code on the report's floor would make every figure edit rerun them. The report's
own figures are in :mod:`freqbrdf.report.figures`.
"""

from __future__ import annotations

import os
from collections.abc import Mapping

import numpy as np

from freqbrdf.util.colour import to_srgb, tonemap
from freqbrdf.util.io import atomic_path, write_png


def pyplot():
    """matplotlib's pyplot on the non-interactive Agg backend, imported on first use
    (importing this module stays cheap for rules that draw nothing)."""
    import matplotlib

    matplotlib.use("Agg")
    import matplotlib.pyplot as plt

    return plt


def save_figure(fig, path: str | os.PathLike, dpi: int = 110) -> None:
    """Write ``fig`` as PNG atomically and release it."""
    with atomic_path(path) as tmp:
        fig.savefig(tmp, dpi=dpi, bbox_inches="tight", format="png")
    pyplot().close(fig)


def env_spectrum_figure(path: str | os.PathLike, name: str, envmap: np.ndarray, spectrum: np.ndarray, high_fraction: float,
                        above: int = 4) -> None:
    """Environment preview beside its SH power spectrum (luminance and RGB).

    Parameters
    ----------
    path : path-like
        PNG destination.
    name : str
        Environment name for the title.
    envmap : ndarray, shape (H, W, 3)
    spectrum : ndarray, shape (lmax + 1, 4)
        From :func:`freqbrdf.scene.envmaps.sh_spectrum`.
    high_fraction : float
        Share of the luminance power above degree ``above``
        (:func:`freqbrdf.scene.envmaps.high_frequency_fraction`), for the caption.
    above : int
        Degree after which power counts as high frequency.
    """
    plt = pyplot()
    fig, (ax_img, ax_spec) = plt.subplots(1, 2, figsize=(11, 3.4), gridspec_kw={"width_ratios": [1.6, 1]})
    ax_img.imshow(tonemap(envmap))
    ax_img.set_title(f"{name} (tone-mapped equirect; top row = +Y)")
    ax_img.set_axis_off()
    degrees = np.arange(len(spectrum))
    for c, colour in enumerate(["tab:red", "tab:green", "tab:blue"]):
        ax_spec.semilogy(degrees, spectrum[:, c] / spectrum[:, 3].sum(), color=colour, alpha=0.35, lw=1)
    ax_spec.semilogy(degrees, spectrum[:, 3] / spectrum[:, 3].sum(), "k.-", label="luminance")
    ax_spec.set_title(f"SH power, {100 * high_fraction:.1f}% above degree {above}")
    ax_spec.set_xlabel("degree l")
    ax_spec.set_ylabel("S(l) / total power")
    ax_spec.grid(alpha=0.3)
    save_figure(fig, path)


def spectra_comparison_figure(path: str | os.PathLike, spectra: Mapping[str, np.ndarray]) -> None:
    """Normalised luminance power spectra of all environments on one plot.

    Parameters
    ----------
    spectra : mapping of str to ndarray, shape (lmax + 1, 4)
    """
    plt = pyplot()
    fig, ax = plt.subplots(figsize=(6, 4))
    for name, spectrum in spectra.items():
        lum = spectrum[:, 3]
        ax.semilogy(np.arange(len(lum)), lum / lum.sum(), ".-", label=name)
    ax.set_xlabel("degree l")
    ax.set_ylabel("S(l) / total power (luminance)")
    ax.set_title("Frequency content of the environments")
    ax.grid(alpha=0.3)
    ax.legend()
    save_figure(fig, path)


def contact_sheet(path: str | os.PathLike, images: list[np.ndarray], columns: int = 4) -> None:
    """Tone-mapped HDR images in a grid, written as one PNG.

    Parameters
    ----------
    images : list of ndarray, shape (H, W, 3)
        Linear radiance, all the same size.
    """
    rows = -(-len(images) // columns)
    h, w = images[0].shape[:2]
    sheet = np.zeros((rows * h, columns * w, 3))
    for k, image in enumerate(images):
        r, c = divmod(k, columns)
        sheet[r * h : (r + 1) * h, c * w : (c + 1) * w] = tonemap(image)
    write_png(path, sheet)


def texture_preview(path: str | os.PathLike, texture: np.ndarray, srgb: bool) -> None:
    """PNG preview of a texture: sRGB-encoded colour, or linear grey values."""
    write_png(path, to_srgb(texture) if srgb else np.clip(texture, 0.0, 1.0))


def atlas_image(resolution: int, texel: np.ndarray, values: np.ndarray) -> np.ndarray:
    """Per-texel values on the UV atlas, shape ``(R, R)``, NaN (drawn grey) at every other texel.

    Parameters
    ----------
    resolution : int
        Atlas size R.
    texel : ndarray, shape (T,)
        Flat texel indices ``i * R + j``.
    values : ndarray, shape (T,)
        One value per texel.
    """
    image = np.full(resolution * resolution, np.nan)
    image[texel] = values
    return image.reshape(resolution, resolution)


def coverage_figure(path: str | os.PathLike, resolution: int, texel: np.ndarray, views_per_texel: np.ndarray, title: str) -> None:
    """How many views observe each texel, drawn in UV space.

    Parameters
    ----------
    resolution : int
        Atlas size R.
    texel : ndarray, shape (T,)
        Flat texel indices.
    views_per_texel : ndarray, shape (T,)
        Number of views observing each texel.
    title : str
        Figure title.
    """
    plt = pyplot()
    fig, ax = plt.subplots(figsize=(5.2, 4.4))
    cmap = plt.get_cmap("viridis").with_extremes(bad="0.85")
    shown = ax.imshow(atlas_image(resolution, texel, views_per_texel), cmap=cmap, vmin=0, interpolation="nearest",
                      extent=(0, 1, 1, 0))
    ax.set_xlabel("u")
    ax.set_ylabel("v")
    ax.set_title(title)
    fig.colorbar(shown, ax=ax, label="views observing the texel (grey: outside the atlas)")
    save_figure(fig, path)


def entropy_figure(path: str | os.PathLike, entropy_atlas: np.ndarray, valid: np.ndarray, title: str) -> None:
    """Normalised entropy in UV space with the Turbo colour map (blue: certain, red: uncertain).

    Parameters
    ----------
    entropy_atlas : ndarray, shape (R, R)
        Entropy in [0, 1].
    valid : ndarray, shape (R, R), bool
        Texels inside the atlas; the rest is drawn grey.
    """
    plt = pyplot()
    fig, ax = plt.subplots(figsize=(5.2, 4.4))
    cmap = plt.get_cmap("turbo").with_extremes(bad="0.85")
    shown = ax.imshow(np.where(valid, entropy_atlas, np.nan), cmap=cmap, vmin=0.0, vmax=1.0,
                      interpolation="nearest", extent=(0, 1, 1, 0))
    ax.set_xlabel("u")
    ax.set_ylabel("v")
    ax.set_title(title)
    fig.colorbar(shown, ax=ax, label="normalised entropy")
    save_figure(fig, path)


def texel_spectra_figure(path: str | os.PathLike, examples: Mapping[str, dict]) -> None:
    """Outgoing and incoming power spectra of a few texels with the fitted filter.

    Parameters
    ----------
    examples : mapping of label to dict
        Each dict holds ``s_b`` and ``s_l`` (lmax + 1,) luminance spectra,
        ``ks`` and ``alpha`` of the grid estimate and ``entropy``.
    """
    plt = pyplot()
    fig, axes = plt.subplots(1, len(examples), figsize=(4.0 * len(examples), 3.3), squeeze=False)
    for ax, (label, ex) in zip(axes[0], examples.items()):
        degrees = np.arange(len(ex["s_l"]))
        scale = max(float(ex["s_l"].sum()), 1e-30)
        model = ex["ks"] ** 2 * np.exp(-2.0 * (ex["alpha"] * degrees) ** 2) * ex["s_l"]
        ax.semilogy(degrees, ex["s_l"] / scale, "o-", label="S_L (incoming)")
        ax.semilogy(degrees, ex["s_b"] / scale, "s-", label="S_B (outgoing)")
        ax.semilogy(degrees[1:], model[1:] / scale, "k--", label="K_s^2 exp(-2(al)^2) S_L")
        ax.set_title(f"{label}: H = {ex['entropy']:.2f}, K_s = {ex['ks']:.2f}, alpha = {ex['alpha']:.2f}", fontsize=9)
        ax.set_xlabel("degree l")
        ax.grid(alpha=0.3)
    axes[0, 0].set_ylabel("power / incoming power")
    axes[0, 0].legend(fontsize=7)
    save_figure(fig, path)


def loss_figure(path: str | os.PathLike, curve: np.ndarray, title: str, ylabel: str = "L1 + TV loss") -> None:
    """Optimisation loss per iteration (log scale; for ``freq``, jumps mark refits of the light)."""
    plt = pyplot()
    fig, ax = plt.subplots(figsize=(5, 3.2))
    ax.semilogy(np.arange(len(curve)), curve)
    ax.set_xlabel("iteration")
    ax.set_ylabel(ylabel)
    ax.set_title(title)
    ax.grid(alpha=0.3)
    save_figure(fig, path)
