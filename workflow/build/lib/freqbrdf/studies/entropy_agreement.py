"""Entropy agreement (paper section 5.4.1, Table 3): the entropy of a grid likelihood
computed with a path tracer, with our forward model, and from the power spectra.

The paper's reference entropy renders uniform materials on a grid of
8 x 8 x 8 (roughness, metallic, base colour) values with Mitsuba, scores each
texel's observations against every grid point, and takes the normalised
entropy of the resulting likelihood. The "angular" entropy does the same with
the mixed forward model of section 4.3 in place of the path tracer, and the
power-spectrum entropy (section 4.5, Eqs. 23-25) replaces the whole grid over
images by a grid over two spectrum parameters. Table 3 reports how well the
two cheap entropies correlate with the expensive one.

Both image-space entropies share one objective and one likelihood:

``D_g = sum_k w_k (B_g,k - B'_k)^2 / Lbar^2``, ``p_g ~ exp(-D_g / (2 sigma^2))``

per texel and colour channel, over the texel's observed views ``k`` (weights
``w_k = cos theta_o``), where ``B_g,k`` is the radiance that grid point ``g``
gives, ``B'_k`` the observed radiance and ``Lbar^2`` the weighted mean square
of the light along the texel's mirror directions. Dividing by the light (as
the spectrum entropy divides its spectra by the light's power) lets one sigma
mean the same for bright and dark texels; summing (not averaging) over views
keeps the likelihood sharpening as views are added. The channels are
independent in both renderers, so a grey base colour ``(b, b, b)`` scores
``b`` in every channel at once: one render per grid point serves all three.
"""

from __future__ import annotations

import time
from collections.abc import Callable, Iterable, Iterator
from dataclasses import dataclass
from types import ModuleType

import numpy as np

from freqbrdf.artefacts import Observations
from freqbrdf.estimate.light import LightQuadrature
from freqbrdf.estimate.optimise.kernels import KernelModel
from freqbrdf.estimate.optimise.model import forward, light_terms
from freqbrdf.estimate.optimise.problem import build_problem
from freqbrdf.estimate.spectrum import combine_entropy, grid_entropy
from freqbrdf.util.validation import check_int, check_positive, check_shape

MATERIAL_AXES = ("roughness", "metallic", "base")


def material_grid(n: int) -> np.ndarray:
    """The uniform materials of the grid: ``n`` values in [0, 1] per axis.

    Parameters
    ----------
    n : int
        Values per axis (paper: 8).

    Returns
    -------
    numpy.ndarray
        Shape ``(n^3, 3)``: roughness, metallic, base colour per grid point,
        roughness varying slowest (one shadowed-light fit serves ``n^2`` points).
    """
    n = check_int(n, "grid", 2)
    axis = np.linspace(0.0, 1.0, n)
    r, m, b = np.meshgrid(axis, axis, axis, indexing="ij")
    return np.stack([r.ravel(), m.ravel(), b.ravel()], axis=1)


def texel_sample(obs: Observations, index: np.ndarray) -> Observations:
    """The observations of the texels ``index`` only (arrays read into memory)."""
    index = np.asarray(index, dtype=np.int64)
    return Observations(obs.texels.subset(index), np.asarray(obs.radiance[index]), np.asarray(obs.weight[index]),
                        np.asarray(obs.wo_local[index]), np.asarray(obs.incoming[index]), obs.meta)


@dataclass(frozen=True)
class Pairs:
    """The observed (texel, view) pairs of a capture, flat (P pairs, S texels).

    Attributes
    ----------
    texel, view : numpy.ndarray
        Shape ``(P,)``, int: the pair's texel (``0 <= texel < S``) and view.
    radiance : numpy.ndarray
        Shape ``(P, 3)``: observed radiance B'.
    weight : numpy.ndarray
        Shape ``(P,)``: ``cos theta_o``.
    light_power : numpy.ndarray
        Shape ``(S, 3)``: weighted mean square of the light along each texel's
        mirror directions (``Lbar^2``); 0 for texels without observations.
    """

    texel: np.ndarray
    view: np.ndarray
    radiance: np.ndarray
    weight: np.ndarray
    light_power: np.ndarray

    @classmethod
    def of(cls, obs: Observations) -> Pairs:
        """The pairs with ``weight > 0`` of ``obs``."""
        w = np.asarray(obs.weight, dtype=np.float64)
        texel, view = np.nonzero(w > 0)
        weight = w[texel, view]
        light = np.asarray(obs.incoming, dtype=np.float64)[texel, view]
        n_tex = w.shape[0]
        total = np.bincount(texel, weights=weight, minlength=n_tex)
        power = np.stack([np.bincount(texel, weights=weight * light[:, c] ** 2, minlength=n_tex)
                          for c in range(3)], axis=1)
        power = np.divide(power, total[:, None], out=np.zeros_like(power), where=total[:, None] > 0)
        return cls(texel, view, np.asarray(obs.radiance, dtype=np.float64)[texel, view], weight, power)

    @property
    def n_texels(self) -> int:
        return self.light_power.shape[0]


