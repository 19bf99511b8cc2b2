"""Does a sandwich (cluster-robust) posterior rank `freq`'s per-texel errors better than the Laplace one?

The fit's posterior (`freqbrdf.estimate.optimise.posterior`) is Laplace's: per texel
``A^-1`` with ``A = J^T J / s^2 + P``, ``s^2`` the residual variance the fit leaves and ``P`` the
prior's precision. It sees how large the residuals are, not where they fall. The sandwich
``A^-1 B A^-1``, with ``B`` the sum over the texel's pairs of ``g g^T``, ``g = J_p^T r_p / s^2``
(each pair's score, its three channels together), grows where the large residuals sit on the
pairs that move the estimate most: a shadow or a mismatched lobe on the views that set the
roughness. With residuals that are noise, ``E[B] = J^T J / s^2`` and the two agree.

Recomputes both at the estimate of a finished run (`freq` by default), each capture's Jacobian by
the posterior's finite differences, and prints per capture the AUSE of each map's expected squared
error against the true squared parameter error (lower ranks better), their Spearman correlation
with it, their partial Pearson correlation given the view count, and the mean of each map over
the mean true error; beside them the view count's and a random order's AUSE. ``--blend``: also the larger of the two per texel.

    python bench/sandwich_variance.py --results DIR --captures sphere/sky bunny/lobby [--method freq]
"""

from __future__ import annotations

import argparse
from pathlib import Path

import numpy as np
import yaml

from freqbrdf import layout
from freqbrdf.artefacts import read_observations, read_svbrdf
from freqbrdf.estimate.light_table import read_light_table
from freqbrdf.estimate.optimise.model import ForwardModel, estimate_light
from freqbrdf.estimate.optimise.posterior import (PRIOR_PRECISION, expected_error, model_jacobian, pair_information,
                                                  residual_variance)
from freqbrdf.estimate.optimise.problem import build_problem, pack_params
from freqbrdf.estimate.optimise.settings import N_PARAMS, OptimiseSettings
from freqbrdf.report.metrics import parameter_error_map
from freqbrdf.report.sparsification import ause, baseline_maps, partial_pearson, random_ause
from freqbrdf.sphere.brdf import TEXTURES
from freqbrdf.util.io import read_exr


def posteriors(jacobian: np.ndarray, residual: np.ndarray, start: np.ndarray) -> tuple[np.ndarray, np.ndarray]:
    """Laplace and sandwich variances (T, 5) of texels with pairs ``start`` (T + 1,), from each
    pair's Jacobian (N, 3, 5) and residual (N, 3), model minus observed."""
    n = start.shape[0] - 1
    slot = np.repeat(np.arange(n), np.diff(start))
    s2 = residual_variance(residual, slot, n)
    curvature = np.zeros((n, N_PARAMS, N_PARAMS))
    np.add.at(curvature, slot, pair_information(jacobian))
    precision = curvature / s2[:, None, None] + PRIOR_PRECISION * np.eye(N_PARAMS)
    inverse = np.linalg.inv(precision)
    score = np.einsum("ncq,nc->nq", jacobian, residual) / s2[slot, None]
    meat = np.zeros((n, N_PARAMS, N_PARAMS))
    np.add.at(meat, slot, score[:, :, None] * score[:, None, :])
    sandwich = inverse @ meat @ inverse
    return np.diagonal(inverse, axis1=1, axis2=2), np.diagonal(sandwich, axis1=1, axis2=2)


def spearman(a: np.ndarray, b: np.ndarray) -> float:
    ranks = [np.argsort(np.argsort(x)).astype(np.float64) for x in (a, b)]
    return float(np.corrcoef(*ranks)[0, 1])


def capture_maps(results: Path, capture: str, method: str, config: dict) -> tuple[dict[str, np.ndarray], np.ndarray,
                                                                                    np.ndarray]:
    """The maps (expected squared error per observed texel), the true squared error and the view count."""
    obj, env = capture.split("/")
    where = dict(object=obj, env=env, poses="gt")
    obs = read_observations(layout.located(layout.OBSERVATIONS, results, **where))
    optimise = config["optimise"]
    settings = OptimiseSettings.from_config(optimise, workers=2)
    envmap = read_exr(layout.located(layout.ENVMAP, results, env=env))
    light, irradiance = estimate_light(envmap, obs, method, optimise["lmax"], optimise["point_sources"])
    table = read_light_table(layout.located(layout.LIGHT_TABLE, results, env=env), light, settings.light_table)
    problem = build_problem(obs, irradiance, settings.dtype)
    model = ForwardModel.of(problem, light, method, settings, table)
    estimate = read_svbrdf(layout.located(layout.ESTIMATE, results, method=method, **where))
    at_texels = estimate.at_texels(obs.texels.texel)
    xp = pack_params(at_texels, len(obs.texels))[problem.perm]
    roughness = np.empty(len(obs.texels))
    roughness[problem.perm] = xp[:, 3]
    terms = model.light_terms(roughness, settings.workers)
    radiance, jacobian = model_jacobian(lambda z: model.radiance(z, terms), xp, problem.start)
    laplace, sandwich = posteriors(jacobian, radiance - problem.radiance, problem.start)
    # internal order (problem.observed first) -> the order of obs.observed
    order = np.empty(len(problem.observed), dtype=np.int64)
    order[np.argsort(problem.observed)] = np.arange(len(problem.observed))
    maps = {"laplace": expected_error(laplace)[order], "sandwich": expected_error(sandwich)[order]}
    truth = read_svbrdf({g: layout.located(layout.OBJECT_TEXTURE, results, object=obj, texture=g) for g in TEXTURES})
    texels = obs.texels.texel[obs.observed]
    error = parameter_error_map(truth, estimate).ravel()[texels]
    return maps, error, baseline_maps(obs)["views"]


def main() -> None:
    parser = argparse.ArgumentParser(description=__doc__.split("\n\n")[0])
    parser.add_argument("--results", type=Path, required=True)
    parser.add_argument("--captures", nargs="+", required=True)
    parser.add_argument("--method", default="freq")
    parser.add_argument("--blend", action="store_true")
    args = parser.parse_args()
    config = yaml.safe_load(layout.located(layout.RUN_CONFIG, args.results).read_text())
    for capture in args.captures:
        maps, error, views = capture_maps(args.results, capture, args.method, config)
        if args.blend:
            maps["larger"] = np.maximum(maps["laplace"], maps["sandwich"])
        maps["views"] = views
        for name, values in maps.items():
            print(f"{capture:14s} {name:9s} AUSE {ause(values, error):.3f}  Spearman {spearman(values, error):+.3f}  "
                  f"partial r | views {partial_pearson(values, error, views) if name != 'views' else float('nan'):+.3f}  "
                  f"mean / mean error {np.mean(values) / np.mean(error):.3f}", flush=True)
        print(f"{capture:14s} {'random':9s} AUSE {random_ause(error):.3f} (expected)", flush=True)


if __name__ == "__main__":
    main()
