"""Settings of the gradient-descent estimator (paper section 4.3), the layout of its
packed parameters, and the roughness its light's band limit can resolve."""

from __future__ import annotations

from dataclasses import dataclass, replace
from typing import Mapping

import numpy as np

from freqbrdf.estimate.light_table import TableSize
from freqbrdf.methods import get_method
from freqbrdf.sphere.brdf import ALPHA_MIN
from freqbrdf.sphere.lobes import DIFFUSE_LOBES, LOBES, VIEW_WEIGHTS, ggx_lobe_spectrum
from freqbrdf.util.validation import check_choice, check_int

__all__ = ["PARAM_COLUMNS", "N_PARAMS", "DTYPES", "SOLVERS", "method_terms", "OptimiseSettings",
           "identifiable_roughness"]

PARAM_COLUMNS = ("base_r", "base_g", "base_b", "roughness", "metallic")  # columns of a packed (T, 5) array
N_PARAMS = len(PARAM_COLUMNS)
DTYPES = ("float32", "float64")
SOLVERS = ("adam", "lm")


def method_terms(method: str) -> tuple[bool, bool]:
    """(shadowing, masking) of a method of rule ``optimise_svbrdf``; its light's pre-filter is
    the caller's (`freqbrdf.estimate.light.light_quadrature`)."""
    entry = get_method(method, "optimise_svbrdf")
    return entry.shadowing, entry.masking


