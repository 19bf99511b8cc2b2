"""Differentiable-rendering baseline: SVBRDF textures by Mitsuba 3's ``prb`` and Adam.

The baseline of the paper's section 5.1 (Mitsuba 3, one ray per pixel and view). The object's mesh carries a
``principled`` BSDF whose base colour, roughness and metallic are float32
``bitmap`` textures (built exactly as the ground-truth renders build theirs,
:func:`freqbrdf.scene.render.principled_bsdf`, so texel (i, j) sits at
uv = ((j + 0.5) / W, (i + 0.5) / H) for both). The scene is lit by the
capture's environment map and rendered with path replay backpropagation
(``prb``), which gives gradients of the rendered image with respect to every
texel, including through inter-reflections up to ``max_depth``.

One gradient step renders one training view (a full image at ``spp`` samples
per pixel) and compares it with the captured image; an epoch visits every
view once, in a seeded random order. The objective of a step is

    loss = sum_px w_px sum_c d(I_pxc, I'_pxc) / (3 sum_px w_px) + tv_weight * TV

with ``w`` the object-coverage mask of the view (background pixels show the
environment and carry no information about the material; NaN/Inf pixels of
the capture get weight 0), ``d`` either ``|log(1 + I) - log(1 + I')|``
(``l1log``: the log compression of the authors' reference code keeps bright
highlights from dominating; its extra gamma curve is left out because its
slope is infinite at black, where a noisy render is often exactly 0) or
``(I - I')^2`` (``l2``). TV is the mean absolute difference between
horizontally and vertically adjacent texels, summed over the five parameter
channels (base R, G, B, roughness, metallic), as in :mod:`freqbrdf.estimate.optimise`,
so ``tv_weight`` means the same for both estimators (here over the whole
atlas, not only over the observed texels). After each Adam step the
textures are clamped to [0, 1].

Mitsuba is passed in as the first argument (``mi``) with a variant already
set (:func:`freqbrdf.util.mitsuba_setup.setup_mitsuba`, e.g. ``llvm_ad_rgb``);
importing this module has no side effect.

With the same inputs and seed two runs render the same samples: on one
thread the results are bit-identical; on several, texel gradients are summed
by atomics in varying order, and Adam magnifies that rounding on texels whose
gradient is almost 0 (measured: up to 2e-3 after two steps).
"""

from __future__ import annotations

import contextlib
import time
from collections.abc import Callable, Iterator, Mapping
from dataclasses import dataclass
from pathlib import Path
from types import ModuleType

import numpy as np

from freqbrdf.sphere.brdf import TEXTURES
from freqbrdf.scene.cameras import Cameras, mitsuba_to_world
from freqbrdf.scene.render import capture_scene, principled_bsdf
from freqbrdf.util.validation import check_int

LOSSES = ("l1log", "l2")
# The object's name in the scene built by render.capture_scene.
_PARAM_KEYS = {name: f"object.bsdf.{name}.data" for name in TEXTURES}
_CHANNELS = {"base_color": 3, "roughness": 1, "metallic": 1}


@dataclass(frozen=True)
class InverseSettings:
    """Settings of the differentiable-rendering optimiser (config ``mitsuba``).

    Attributes
    ----------
    epochs : int
        Passes over the training views; one view per gradient step.
    spp : int
        Samples per pixel of each gradient step's render (the ``prb``
        integrator uses the same count for its adjoint pass).
    lr : float
        Adam learning rate (texture values are in [0, 1]).
    loss : {"l1log", "l2"}
        Image distance (module docstring).
    tv_weight : float
        Weight of the textures' total variation, ``>= 0``.
    max_depth : int
        Path length limit of ``prb`` (-1: unlimited; 2: direct light only).
    seed : int
        Seeds the view order of every epoch and every step's sampler.
    """

    epochs: int = 10
    spp: int = 32
    lr: float = 0.01
    loss: str = "l1log"
    tv_weight: float = 1e-3
    max_depth: int = 8
    seed: int = 0

    def __post_init__(self) -> None:
        check_int(self.epochs, "epochs", 1)
        check_int(self.spp, "spp", 1)
        check_int(self.seed, "seed", 0)
        check_int(self.max_depth, "max_depth", -1)
        if self.max_depth == 0:
            raise ValueError("max_depth must be -1 (unlimited) or >= 1, got 0")
        if not (np.isfinite(self.lr) and self.lr > 0):
            raise ValueError(f"lr must be a finite number > 0, got {self.lr!r}")
        if self.loss not in LOSSES:
            raise ValueError(f"loss must be one of {LOSSES}, got {self.loss!r}")
        if not (np.isfinite(self.tv_weight) and self.tv_weight >= 0):
            raise ValueError(f"tv_weight must be a finite number >= 0, got {self.tv_weight!r}")


