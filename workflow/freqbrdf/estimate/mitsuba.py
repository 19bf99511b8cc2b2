"""Differentiable-rendering baseline: SVBRDF textures by Mitsuba 3's ``prb`` and Adam.

The baseline of the paper's section 5.1 (Mitsuba 3, one ray per pixel and view). The object's mesh carries a
``principled`` BSDF whose base colour, roughness and metallic are float32
``bitmap`` textures (built exactly as the ground-truth renders build theirs,
:func:`freqbrdf.scene.render.principled_bsdf`, so texel (i, j) sits at
uv = ((j + 0.5) / W, (i + 0.5) / H) for both). The scene is lit by the
capture's environment map and rendered with path replay backpropagation
(``prb``), which gives gradients of the rendered image with respect to every
texel, including through inter-reflections up to ``max_depth``.

A gradient step renders ``views_per_step`` training views (by default one;
each a full image at ``spp`` samples per pixel) and compares them with the
captured images; an epoch visits every view once, in a seeded random order,
in ceil(views / views_per_step) steps. The objective of a step is the mean
over its views of

    sum_px w_px sum_c d(I_pxc, I'_pxc) / (3 sum_px w_px)

plus the regulariser, with ``w`` the object-coverage mask of the view
(background pixels show the environment and carry no information about the
material; NaN/Inf pixels of the capture get weight 0; with ``crop`` a step renders only a
window around the pixels of weight > 0, :func:`crop_windows`) and ``d`` one of
``|log(1 + I) - log(1 + I')|`` (``l1log``: the log compression of the
authors' reference code keeps bright highlights from dominating; its extra
gamma curve is left out because its slope is infinite at black, where a noisy
render is often exactly 0; nearly linear at radiance ~0.1-0.5),
``|log(I + eps) - log(I' + eps)|`` (``l1rel``, ``eps = loss_eps``: about the
relative error, which the reference code's log-then-gamma loss
approximates) or ``(I - I')^2`` (``l2``). The views of a step are rendered
and backpropagated one after the other (``prb`` replays a render's paths when
its gradient is taken, so each must be done before the sensor moves), their
gradients summed, before one Adam step. The regulariser is ``tv_weight``
times TV, the mean absolute difference between horizontally and vertically
adjacent texels, summed over the five parameter channels (base R, G, B,
roughness, metallic), as in :mod:`freqbrdf.estimate.optimise`, so
``tv_weight`` means the same for both estimators (here over the whole atlas,
not only over the observed texels); ``tv_weight`` and the learning rate may
also be given per texture (:class:`InverseSettings`). After each Adam step the
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
from collections.abc import Callable, Iterator, Mapping, Sequence
from dataclasses import dataclass
from pathlib import Path
from types import ModuleType

import numpy as np

from freqbrdf.estimate.mitsuba_settings import (LOSSES, LR_DECAYS, InverseSettings, lr_factor, render_seeds,
                                              stop_epoch, view_order)
from freqbrdf.estimate.mitsuba_textures import check_textures, coarse_textures, constant_textures, full_size
from freqbrdf.estimate.mitsuba_views import CropWindows, TrainingViews, crop_windows, sensor_intrinsics, sensor_views
from freqbrdf.sphere.brdf import TEXTURES
from freqbrdf.scene.cameras import Cameras
from freqbrdf.scene.render import capture_scene, principled_bsdf

# The object's name in the scene built by render.capture_scene.
_PARAM_KEYS = {name: f"object.bsdf.{name}.data" for name in TEXTURES}
_CHANNELS = {"base_color": 3, "roughness": 1, "metallic": 1}

__all__ = ["LOSSES", "LR_DECAYS", "CropWindows", "EpochReport", "InverseResult", "InverseSettings", "check_textures",
           "coarse_textures", "constant_textures", "crop_windows", "image_loss", "inverse_scene", "lr_factor",
           "optimise_textures", "render_seeds",
           "sensor_intrinsics", "sensor_views", "step_table", "stop_epoch", "texture_regulariser", "total_variation",
           "view_order"]


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
    loss : ndarray, shape (S,)
        Loss of every step (before its update); S = epochs * ceil(K / views_per_step).
    views : tuple of tuple of int, length S
        Indices of the views rendered at each step, in render order.
    epoch : ndarray, shape (S,), int
        1-based epoch of each step.
    epoch_loss : ndarray, shape (epochs,)
        Mean loss of each epoch.
    evaluations : list of dict
        With an ``evaluate`` callback: one row per epoch, epoch 0 the start,
        ``{"epoch", "elapsed_s", **evaluate(textures)}``; ``elapsed_s`` is
        optimisation time only (the evaluations' own time is left out).
    """

    textures: dict[str, np.ndarray]
    loss: np.ndarray
    views: tuple[tuple[int, ...], ...]
    epoch: np.ndarray
    epoch_loss: np.ndarray
    evaluations: list[dict[str, float]]