@dataclass(frozen=True)
class OptimiseSettings:
    """Settings of `optimise`.

    The fields the config's ``optimise`` block sets (``solver`` to
    ``min_roughness``) have no defaults here: the pipeline's live in
    ``config/config.yaml`` (`from_config` builds the settings from them), the
    paper's in the preset `paper`. The implementation's own fields, which no
    config sets (``sweep_tolerance`` on), keep their defaults.

    Attributes
    ----------
    solver : {"adam", "lm"}
        ``lm``: per-texel Levenberg-Marquardt on reweighted least squares,
        the atlas's two checkerboard colours in turn (`lm_sweep`); ``adam``:
        Adam on all texels at once (the authors' code).
    lobe : {"gaussian", "ggx"}
        Zonal spectrum of the specular lobe (`freqbrdf.sphere.lobes.LOBES`): the
        paper's ``exp(-(alpha l)^2)`` or GGX's own (`freqbrdf.sphere.lobes.ggx_lobe_spectrum`).
    view_weight : {"paper", "albedo"}
        Weight of the filtered light per view (`freqbrdf.sphere.lobes.VIEW_WEIGHTS`): the paper's
        ``F(theta_o) G1(theta_o)`` or GGX's directional albedo (`freqbrdf.sphere.lobes.view_table`),
        for the methods with shadowing and masking; the others ablate the paper's terms and keep its weight.
    diffuse : {"lambert", "principled"}
        The diffuse term's view dependence (`freqbrdf.sphere.lobes.DIFFUSE_LOBES`): the paper's
        Lambertian, or the principled BSDF's (`freqbrdf.sphere.lobes.principled_diffuse_albedo`).
    sweeps : int
        ``lm``: sweeps over both colours (one damped Gauss-Newton step per texel each).
    sweep_refit_every : int
        ``lm``: sweeps between refits of the shadowed light.
    iterations : int
        Adam steps (one full batch each).
    grid_start : bool
        Start each texel from the best point of a roughness x metallic grid
        (`grid_start`) unless an explicit start is given.
    lr : float
        Adam learning rate.
    refit_every : int
        Iterations between refits of the shadowed light ``Lg`` (the first
        fit is at iteration 0; methods without shadowing fit once).
    tv_weight : float
        Weight of the total variation of the parameter textures, ``>= 0``.
    min_roughness : float
        Lower bound of the fitted roughness, in [0, 1), e.g.
        `identifiable_roughness` of the light's degree: below it the model
        does not resolve the lobe (docs/method.md, "Identifiable roughness").
    variance_scale : float
        Calibration of the posterior's variances (`freqbrdf.estimate.optimise.posterior`), > 0.
    light_table : TableSize
        The shadowed light from one table per environment
        (`freqbrdf.estimate.light_table.ShadowedLightTable`), or with ``rows`` 0
        fitted per texel at every refit (`freqbrdf.estimate.light.shadowed_light`).
    sweep_tolerance : float
        ``lm``: stop once a sweep lowers the objective by less than this
        fraction (after the last refit).
    irls_floor, tv_floor : float
        ``lm``: floors of the reweighting of the data residuals (relative
        to each texel's mean radiance) and of the TV differences.
    damping : float
        ``lm``: initial Marquardt damping of every texel.
    grid_roughness, grid_metallic : int
        Grid points in [0, 1] of each.
    betas : tuple of float
        Adam decay rates of the first and second moment.
    eps : float
        Adam denominator offset.
    refit_tolerance : float
        A refit skips texels whose roughness moved less than this since
        their last fit (at roughness 0.5 and 80 degrees from the normal,
        ``G1`` changes by 3%).
    workers : int
        Threads (texels run concurrently; results are identical
        for any number).
    dtype : {"float32", "float64"}
        Precision of the per-observation arrays (parameters, gradients and
        Adam moments are always float64; the loss is accumulated in float64).
    """

    solver: str
    lobe: str
    view_weight: str
    diffuse: str
    sweeps: int
    sweep_refit_every: int
    iterations: int
    grid_start: bool
    lr: float
    refit_every: int
    tv_weight: float
    min_roughness: float
    light_table: TableSize
    variance_scale: float
    sweep_tolerance: float = 1e-4
    irls_floor: float = 1e-2
    tv_floor: float = 1e-2
    damping: float = 1e-2
    grid_roughness: int = 21
    grid_metallic: int = 5
    betas: tuple[float, float] = (0.9, 0.999)
    eps: float = 1e-8
    refit_tolerance: float = 0.02
    workers: int = 1
    dtype: str = "float32"

    def __post_init__(self) -> None:
        for name, choices in (("solver", SOLVERS), ("lobe", LOBES), ("view_weight", VIEW_WEIGHTS),
                              ("diffuse", DIFFUSE_LOBES), ("dtype", DTYPES)):
            check_choice(getattr(self, name), name, choices)
        check_int(self.sweeps, "sweeps", 0)
        check_int(self.sweep_refit_every, "sweep_refit_every", 1)
        for name in ("sweep_tolerance", "irls_floor", "tv_floor", "damping"):
            value = getattr(self, name)
            if not (np.isfinite(value) and value > 0):
                raise ValueError(f"{name} must be a finite number > 0, got {value!r}")
        check_int(self.iterations, "iterations", 0)
        check_int(self.grid_roughness, "grid_roughness", 2)
        check_int(self.grid_metallic, "grid_metallic", 2)
        check_int(self.refit_every, "refit_every", 1)
        check_int(self.workers, "workers", 1)
        if not (np.isfinite(self.lr) and self.lr > 0):
            raise ValueError(f"lr must be a finite number > 0, got {self.lr!r}")
        if len(self.betas) != 2 or not all(0.0 <= b < 1.0 for b in self.betas):
            raise ValueError(f"betas must be two numbers in [0, 1), got {self.betas!r}")
        if not (np.isfinite(self.eps) and self.eps > 0):
            raise ValueError(f"eps must be a finite number > 0, got {self.eps!r}")
        if not (np.isfinite(self.refit_tolerance) and self.refit_tolerance >= 0):
            raise ValueError(f"refit_tolerance must be a finite number >= 0, got {self.refit_tolerance!r}")
        if not (np.isfinite(self.tv_weight) and self.tv_weight >= 0):
            raise ValueError(f"tv_weight must be a finite number >= 0, got {self.tv_weight!r}")
        if not (np.isfinite(self.variance_scale) and self.variance_scale > 0):
            raise ValueError(f"variance_scale must be a finite number > 0, got {self.variance_scale!r}")
        if not isinstance(self.light_table, TableSize):
            raise TypeError(f"light_table must be a TableSize, got {type(self.light_table).__name__}")
        if not 0.0 <= self.min_roughness < 1.0:
            raise ValueError(f"min_roughness must be in [0, 1), got {self.min_roughness!r}")

    @classmethod
    def paper(cls, **overrides: object) -> OptimiseSettings:
        """The paper's estimator (section 4.3) and the authors' code, with ``overrides``.

        From the paper: the Gaussian lobe ``exp(-(alpha l)^2)``, the specular
        weight ``F(theta_o) G1(theta_o)`` per view, the Lambertian diffuse term,
        TV weight 1e-3, no roughness bound, the shadowed light fitted per texel
        (``light_table`` rows 0). From the authors' code (METHOD.md
        section 5): Adam, lr 0.02 (of 0.01-0.02), 150 iterations (of 100-200),
        the shadowed light refitted every 50. This project's, not the paper's:
        the grid start (the authors start from 0.5 or the spectrum search) and
        the ``lm`` solver's ``sweeps`` 12 and ``sweep_refit_every`` 4, unused by
        Adam. ``config/paper.yaml`` merged over ``config/config.yaml`` gives
        the same (tested).

        Parameters
        ----------
        **overrides
            Fields to change (`dataclasses.replace`), e.g. ``iterations=300``.

        Returns
        -------
        OptimiseSettings
        """
        preset = cls(solver="adam", lobe="gaussian", view_weight="paper", diffuse="lambert", sweeps=12,
                     sweep_refit_every=4, iterations=150, grid_start=True, lr=0.02, refit_every=50,
                     tv_weight=1e-3, min_roughness=0.0, light_table=TableSize(rows=0, rank=4),
                     variance_scale=1.0)
        return replace(preset, **overrides)

    @classmethod
    def from_config(cls, config: Mapping[str, object], workers: int = 1) -> OptimiseSettings:
        """Settings from config ``optimise``, the pipeline's (``min_roughness: auto`` is
        `identifiable_roughness` of ``lmax``; ``init: grid`` starts from the grid)."""
        bound = config["min_roughness"]
        return cls(solver=config["solver"], lobe=config["lobe"], view_weight=config["view_weight"],
                   diffuse=config["diffuse"], sweeps=config["sweeps"],
                   sweep_refit_every=config["sweep_refit_every"],
                   iterations=config["iterations"], lr=config["lr"], refit_every=config["refit_every"],
                   tv_weight=config["tv_weight"], workers=workers, light_table=TableSize(**config["light_table"]),
                   variance_scale=config["variance_scale"], grid_start=config["init"] == "grid",
                   min_roughness=identifiable_roughness(config["lmax"], lobe=config["lobe"]) if bound == "auto"
                   else float(bound))


