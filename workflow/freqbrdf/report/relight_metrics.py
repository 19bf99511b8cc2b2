"""Relighting: Stanford-ORB style image metrics of relit images against ground-truth
renders, within the object mask (also used on base colour textures,
:func:`freqbrdf.report.metrics.base_color_si_scores`)."""

from __future__ import annotations

from collections.abc import Mapping
from dataclasses import dataclass

import numpy as np

from freqbrdf.util.colour import to_srgb

# How the per-channel scale of a relit image to its reference is fitted before PSNR-H:
# on the clipped images, as Stanford-ORB on the raw ones, or not at all (exposure known).
HDR_SCALES = ("clipped", "orb", "none")


@dataclass(frozen=True)
class HdrScoring:
    """How PSNR-H and the clipped MSE treat linear HDR images (config ``evaluate``).

    Attributes
    ----------
    clip : float
        Upper clip of linear radiance (``evaluate.hdr_clip``; Stanford-ORB: 4).
    normalise : bool
        Stanford-ORB's exposure normalisation of PSNR-H (``evaluate.hdr_normalise``).
    scale : {"clipped", "orb", "none"}
        The per-channel least-squares scale of the prediction (``evaluate.hdr_scale``):
        ``orb`` fits it on the images before clipping, as Stanford-ORB does, so a
        reflected sun's few pixels can set it for the whole image; ``clipped`` fits it
        on the images clipped to [0, ``clip``], the pixels the score compares;
        ``none`` applies none, for captures whose exposure is known.
    """

    clip: float = 4.0
    normalise: bool = True
    scale: str = "orb"

    def __post_init__(self) -> None:
        if not self.clip > 0:
            raise ValueError(f"hdr_clip must be positive, got {self.clip}")
        if self.scale not in HDR_SCALES:
            raise ValueError(f"hdr_scale must be one of {HDR_SCALES}, got {self.scale!r}")

    @classmethod
    def from_config(cls, evaluate: Mapping[str, object]) -> HdrScoring:
        """From config ``evaluate`` (keys ``hdr_clip``, ``hdr_normalise``, ``hdr_scale``)."""
        return cls(float(evaluate["hdr_clip"]), bool(evaluate["hdr_normalise"]), str(evaluate["hdr_scale"]))


STANFORD_ORB = HdrScoring()


def _check_images(pred: np.ndarray, ref: np.ndarray, mask: np.ndarray, name: str) -> tuple[np.ndarray, np.ndarray, np.ndarray]:
    """An image pair as float64 and a boolean mask, after shape and value checks."""
    p, r, m = np.asarray(pred, dtype=np.float64), np.asarray(ref, dtype=np.float64), np.asarray(mask)
    if r.ndim != 3 or r.shape[2] != 3:
        raise ValueError(f"{name}: reference is {r.shape}, expected (H, W, 3)")
    if p.shape != r.shape:
        raise ValueError(f"{name}: prediction is {p.shape}, reference {r.shape}")
    if m.shape != r.shape[:2] or m.dtype != bool:
        raise ValueError(f"{name}: mask is {m.shape} {m.dtype}, expected bool {r.shape[:2]}")
    if not m.any():
        raise ValueError(f"{name}: the mask selects no pixels")
    if not (np.isfinite(p).all() and np.isfinite(r).all()):
        raise ValueError(f"{name}: prediction or reference holds NaN/Inf values")
    return p, r, m


def channel_scale(pred: np.ndarray, ref: np.ndarray, mask: np.ndarray) -> np.ndarray:
    """Per-channel least-squares scale of a prediction to a reference within a mask.

    ``s_c = argmin_s sum_mask (s pred_c - ref_c)^2 = <pred_c, ref_c> / <pred_c, pred_c>``,
    as Stanford-ORB applies before comparing relit images: an estimate is not
    penalised for an overall albedo scale (or colour of the light) it cannot
    know. A channel that is zero inside the mask keeps scale 1.

    Parameters
    ----------
    pred, ref : ndarray, shape (H, W, 3)
        Linear radiance.
    mask : ndarray, shape (H, W), bool
        Pixels to fit over.

    Returns
    -------
    ndarray, shape (3,)
    """
    p, r, m = _check_images(pred, ref, mask, "channel_scale")
    return _channel_scale(p, r, m)


def _channel_scale(p: np.ndarray, r: np.ndarray, m: np.ndarray) -> np.ndarray:
    num = (p[m] * r[m]).sum(axis=0)
    den = (p[m] ** 2).sum(axis=0)
    return np.divide(num, den, out=np.ones(3), where=den > 0)


def image_mse(pred: np.ndarray, ref: np.ndarray, mask: np.ndarray) -> float:
    """Mean squared difference over the masked pixels and the three channels.

    Parameters
    ----------
    pred, ref : ndarray, shape (H, W, 3)
    mask : ndarray, shape (H, W), bool

    Returns
    -------
    float
    """
    p, r, m = _check_images(pred, ref, mask, "image_mse")
    return _mse(p, r, m)