def step_table(result: InverseResult, names: Sequence[str]) -> dict[str, np.ndarray | list[str]]:
    """Columns of ``loss.tsv``: one row per Adam step.

    Parameters
    ----------
    result : InverseResult
    names : sequence of str
        Names of the views, indexed as ``result.views``.

    Returns
    -------
    dict
        ``iteration`` (0-based step), ``loss``, ``epoch`` (1-based) and
        ``view``: the names of the step's views joined by ``+`` in render order.
    """
    return {"iteration": np.arange(len(result.loss)), "loss": np.asarray(result.loss),
            "epoch": np.asarray(result.epoch), "view": ["+".join(names[k] for k in step) for step in result.views]}




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


def image_loss(mi: ModuleType, image, reference, weight, kind: str, eps: float = 0.01):
    """Coverage-weighted mean image distance (module docstring), a Dr.Jit scalar.

    Parameters
    ----------
    image, reference : mitsuba.TensorXf, shape (H, W, 3)
        Rendered and captured linear radiance.
    weight : mitsuba.TensorXf, shape (H, W, 1)
        Per-pixel weight (object coverage), not all zero.
    kind : {"l1log", "l2", "l1rel"}
    eps : float
        Offset of ``l1rel``, ``|log(I + eps) - log(I' + eps)|`` (both clamped at 0 first).
    """
    import drjit as dr

    if kind == "l1log":
        distance = dr.abs(dr.log(1.0 + dr.maximum(image, 0.0)) - dr.log(1.0 + reference))
    elif kind == "l1rel":
        distance = dr.abs(dr.log(dr.maximum(image, 0.0) + eps) - dr.log(dr.maximum(reference, 0.0) + eps))
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


def texture_regulariser(mi: ModuleType, textures: Mapping[str, object],
                        tv_weight: float | Mapping[str, float]) -> object | None:
    """The weighted total variation of the textures (a Dr.Jit scalar), or None when every weight is 0.

    Parameters
    ----------
    textures : mapping
        ``base_color``, ``roughness``, ``metallic`` -> mitsuba.TensorXf (R, R, C).
    tv_weight : float or mapping
        One weight times the TV of all five channels, or per texture name a
        weight times the TV of that texture's own channels.
    """
    if not isinstance(tv_weight, Mapping):
        return tv_weight * total_variation(mi, [textures[name] for name in TEXTURES]) if tv_weight > 0 else None
    total = None
    for name in TEXTURES:
        if tv_weight[name] > 0:
            term = tv_weight[name] * total_variation(mi, [textures[name]])
            total = term if total is None else total + term
    return total


def _set_learning_rates(opt, rates: float | Mapping[str, float]) -> None:
    """Adam's learning rate: one for every texture, or one per texture name (Dr.Jit's per-parameter rates)."""
    if isinstance(rates, Mapping):
        opt.set_learning_rate({_PARAM_KEYS[name]: float(value) for name, value in rates.items()})
    else:
        opt.set_learning_rate(float(rates))


def _adam_step(mi: ModuleType, scene, params, opt, views: Sequence[int], data: TrainingViews,
               settings: InverseSettings, first_render: int) -> float:
    """Render the step's views, backpropagate their mean loss and the regulariser, update and clamp the textures.

    Each view is rendered and backpropagated before the sensor moves to the
    next (``prb`` re-renders the scene in its adjoint pass), each with its
    share ``1 / len(views)`` of the loss; the texel gradients add up, and the
    regulariser joins the last view's backward pass. ``first_render`` is the
    run's count of renders before this step (:func:`render_seeds`).

    Returns the step's loss (before the update). Nothing of the step's
    differentiable graph outlives this call (``dr.backward`` frees it), so
    memory does not grow from step to step.
    """
    import drjit as dr

    total = 0.0
    for i, k in enumerate(views):
        for key, value in data.sensors[k].items():
            params[key] = value
        if i == 0:
            params.update(opt)
        else:
            params.update()
        seed, seed_grad = render_seeds(settings.seed, first_render + i)
        rendered = mi.render(scene, params, spp=settings.spp, seed=seed, seed_grad=seed_grad)
        loss = image_loss(mi, rendered, mi.TensorXf(data.images[k]), mi.TensorXf(data.weights[k][..., None]),
                          settings.loss, settings.loss_eps)
        if len(views) > 1:
            loss = loss / len(views)
        if i == len(views) - 1:
            regulariser = texture_regulariser(mi, {name: opt[key] for name, key in _PARAM_KEYS.items()},
                                              settings.tv_weight)
            loss = loss if regulariser is None else loss + regulariser
        dr.backward(loss)
        total += float(loss.array[0])
    opt.step()
    for key in _PARAM_KEYS.values():
        opt[key] = dr.clip(opt[key], 0.0, 1.0)
    return total