@dataclass(frozen=True)
class EpochReport:
    """Progress after one epoch, handed to the ``progress`` callback.

    Attributes
    ----------
    epoch : int
        1-based epoch just finished.
    epochs : int
        Epochs in the run.
    loss : float
        Mean loss of the epoch's steps.
    elapsed_s : float
        Wall-clock seconds since the optimisation started.
    resident_mb : float
        Resident memory of the process (MB), to show it does not grow.
    """

    epoch: int
    epochs: int
    loss: float
    elapsed_s: float
    resident_mb: float


@dataclass(frozen=True)
class InverseResult:
    """Output of :func:`optimise_textures`.

    Attributes
    ----------
    textures : dict
        ``base_color`` (R, R, 3), ``roughness`` (R, R), ``metallic`` (R, R),
        float32 in [0, 1].
    loss : ndarray, shape (epochs * K,)
        Loss of every step (before its update).
    view : ndarray, shape (epochs * K,), int
        Index of the view rendered at each step.
    epoch_loss : ndarray, shape (epochs,)
        Mean loss of each epoch.
    evaluations : list of dict
        With an ``evaluate`` callback: one row per epoch, epoch 0 the start,
        ``{"epoch", "elapsed_s", **evaluate(textures)}``; ``elapsed_s`` is
        optimisation time only (the evaluations' own time is left out).
    """

    textures: dict[str, np.ndarray]
    loss: np.ndarray
    view: np.ndarray
    epoch_loss: np.ndarray
    evaluations: list[dict[str, float]]


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


def sensor_intrinsics(cameras: Cameras) -> tuple[np.ndarray, np.ndarray]:
    """Mitsuba ``perspective`` settings that reproduce each view's intrinsics K.

    Mitsuba's pinhole has square pixels and no skew; the principal point is
    an offset from the image centre in units of the image size, with the
    sign measured by rendering (an offset of +0.1 moves the image of the
    optical axis by -0.1 W).

    Parameters
    ----------
    cameras : Cameras

    Returns
    -------
    x_fov_deg : ndarray, shape (N,)
        Horizontal field of view.
    principal_offset : ndarray, shape (N, 2)
        ``principal_point_offset_x``, ``principal_point_offset_y``.

    Raises
    ------
    ValueError
        Naming the first view whose K has non-square pixels or skew.
    """
    K = np.asarray(cameras.K, dtype=np.float64)
    fx, fy = K[:, 0, 0], K[:, 1, 1]
    bad = np.nonzero(~np.isclose(fx, fy, rtol=1e-4) | (np.abs(K[:, 0, 1]) > 1e-6 * fx))[0]
    if len(bad):
        raise ValueError(
            f"view {cameras.names[bad[0]]}: K {K[bad[0]].tolist()} has non-square pixels or skew, "
            "which Mitsuba's perspective sensor cannot reproduce"
        )
    x_fov = np.degrees(2.0 * np.arctan(cameras.width / (2.0 * fx)))
    offset = np.stack([(cameras.width / 2.0 - K[:, 0, 2]) / cameras.width,
                       (cameras.height / 2.0 - K[:, 1, 2]) / cameras.height], axis=-1)
    return x_fov, offset