def _mse(p: np.ndarray, r: np.ndarray, m: np.ndarray) -> float:
    return float(np.mean((p[m] - r[m]) ** 2))


def _psnr(mse: float) -> float:
    # Peak 1, as Stanford-ORB's mse_to_psnr for both PSNR-H and PSNR-L; inf for identical images.
    return float("inf") if mse == 0.0 else float(-10.0 * np.log10(mse))


def psnr_h(pred: np.ndarray, ref: np.ndarray, mask: np.ndarray, scoring: HdrScoring = STANFORD_ORB) -> float:
    """PSNR on linear HDR (Stanford-ORB's ``psnr_hdr``), within the mask.

    Steps, in Stanford-ORB's order:

    1. ``normalise``: both images are multiplied by
       ``sum(srgb(ref)) / sum(ref)`` over the mask (``ref`` clipped to [0, 1]
       inside both sums), which brings a dark linear image to the brightness
       of its sRGB display so the clip and the error mean the same across
       exposures (ORB's ``use_gt_median``).
    2. The prediction is scaled per channel to the reference (:func:`channel_scale`),
       with the scale fitted as ``scoring.scale`` says (Stanford-ORB: on the
       images before step 3).
    3. Both are clipped to [0, ``clip``], so a few very bright pixels (a
       reflected sun) do not dominate the error.
    4. ``PSNR = -10 log10(MSE)``, MSE over the masked pixels and channels.

    The peak is 1, not ``clip``, exactly as Stanford-ORB computes it, so the
    values are on the scale of the paper's Table 1 (a peak of 4 would add
    20 log10(4) = 12.04 dB). Unlike Stanford-ORB, the MSE is averaged over the
    mask, not over the whole image (ORB's values grow with the fraction of
    the image the background fills), the mask is not eroded (ours is exact;
    the caller chooses which pixels count), and there is no floor at the
    PSNR of a constant grey prediction.

    Parameters
    ----------
    pred, ref : ndarray, shape (H, W, 3)
        Linear radiance, non-negative.
    mask : ndarray, shape (H, W), bool
        Object pixels to compare.
    scoring : HdrScoring
        The clip, step 1 and the scale's fit; default Stanford-ORB's.

    Returns
    -------
    float
        Decibels; ``inf`` when the scaled, clipped images are identical.
    """
    p, r = hdr_pair(pred, ref, mask, scoring)
    return _psnr(_mse(p, r, np.asarray(mask)))


def hdr_pair(pred: np.ndarray, ref: np.ndarray, mask: np.ndarray,
             scoring: HdrScoring = STANFORD_ORB) -> tuple[np.ndarray, np.ndarray]:
    """The images :func:`psnr_h` compares: steps 1 to 3 of its definition applied to both.

    Parameters
    ----------
    pred, ref : ndarray, shape (H, W, 3)
        Linear radiance, non-negative.
    mask : ndarray, shape (H, W), bool
        Object pixels (the exposure and the channel scales are fitted over them).
    scoring : HdrScoring
        As :func:`psnr_h`.

    Returns
    -------
    pred, ref : ndarray, shape (H, W, 3), float64 in [0, clip]
        Their squared difference, averaged over the masked pixels and the
        channels, is ``10 ** (-psnr_h / 10)``.
    """
    p, r, m = _check_images(pred, ref, mask, "psnr_h")
    if scoring.normalise:
        linear = np.clip(r[m], 0.0, 1.0)
        total = linear.sum()
        if total > 0:
            gain = to_srgb(linear).sum() / total
            p, r = p * gain, r * gain
    clip = scoring.clip
    if scoring.scale == "orb":
        p = p * _channel_scale(p, r, m)
    elif scoring.scale == "clipped":
        p = p * _channel_scale(np.clip(p, 0.0, clip), np.clip(r, 0.0, clip), m)
    return np.clip(p, 0.0, clip), np.clip(r, 0.0, clip)


def scored_pixels(coverage: np.ndarray, min_coverage: float) -> np.ndarray:
    """Pixels of a reference view that the relighting metrics score (config ``evaluate.mask_min_coverage``).

    Parameters
    ----------
    coverage : ndarray, shape (H, W)
        Fraction of the pixel the object covers, in [0, 1] (the capture's mask PNG).
    min_coverage : float
        Smallest coverage scored.

    Returns
    -------
    ndarray, shape (H, W), bool
    """
    # the mask PNG holds coverage in steps of 1/255: a threshold of 1 must keep 255/255
    return np.asarray(coverage) >= min_coverage - 1e-6


