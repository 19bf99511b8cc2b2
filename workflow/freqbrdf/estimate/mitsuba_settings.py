"""Settings of the differentiable-rendering baseline (config ``mitsuba``) and its schedule.

:class:`InverseSettings` holds what :func:`freqbrdf.estimate.mitsuba.optimise_textures`
needs, each field checked on construction with a one-line error naming it.
``lr`` and ``tv_weight`` are one number for every texture, or a mapping
``{base_color, roughness, metallic} -> number``. The schedule of a run: the
seeded view order of each epoch (:func:`view_order`), the sampler seeds of
each render (:func:`render_seeds`) and the learning rate's decay
(:func:`lr_factor`). :func:`run_settings` reads one run's settings from the config.
"""

from __future__ import annotations

import math
from collections.abc import Mapping
from dataclasses import dataclass

import numpy as np

from freqbrdf.util.seeds import derived_seed
from freqbrdf.methods import METHODS
from freqbrdf.sphere.brdf import TEXTURES
from freqbrdf.util.validation import check_choice, check_int

LOSSES = ("l1log", "l2", "l1rel")
LR_DECAYS = ("none", "cosine")


def _per_texture(value: object, name: str, *, positive: bool) -> float | dict[str, float]:
    """A checked number, or a mapping of every texture name to a checked number (returned as a dict).

    A number must be finite and ``> 0`` (``positive``) or ``>= 0``; a mapping's
    values must be finite and ``>= 0``, and with ``positive`` at least one ``> 0``.

    Raises
    ------
    ValueError
        One line naming the key (``lr``, ``lr.roughness``, ...).
    """
    if isinstance(value, Mapping):
        unknown = sorted(str(k) for k in value if k not in TEXTURES)
        missing = [k for k in TEXTURES if k not in value]
        if unknown or missing:
            wrong = f"unknown keys {unknown}" if unknown else f"missing keys {missing}"
            raise ValueError(f"{name}: {wrong}; a mapping needs exactly the keys {list(TEXTURES)}")
        out = {k: _number(value[k], f"{name}.{k}", positive=False) for k in TEXTURES}
        if positive and max(out.values()) <= 0.0:
            raise ValueError(f"{name}: at least one texture's value must be > 0, got {out}")
        return out
    return _number(value, name, positive=positive)


def _number(value: object, name: str, *, positive: bool) -> float:
    """``value`` if it is a finite real number, ``> 0`` (``positive``) or ``>= 0``; returned unchanged."""
    bound = "> 0" if positive else ">= 0"
    if isinstance(value, (bool, np.bool_)) or not isinstance(value, (int, float, np.integer, np.floating)):
        raise ValueError(f"{name} must be a finite number {bound} or a mapping of {list(TEXTURES)}, "
                         f"got {type(value).__name__} {value!r}")
    if not (np.isfinite(value) and (value > 0 if positive else value >= 0)):
        raise ValueError(f"{name} must be a finite number {bound}, got {value!r}")
    return value