def sensor_views(mi: ModuleType, cameras: Cameras) -> list[dict[str, object]]:
    """Sensor parameters of every view, to assign to ``mi.traverse(scene)``.

    Moving the one sensor of the scene (rather than holding a sensor per
    view) lets Dr.Jit compile the render kernels once for all views.

    Returns
    -------
    list of dict
        Per view: ``sensor.to_world``, ``sensor.x_fov``,
        ``sensor.principal_point_offset_x`` and ``_y``.
    """
    x_fov, offset = sensor_intrinsics(cameras)
    views = []
    for k, w2c in enumerate(np.asarray(cameras.world_to_camera, dtype=np.float64)):
        views.append({
            "sensor.to_world": mi.ScalarTransform4f(mitsuba_to_world(w2c)),
            "sensor.x_fov": float(x_fov[k]),
            "sensor.principal_point_offset_x": float(offset[k, 0]),
            "sensor.principal_point_offset_y": float(offset[k, 1]),
        })
    return views


def inverse_scene(
    mi: ModuleType,
    mesh: str | Path,
    envmap: np.ndarray,
    textures: Mapping[str, np.ndarray],
    *,
    width: int,
    height: int,
    spp: int,
    max_depth: int,
):
    """The capture's scene with ``prb`` and the textures as parameters.

    Parameters
    ----------
    mesh : path-like
        PLY mesh with normals and uvs.
    envmap : ndarray, shape (H, 2H, 3)
        Equirectangular radiance of the capture's environment.
    textures : mapping
        Start textures (:func:`check_textures`).
    width, height : int
        Image size in pixels (the capture's).
    spp : int
        Default samples per pixel.
    max_depth : int
        Path length limit of ``prb``.

    Returns
    -------
    mitsuba.Scene
        Its parameters ``object.bsdf.{base_color,roughness,metallic}.data``
        are the (H, W, C) texture tensors.
    """
    start = check_textures(textures)
    bsdf = principled_bsdf(mi, start["base_color"], start["roughness"], start["metallic"])
    # The field of view is set per view before each render; 35 is a placeholder.
    return capture_scene(mi, mesh, bsdf, envmap, width=width, height=height, fov_x_deg=35.0, spp=spp,
                         max_depth=max_depth, integrator="prb")


def _step_seeds(seed: int, step: int) -> tuple[int, int]:
    """Sampler seeds (32-bit) of one step's primal and adjoint renders.

    Distinct strides keep the two passes' noise independent (correlated
    noise biases the gradient) and every step's noise different.
    """
    primal = (int(seed) * 0x85EBCA6B + step * 0x9E3779B1 + 1) & 0xFFFFFFFF
    adjoint = (int(seed) * 0xC2B2AE35 + step * 0x27D4EB2F + 2) & 0xFFFFFFFF
    return primal, adjoint


def view_order(seed: int, epoch: int, n_views: int) -> np.ndarray:
    """Seeded random order of the views in one epoch, shape (n_views,)."""
    return np.random.default_rng([int(seed), int(epoch)]).permutation(n_views)


def image_loss(mi: ModuleType, image, reference, weight, kind: str):
    """Coverage-weighted mean image distance (module docstring), a Dr.Jit scalar.

    Parameters
    ----------
    image, reference : mitsuba.TensorXf, shape (H, W, 3)
        Rendered and captured linear radiance.
    weight : mitsuba.TensorXf, shape (H, W, 1)
        Per-pixel weight (object coverage), not all zero.
    kind : {"l1log", "l2"}
    """
    import drjit as dr

    if kind == "l1log":
        distance = dr.abs(dr.log(1.0 + dr.maximum(image, 0.0)) - dr.log(1.0 + reference))
    elif kind == "l2":
        distance = dr.square(image - reference)
    else:
        raise ValueError(f"loss must be one of {LOSSES}, got {kind!r}")
    return dr.sum(weight * distance, axis=None) / (3.0 * dr.sum(weight, axis=None))