def grid_objective(model: Iterable[np.ndarray], pairs: Pairs) -> np.ndarray:
    """``D`` of every texel, grid point and channel (module docstring).

    Parameters
    ----------
    model : iterable of numpy.ndarray
        For each grid point in turn, shape ``(P, 3)``: the radiance it gives at every pair.
    pairs : Pairs
        The observations scored.

    Returns
    -------
    numpy.ndarray
        Shape ``(S, G, 3)``, float64, dimensionless; ``inf`` where the light
        along a texel's mirror directions is dark in a channel (no scale).
    """
    inverse = np.divide(1.0, pairs.light_power, out=np.full_like(pairs.light_power, np.inf),
                        where=pairs.light_power > 0)
    columns = []
    for g, radiance in enumerate(model):
        b = np.asarray(radiance, dtype=np.float64)
        check_shape(b, f"model radiance of grid point {g}", pairs.radiance.shape)
        residual = pairs.weight[:, None] * (b - pairs.radiance) ** 2
        sums = np.stack([np.bincount(pairs.texel, weights=residual[:, c], minlength=pairs.n_texels)
                         for c in range(3)], axis=1)
        with np.errstate(invalid="ignore"):
            columns.append(np.where(np.isinf(inverse), np.inf, sums * inverse))
    if len(columns) < 2:
        raise ValueError(f"the grid needs at least 2 points, got {len(columns)}")
    return np.stack(columns, axis=1)


def likelihood_entropy(objective: np.ndarray, sigma: float, combine: str = "min") -> np.ndarray:
    """Normalised entropy of ``p_g ~ exp(-D_g / (2 sigma^2))`` per texel, channels combined.

    Parameters
    ----------
    objective : numpy.ndarray
        Shape ``(S, G, 3)`` (`grid_objective`).
    sigma : float
        Noise scale of D (relative to the light).
    combine : {"min", "luminance"}
        How the channels' entropies are combined (:func:`freqbrdf.estimate.spectrum.combine_entropy`).

    Returns
    -------
    numpy.ndarray
        Shape ``(S,)``, in [0, 1]; 1 for a channel without light (``D = inf``).
    """
    d = np.asarray(objective, dtype=np.float64)
    check_shape(d, "objective", (None, None, 3))
    sigma = check_positive(sigma, "sigma")
    finite = np.isfinite(d).all(axis=1)  # (S, 3)
    h = grid_entropy(np.where(finite[:, None, :], d, 0.0)[:, :, None, :], sigma)
    return combine_entropy(np.where(finite, h, 1.0), combine)


def angular_radiance(obs: Observations, irradiance: np.ndarray, light: LightQuadrature, grid: np.ndarray,
                     workers: int = 1, lobe: np.ndarray | None = None,
                     view: np.ndarray | None = None) -> Iterator[np.ndarray]:
    """Radiance of each uniform material of ``grid`` at the observed pairs, by the mixed
    forward model with shadowing and masking (paper section 4.3, Eqs. 14-18).

    Parameters
    ----------
    obs : Observations
        S texels x K views.
    irradiance : numpy.ndarray
        Shape ``(S, 3)``, E at the texel normals.
    light : LightQuadrature
        The capture's environment (:func:`freqbrdf.estimate.light.light_quadrature`).
    grid : numpy.ndarray
        Shape ``(G, 3)``: roughness, metallic, base colour (`material_grid`).
    workers : int
        Threads.
    lobe : numpy.ndarray, optional
        The lobe spectrum (:func:`freqbrdf.sphere.lobes.lobe_table`, config ``optimise.lobe``); default the paper's.
    view : numpy.ndarray, optional
        The weights per view (:func:`freqbrdf.sphere.lobes.view_table`, config
        ``optimise.view_weight`` and ``diffuse``); default the paper's.

    Yields
    ------
    numpy.ndarray
        Shape ``(P, 3)`` per grid point, pairs in the order of `Pairs.of`.
    """
    grid = np.asarray(grid, dtype=np.float64)
    check_shape(grid, "grid", (None, 3))
    problem = build_problem(obs, irradiance, "float64")
    pairs = Pairs.of(obs)
    fitted, p = None, None
    x = np.empty((problem.n_texels, 5))
    for roughness, metallic, base in grid:
        if roughness != fitted:  # the shadowed light depends on roughness only
            p = light_terms(np.full(problem.n_texels, roughness), problem, True, light, workers)
            fitted = roughness
        x[:, :3], x[:, 3], x[:, 4] = base, roughness, metallic
        yield forward(x, problem, p, KernelModel(True, lobe, view))[pairs.texel, pairs.view]