@dataclass(frozen=True)
class InverseSettings:
    """Settings of the differentiable-rendering optimiser (config ``mitsuba``).

    Attributes
    ----------
    epochs : int
        Passes over the training views; each visits every view once.
    spp : int
        Samples per pixel of each view's render in a step (the ``prb``
        integrator uses the same count for its adjoint pass).
    lr : float or dict
        Adam learning rate (texture values are in [0, 1]): one number ``> 0``,
        or ``{base_color, roughness, metallic} -> number >= 0`` (0 freezes
        that texture; at least one ``> 0``).
    loss : {"l1log", "l2", "l1rel"}
        Image distance (:func:`freqbrdf.estimate.mitsuba.image_loss`).
    tv_weight : float or dict
        Weight of the textures' total variation, ``>= 0``: one for all five
        channels, or one per texture (its own channels).
    max_depth : int
        Path length limit of ``prb`` (-1: unlimited; 2: direct light only).
    seed : int
        Seeds the view order of every epoch and every render's sampler.
    views_per_step : int
        Views rendered per Adam step (the next ones of the epoch's order),
        their losses averaged; an epoch has ceil(views / views_per_step) steps.
    loss_eps : float
        ``eps`` of ``l1rel``'s ``|log(I + eps) - log(I' + eps)|``, ``> 0``
        (unused by the other losses).
    lr_decay : {"none", "cosine"}
        ``cosine`` multiplies the learning rate by ``0.5 (1 + cos(pi t))``,
        ``t`` the fraction of the run's steps done (:func:`lr_factor`).
    stop_window : int
        Stop before ``epochs`` once the training loss has levelled off (:func:`stop_epoch`, no
        ground truth): the mean loss of the last ``stop_window`` epochs fell by less than
        ``stop_fall`` from that of the ``stop_window`` before. 0: run every epoch.
    stop_fall : float
        That relative fall, in [0, 1).
    coarse_levels : int
        Coarse to fine, as Mitsuba's tutorials optimise textures: the textures start at
        ``1 / 2**coarse_levels`` of their resolution (block means of the start) and double it,
        nearest-neighbour, every ``coarse_epochs`` epochs, Adam's state reset at each doubling,
        until full; 0: full resolution throughout. A run stops by its loss
        (``stop_window``) only once at full resolution.
    coarse_epochs : int
        Epochs at each coarse level, >= 1; ``epochs`` must exceed ``coarse_levels * coarse_epochs``.
    crop : bool
        Render only a window of each view that holds every pixel of loss weight > 0, one window
        size for all views (:func:`freqbrdf.estimate.mitsuba.crop_windows`): the pixels outside
        it add nothing to the loss or its gradient, so the estimate is the same in expectation
        and a step costs less, the more so the smaller the object in the image.
    """

    epochs: int = 10
    spp: int = 32
    lr: float | Mapping[str, float] = 0.01
    loss: str = "l1log"
    tv_weight: float | Mapping[str, float] = 1e-3
    max_depth: int = 8
    seed: int = 0
    views_per_step: int = 1
    loss_eps: float = 0.01
    lr_decay: str = "none"
    stop_window: int = 0
    stop_fall: float = 0.01
    coarse_levels: int = 0
    coarse_epochs: int = 1
    crop: bool = False

    def __post_init__(self) -> None:
        check_int(self.epochs, "epochs", 1)
        check_int(self.spp, "spp", 1)
        check_int(self.seed, "seed", 0)
        check_int(self.views_per_step, "views_per_step", 1)
        check_int(self.max_depth, "max_depth", -1)
        if self.max_depth == 0:
            raise ValueError("max_depth must be -1 (unlimited) or >= 1, got 0")
        object.__setattr__(self, "lr", _per_texture(self.lr, "lr", positive=True))
        check_choice(self.loss, "loss", LOSSES)
        object.__setattr__(self, "tv_weight", _per_texture(self.tv_weight, "tv_weight", positive=False))
        _number(self.loss_eps, "loss_eps", positive=True)
        check_choice(self.lr_decay, "lr_decay", LR_DECAYS)
        check_int(self.stop_window, "stop_window", 0)
        if not 0.0 <= _number(self.stop_fall, "stop_fall", positive=False) < 1.0:
            raise ValueError(f"stop_fall must be in [0, 1), got {self.stop_fall!r}")
        check_int(self.coarse_levels, "coarse_levels", 0)
        check_int(self.coarse_epochs, "coarse_epochs", 1)
        if not isinstance(self.crop, bool):
            raise ValueError(f"crop must be true or false, got {self.crop!r}")
        if self.epochs <= self.full_resolution_from:
            raise ValueError(f"epochs ({self.epochs}) must exceed coarse_levels x coarse_epochs "
                             f"({self.coarse_levels} x {self.coarse_epochs}), so the run ends at full resolution")

    @property
    def full_resolution_from(self) -> int:
        """Epochs run at a coarse level before the first at full resolution (0 without coarse levels)."""
        return self.coarse_levels * self.coarse_epochs

    def doubles_before(self, epoch: int) -> bool:
        """Whether the textures double their resolution before 0-based ``epoch``."""
        return 0 < epoch <= self.full_resolution_from and epoch % self.coarse_epochs == 0

    def steps_per_epoch(self, n_views: int) -> int:
        """Adam steps of one epoch over ``n_views`` views: ceil(n_views / views_per_step)."""
        return -(-int(n_views) // self.views_per_step)

    def learning_rates(self, step: int, steps: int) -> float | dict[str, float]:
        """The learning rate(s) of 0-based ``step`` of ``steps``: ``lr`` times :func:`lr_factor`.

        Returns a float for one ``lr``, else a dict per texture name. Without
        decay the factor is exactly 1, so the values are ``lr``'s own.
        """
        factor = lr_factor(self.lr_decay, step, steps)
        if isinstance(self.lr, Mapping):
            return {name: float(value) * factor for name, value in self.lr.items()}
        return float(self.lr) * factor


def run_settings(config: Mapping, obj: str, env: str, poses: str, method: str) -> dict:
    """The keyword arguments of :class:`InverseSettings` for one run of rule ``mitsuba``.

    Config ``mitsuba`` less ``variant``, with ``mitsuba.finetune`` overriding
    its keys when ``method`` starts from another method's estimate, and a seed
    per capture and method (derived from config ``seed``).
    """
    block = config["mitsuba"]
    settings = {key: value for key, value in block.items() if key not in ("finetune", "variant")}
    if METHODS[method].start is not None:
        settings.update(block["finetune"])
        settings["coarse_levels"] = 0  # a fine-tuning starts from an estimate at full resolution
    settings["seed"] = derived_seed(config["seed"], "mitsuba", obj, env, poses, method)
    return settings


def lr_factor(decay: str, step: int, steps: int) -> float:
    """Learning-rate factor of 0-based ``step`` of ``steps``.

    ``none``: 1. ``cosine``: ``0.5 (1 + cos(pi t))`` with ``t = step / steps``
    the fraction of steps done, from 1 at the first step to nearly 0 at the last.
    """
    check_choice(decay, "lr_decay", LR_DECAYS)
    if not 0 <= step < steps:
        raise ValueError(f"step must be in [0, {steps}), got {step}")
    if decay == "none":
        return 1.0
    return 0.5 * (1.0 + math.cos(math.pi * step / steps))


def stop_epoch(epoch_loss: np.ndarray, window: int, fall: float) -> int | None:
    """The first epoch after which the training loss counts as levelled off, or None.

    After epoch ``e`` (1-based, ``e >= 2 window``) the mean loss of epochs ``e - window + 1 .. e``
    is compared with that of the ``window`` epochs before: levelled off when it fell by less
    than ``fall`` of the earlier mean. Over whole epochs, so every view weighs the same; over
    windows, because one epoch's loss at a few samples per pixel is noisy.

    Parameters
    ----------
    epoch_loss : ndarray, shape (E,)
        Mean training loss of each epoch done.
    window : int
        Epochs per window, >= 1.
    fall : float
        Relative fall below which the loss has levelled off.

    Returns
    -------
    int or None
        The epoch (1-based), or None if the loss is still falling at every epoch so far.
    """
    loss = np.asarray(epoch_loss, dtype=np.float64)
    check_int(window, "stop_window", 1)
    for e in range(2 * window, len(loss) + 1):
        before, last = loss[e - 2 * window:e - window].mean(), loss[e - window:e].mean()
        if before - last < fall * before:
            return e
    return None


def render_seeds(seed: int, render: int) -> tuple[int, int]:
    """Sampler seeds (32-bit) of the primal and adjoint passes of the run's 0-based ``render``-th view render.

    Distinct strides keep the two passes' noise independent (correlated
    noise biases the gradient) and every render's noise different, also
    between the views of one step. With one view per step, ``render`` is
    the step's index.
    """
    primal = (int(seed) * 0x85EBCA6B + render * 0x9E3779B1 + 1) & 0xFFFFFFFF
    adjoint = (int(seed) * 0xC2B2AE35 + render * 0x27D4EB2F + 2) & 0xFFFFFFFF
    return primal, adjoint


def view_order(seed: int, epoch: int, n_views: int) -> np.ndarray:
    """Seeded random order of the views in one epoch, shape (n_views,)."""
    return np.random.default_rng([int(seed), int(epoch)]).permutation(n_views)