def total_variation(mi: ModuleType, tensors) -> object:
    """Mean absolute difference of adjacent texels, summed over channels (a Dr.Jit scalar).

    Parameters
    ----------
    tensors : sequence of mitsuba.TensorXf, each shape (R, R, C)
        The parameter textures (all the same size).
    """
    import drjit as dr

    height, width = tensors[0].shape[:2]
    pairs = (height - 1) * width + height * (width - 1)
    total = 0.0
    for t in tensors:
        total = total + dr.sum(dr.abs(t[1:, :, :] - t[:-1, :, :]), axis=None)
        total = total + dr.sum(dr.abs(t[:, 1:, :] - t[:, :-1, :]), axis=None)
    return total / max(pairs, 1)


def _resident_mb() -> float:
    import psutil

    return psutil.Process().memory_info().rss / 2**20


def _check_captures(cameras: Cameras, images: np.ndarray, weights: np.ndarray) -> tuple[np.ndarray, np.ndarray]:
    """Captured views with NaN/Inf pixels zeroed and given weight 0."""
    n, h, w = len(cameras), cameras.height, cameras.width
    images = np.asarray(images, dtype=np.float32)
    weights = np.asarray(weights, dtype=np.float32)
    if images.shape != (n, h, w, 3):
        raise ValueError(f"images are {images.shape}, cameras say ({n}, {h}, {w}, 3)")
    if weights.shape != (n, h, w):
        raise ValueError(f"masks are {weights.shape}, cameras say ({n}, {h}, {w})")
    if not np.isfinite(weights).all() or weights.min() < 0.0:
        raise ValueError("masks must hold finite weights >= 0")
    bad = ~np.isfinite(images).all(axis=-1)
    images = np.where(bad[..., None], 0.0, images).astype(np.float32)
    weights = np.where(bad, 0.0, weights).astype(np.float32)
    empty = np.nonzero(weights.reshape(n, -1).sum(axis=1) <= 0.0)[0]
    if len(empty):
        raise ValueError(f"view {cameras.names[empty[0]]}: the mask covers no pixel")
    return images, weights


def _adam_step(mi: ModuleType, scene, params, opt, image: np.ndarray, weight: np.ndarray,
               settings: InverseSettings, step: int) -> float:
    """Render the view the sensor is set to, backpropagate its loss, update and clamp the textures.

    Returns the step's loss (before the update). Nothing of the step's
    differentiable graph outlives this call (``dr.backward`` frees it), so
    memory does not grow from step to step.
    """
    import drjit as dr

    params.update(opt)
    seed, seed_grad = _step_seeds(settings.seed, step)
    rendered = mi.render(scene, params, spp=settings.spp, seed=seed, seed_grad=seed_grad)
    loss = image_loss(mi, rendered, mi.TensorXf(image), mi.TensorXf(weight[..., None]), settings.loss)
    if settings.tv_weight > 0:
        loss = loss + settings.tv_weight * total_variation(mi, [opt[key] for key in _PARAM_KEYS.values()])
    dr.backward(loss)
    opt.step()
    for key in _PARAM_KEYS.values():
        opt[key] = dr.clip(opt[key], 0.0, 1.0)
    return float(loss.array[0])