def uniform_material_scene(mi: ModuleType, mesh: str, envmap: np.ndarray, max_depth: int):
    """The object with a uniform ``principled`` material under its environment, path traced.

    Returns
    -------
    mitsuba.Scene
        Its material is set by `set_material`.
    """
    return mi.load_dict({
        "type": "scene",
        "integrator": {"type": "path", "max_depth": int(max_depth)},
        "emitter": {"type": "envmap", "bitmap": mi.Bitmap(np.ascontiguousarray(envmap, dtype=np.float32))},
        "object": {"type": "ply", "filename": str(mesh),
                   "bsdf": {"type": "principled", "base_color": {"type": "rgb", "value": [0.5, 0.5, 0.5]},
                            "roughness": 0.5, "metallic": 0.0}},
    })


def mitsuba_radiance(mi: ModuleType, scene, obs: Observations, grid: np.ndarray, spp: int,
                     seeds: tuple[int, ...] = (0,), offset: float = 1e-2) -> Iterator[np.ndarray]:
    """Radiance of each uniform material of ``grid`` at the observed pairs, path traced by Mitsuba.

    Each pair's rays start ``offset`` above its texel along the direction to
    the camera and point back at the texel, so the path tracer returns the
    radiance leaving the texel towards that camera (what the observation
    sampled from the image), without rendering images. Every grid point uses
    the same random numbers, so differences between grid points are not noise;
    each seed gives an independent estimate, and their mean one with
    ``len(seeds) spp`` paths.

    Parameters
    ----------
    mi : module
        Mitsuba, with a variant set.
    scene : mitsuba.Scene
        From `uniform_material_scene`.
    obs : Observations
        S texels x K views (positions and frames are used).
    grid : numpy.ndarray
        Shape ``(G, 3)``: roughness, metallic, base colour.
    spp : int
        Paths per pair.
    seeds : tuple of int
        Seeds of the sampler (32-bit), one estimate each.
    offset : float
        Start of the rays above the surface (object radius 1).

    Yields
    ------
    numpy.ndarray
        Shape ``(len(seeds), P, 3)`` per grid point, pairs in the order of `Pairs.of`.
    """
    spp = check_int(spp, "spp", 1)
    pairs = Pairs.of(obs)
    frame = obs.frame[pairs.texel]
    wo = np.einsum("pji,pj->pi", frame, np.asarray(obs.wo_local, dtype=np.float64)[pairs.texel, pairs.view])
    origin = np.repeat(obs.texels.position[pairs.texel] + offset * wo, spp, axis=0).astype(np.float32)
    direction = np.repeat(-wo, spp, axis=0).astype(np.float32)
    ray = mi.Ray3f(mi.Point3f(*origin.T), mi.Vector3f(*direction.T))
    sampler = mi.load_dict({"type": "independent"})
    integrator = scene.integrator()
    params = mi.traverse(scene)
    for roughness, metallic, base in np.asarray(grid, dtype=np.float64):
        params["object.bsdf.roughness.value"] = float(roughness)
        params["object.bsdf.metallic.value"] = float(metallic)
        params["object.bsdf.base_color.value"] = mi.Color3f(float(base), float(base), float(base))
        params.update()
        estimates = []
        for seed in seeds:
            sampler.seed(int(seed) & 0xFFFFFFFF, len(origin))
            spectrum, _, _ = integrator.sample(scene, sampler, ray)
            estimates.append(np.array(spectrum, dtype=np.float64).T.reshape(-1, spp, 3).mean(axis=1))
        yield np.stack(estimates)


def timed(evaluate: Callable[[], np.ndarray]) -> tuple[np.ndarray, float]:
    """``evaluate()`` and its wall time in seconds."""
    start = time.perf_counter()
    value = evaluate()
    return value, time.perf_counter() - start