def identifiable_roughness(lmax: int, tail: float = 0.05, lobe: str = "gaussian") -> float:
    """Smallest roughness whose lobe the model at degree l* represents.

    The lobe ``exp(-(alpha l)^2)`` applied to a point light has its value at
    the mirror direction spread over degrees with weights ``(2l + 1) exp(-(alpha l)^2)``;
    the share above l* is about ``exp(-(alpha (l* + 1))^2)``. Requiring it
    below ``tail`` gives ``alpha >= sqrt(ln(1 / tail)) / (l* + 1)``, and
    ``roughness = sqrt(alpha)``: 0.29 at l* = 20 (measured on noise-free texels
    under the sun: roughness 0.3 recovered within 0.04, 0.25 off by up to 0.13).
    GGX's spectrum (`freqbrdf.sphere.lobes.ggx_lobe_spectrum`) keeps more of the high
    degrees; its share above l* is summed numerically (to degree 16 (l* + 1))
    and the alpha where it falls below ``tail`` bisected (to 1e-4): 0.356 at l* = 20.

    Parameters
    ----------
    lmax : int
        Degree l* of the model's light.
    tail : float
        Largest share of the lobe allowed above l*, in (0, 1).
    lobe : {"gaussian", "ggx"}
        The lobe (`freqbrdf.sphere.lobes.LOBES`).

    Returns
    -------
    float
        Roughness in (0, 1).
    """
    lmax = check_int(lmax, "lmax", 0)
    if not 0.0 < tail < 1.0:
        raise ValueError(f"tail must be in (0, 1), got {tail!r}")
    if check_choice(lobe, "lobe", LOBES) == "gaussian":
        return float(np.sqrt(min(np.sqrt(np.log(1.0 / tail)) / (lmax + 1), 1.0)))
    degrees = np.arange(16 * (lmax + 1) + 1)

    def share_above(alpha: float) -> float:
        weight = (2 * degrees + 1) * ggx_lobe_spectrum(np.array([alpha]), degrees[-1])[0][0]
        return float(weight[lmax + 1 :].sum() / weight.sum())

    if share_above(1.0) >= tail:
        return 1.0
    lo, hi = ALPHA_MIN, 1.0  # the share falls as the lobe widens: bisect for where it crosses ``tail``
    while hi - lo > 1e-4:
        mid = 0.5 * (lo + hi)
        lo, hi = (mid, hi) if share_above(mid) >= tail else (lo, mid)
    return float(np.sqrt(hi))