def optimise_textures(
    mi: ModuleType,
    mesh: str | Path,
    envmap: np.ndarray,
    cameras: Cameras,
    images: np.ndarray,
    weights: np.ndarray,
    start: Mapping[str, np.ndarray],
    settings: InverseSettings,
    progress: Callable[[EpochReport], None] | None = None,
    evaluate: Callable[[dict[str, np.ndarray]], Mapping[str, float]] | None = None,
) -> InverseResult:
    """Optimise the SVBRDF textures so that ``prb`` renders match the captured views.

    Parameters
    ----------
    mi : module
        Mitsuba with an ``*_ad_*`` variant set.
    mesh : path-like
        The object's PLY mesh (normals, uvs).
    envmap : ndarray, shape (He, 2He, 3)
        Equirectangular environment radiance that lit the capture.
    cameras : Cameras
        Poses and intrinsics of the K training views (OpenCV convention).
    images, weights : ndarray, shape (K, H, W, 3) and (K, H, W)
        Captured linear radiance (NaN/Inf pixels are ignored) and per-pixel
        loss weights, e.g. the object coverage masks in [0, 1].
    start : mapping
        Start textures (:func:`check_textures`), e.g. :func:`constant_textures`.
    settings : InverseSettings
    progress : callable, optional
        Called with an :class:`EpochReport` after every epoch.
    evaluate : callable, optional
        Called with the current textures before the first step and after every
        epoch (e.g. the error against a ground truth); it only reads them, and
        its time is left out of ``elapsed_s``.

    Returns
    -------
    InverseResult
        Textures clamped to [0, 1] and the loss of every step (reproducibility:
        see the module docstring).
    """
    import drjit as dr

    if not dr.is_diff_v(mi.Float):
        raise ValueError(f"optimise_textures needs a differentiable Mitsuba variant (e.g. llvm_ad_rgb), "
                         f"not {mi.variant()}")
    images, weights = _check_captures(cameras, images, weights)
    sensors = sensor_views(mi, cameras)
    scene = inverse_scene(mi, mesh, envmap, start, width=cameras.width, height=cameras.height,
                          spp=settings.spp, max_depth=settings.max_depth)
    params = mi.traverse(scene)
    opt = mi.ad.Adam(lr=settings.lr)
    for key in _PARAM_KEYS.values():
        opt[key] = params[key]
    params.update(opt)

    losses, order, epoch_loss, evaluations = [], [], [], []
    clock = _Clock()
    if evaluate is not None:
        with clock.paused():
            evaluations.append({"epoch": 0, "elapsed_s": 0.0, **evaluate(_textures(opt))})
    for epoch in range(settings.epochs):
        for k in view_order(settings.seed, epoch, len(cameras)):
            for key, value in sensors[k].items():
                params[key] = value
            losses.append(_adam_step(mi, scene, params, opt, images[k], weights[k], settings, len(losses)))
            order.append(int(k))
        epoch_loss.append(float(np.mean(losses[-len(cameras):])))
        elapsed = clock.elapsed()
        with clock.paused():
            if evaluate is not None:
                evaluations.append({"epoch": epoch + 1, "elapsed_s": elapsed, **evaluate(_textures(opt))})
            if progress is not None:
                progress(EpochReport(epoch + 1, settings.epochs, epoch_loss[-1], elapsed, _resident_mb()))

    params.update(opt)
    return InverseResult(textures=_textures(params), loss=np.asarray(losses), view=np.asarray(order, dtype=np.int64),
                         epoch_loss=np.asarray(epoch_loss), evaluations=evaluations)


def _textures(params) -> dict[str, np.ndarray]:
    """Textures as float32 arrays from the scene's parameters or the optimiser (which holds the
    latest step's values; the scene gets them at the next step), clamped to [0, 1] after every step."""
    textures = {}
    for name, key in _PARAM_KEYS.items():
        value = np.array(params[key], dtype=np.float32)
        textures[name] = value if _CHANNELS[name] == 3 else value[..., 0]
    return textures


class _Clock:
    """Wall-clock seconds of optimisation, leaving out the intervals spent in `paused`."""

    def __init__(self) -> None:
        self._start, self._paused = time.perf_counter(), 0.0

    def elapsed(self) -> float:
        return time.perf_counter() - self._start - self._paused

    @contextlib.contextmanager
    def paused(self) -> Iterator[None]:
        begin = time.perf_counter()
        try:
            yield
        finally:
            self._paused += time.perf_counter() - begin