def display_pair(pred: np.ndarray, ref: np.ndarray, mask: np.ndarray) -> tuple[np.ndarray, np.ndarray]:
    """The images PSNR-L and SSIM compare: the prediction scaled per channel
    to the reference in linear space (:func:`channel_scale`), then both clipped
    to [0, 1] and encoded with the sRGB curve (Stanford-ORB's tone mapping).

    Parameters
    ----------
    pred, ref : ndarray, shape (H, W, 3)
        Linear radiance.
    mask : ndarray, shape (H, W), bool
        Pixels the scale is fitted over.

    Returns
    -------
    pred_srgb, ref_srgb : ndarray, shape (H, W, 3), values in [0, 1]
    """
    return _display_pair(*_check_images(pred, ref, mask, "display_pair"))


def _display_pair(p: np.ndarray, r: np.ndarray, m: np.ndarray) -> tuple[np.ndarray, np.ndarray]:
    return to_srgb(p * _channel_scale(p, r, m)), to_srgb(r)


def psnr_l(pred: np.ndarray, ref: np.ndarray, mask: np.ndarray) -> float:
    """PSNR on tone-mapped sRGB in [0, 1] (Stanford-ORB's ``psnr_ldr``), within the mask.

    The per-channel scale is applied first, in linear space, as Stanford-ORB
    does for relighting (:func:`display_pair`); peak 1; MSE averaged over
    the masked pixels and channels.

    Parameters
    ----------
    pred, ref : ndarray, shape (H, W, 3)
        Linear radiance.
    mask : ndarray, shape (H, W), bool

    Returns
    -------
    float
        Decibels; ``inf`` for identical display images.
    """
    p, r, m = _check_images(pred, ref, mask, "psnr_l")
    return _psnr(_mse(*_display_pair(p, r, m), m))


def ssim(pred: np.ndarray, ref: np.ndarray, mask: np.ndarray) -> float:
    """Structural similarity of the display images (:func:`display_pair`), averaged over the mask.

    Both images are set to 0 outside the mask (as Stanford-ORB does), the
    SSIM map is computed by scikit-image with Wang et al.'s settings (Gaussian
    window, sigma 1.5, population covariances, ``data_range`` 1), and its
    mean is taken over the masked pixels and the channels only, so the
    trivially equal background does not raise the score.

    Parameters
    ----------
    pred, ref : ndarray, shape (H, W, 3)
        Linear radiance; H and W at least 11 (the window).
    mask : ndarray, shape (H, W), bool

    Returns
    -------
    float
        At most 1 (identical images).
    """
    from skimage.metrics import structural_similarity

    p, r, m = _check_images(pred, ref, mask, "ssim")
    if min(m.shape) < 11:
        raise ValueError(f"ssim: images are {m.shape}, need at least 11x11 for the Gaussian window")
    p, r = _display_pair(p, r, m)
    _, ssim_map = structural_similarity(
        p * m[..., None], r * m[..., None], data_range=1.0, channel_axis=-1, full=True,
        gaussian_weights=True, sigma=1.5, use_sample_covariance=False,
    )
    return float(ssim_map[m].mean())


RELIGHT_METRICS = ("psnr_h", "psnr_l", "ssim", "mse")


def relight_view_scores(
    preds: list[np.ndarray], refs: list[np.ndarray], masks: list[np.ndarray], scoring: HdrScoring = STANFORD_ORB
) -> list[dict[str, float]]:
    """Relighting metrics of each view of one image set.

    Parameters
    ----------
    preds, refs : list of ndarray, shape (H, W, 3)
        Relit and reference linear HDR views, in the same order.
    masks : list of ndarray, shape (H, W), bool
        Object pixels of each view.
    scoring : HdrScoring
        PSNR-H's settings; ``mse`` uses its clip.

    Returns
    -------
    list of dict
        Per view: ``psnr_h``, ``psnr_l``, ``ssim`` and ``mse``, the :func:`image_mse` of
        linear HDR clipped to [0, ``clip``] *without* any scale, so that it, unlike
        the other three, sees an estimate's absolute albedo error (synthetic
        references share the renderer's exposure).
    """
    if not (len(preds) == len(refs) == len(masks)) or not preds:
        raise ValueError(f"relight_view_scores: {len(preds)} predictions, {len(refs)} references, {len(masks)} masks")
    clip = scoring.clip
    return [dict(zip(RELIGHT_METRICS, (psnr_h(p, r, m, scoring), psnr_l(p, r, m), ssim(p, r, m),
                                       image_mse(np.clip(p, 0.0, clip), np.clip(r, 0.0, clip), m))))
            for p, r, m in zip(preds, refs, masks)]


def relight_scores(
    preds: list[np.ndarray], refs: list[np.ndarray], masks: list[np.ndarray], scoring: HdrScoring = STANFORD_ORB
) -> dict[str, float]:
    """:func:`relight_view_scores` averaged over the views (as Stanford-ORB averages)."""
    per_view = relight_view_scores(preds, refs, masks, scoring)
    return {name: float(np.mean([view[name] for view in per_view])) for name in RELIGHT_METRICS}