@dataclass
class _Trace:
    """What a run records: per step its loss, views and epoch; per epoch the mean loss and evaluations."""

    loss: list[float]
    views: list[tuple[int, ...]]
    epoch: list[int]
    epoch_loss: list[float]
    evaluations: list[dict[str, float]]


def _run_epoch(mi: ModuleType, scene, params, opt, data: TrainingViews, settings: InverseSettings, epoch: int,
               trace: _Trace) -> None:
    """One pass over every view in the epoch's seeded order, ``views_per_step`` views per Adam step."""
    n_views = len(data.sensors)
    steps = settings.epochs * settings.steps_per_epoch(n_views)
    order = [int(k) for k in view_order(settings.seed, epoch, n_views)]
    for first in range(0, n_views, settings.views_per_step):
        views = tuple(order[first:first + settings.views_per_step])
        _set_learning_rates(opt, settings.learning_rates(len(trace.loss), steps))
        renders = sum(len(v) for v in trace.views)
        trace.loss.append(_adam_step(mi, scene, params, opt, views, data, settings, renders))
        trace.views.append(views)
        trace.epoch.append(epoch + 1)
    trace.epoch_loss.append(float(np.mean(trace.loss[-settings.steps_per_epoch(n_views):])))


def _start_optimiser(mi: ModuleType, params, settings: InverseSettings):
    """Adam over the three texture parameters of the scene (learning rates set before every step)."""
    opt = mi.ad.Adam(lr=max(settings.lr.values()) if isinstance(settings.lr, Mapping) else settings.lr)
    for key in _PARAM_KEYS.values():
        opt[key] = params[key]
    params.update(opt)
    return opt


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
    data = TrainingViews.of(mi, cameras, images, weights, settings.crop)
    resolution = check_textures(start)["roughness"].shape[0]
    scene = inverse_scene(mi, mesh, envmap, coarse_textures(start, settings.coarse_levels), width=cameras.width,
                          height=cameras.height, spp=settings.spp, max_depth=settings.max_depth)
    params = mi.traverse(scene)
    opt = _start_optimiser(mi, params, settings)

    trace = _Trace([], [], [], [], [])
    clock = _Clock()
    if evaluate is not None:
        with clock.paused():
            trace.evaluations.append({"epoch": 0, "elapsed_s": 0.0, **evaluate(_textures(opt, resolution))})
    for epoch in range(settings.epochs):
        if settings.doubles_before(epoch):
            _double_resolution(opt)
        _run_epoch(mi, scene, params, opt, data, settings, epoch, trace)
        elapsed = clock.elapsed()
        with clock.paused():
            if evaluate is not None:
                trace.evaluations.append({"epoch": epoch + 1, "elapsed_s": elapsed,
                                          **evaluate(_textures(opt, resolution))})
            if progress is not None:
                progress(EpochReport(epoch + 1, settings.epochs, trace.epoch_loss[-1], elapsed, _resident_mb()))
        full = trace.epoch_loss[settings.full_resolution_from:]  # a coarse level's loss is another problem's
        if settings.stop_window and stop_epoch(full, settings.stop_window, settings.stop_fall):
            break  # the training loss has levelled off: converged by its own measure, no ground truth

    params.update(opt)
    return InverseResult(textures=_textures(params, resolution), loss=np.asarray(trace.loss), views=tuple(trace.views),
                         epoch=np.asarray(trace.epoch, dtype=np.int64), epoch_loss=np.asarray(trace.epoch_loss),
                         evaluations=trace.evaluations)


def _double_resolution(opt) -> None:
    """Coarse to fine: every texture texel to 2 x 2 (a new shape, so Adam resets its state)."""
    import drjit as dr

    for key in _PARAM_KEYS.values():
        r, _, c = opt[key].shape
        opt[key] = dr.resample(opt[key], (2 * r, 2 * r, c), filter="box")


def _textures(params, resolution: int) -> dict[str, np.ndarray]:
    """Textures as float32 (R, R[, 3]) arrays from the scene's parameters or the optimiser (which holds
    the latest step's values; the scene gets them at the next step), clamped to [0, 1] after every
    step; a coarse level's at full size (:func:`full_size`)."""
    textures = {}
    for name, key in _PARAM_KEYS.items():
        value = full_size(np.array(params[key], dtype=np.float32), resolution)
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
