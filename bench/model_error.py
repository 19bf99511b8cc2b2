"""Where `freq`'s model departs from the rendered captures, and what that does to the entropy's correlation.

For each capture and material class (metal or dielectric x true roughness
below 0.2, 0.2-0.356, 0.356-0.6, 0.6 and above; 0.356 is the GGX lobe's
identifiable roughness at l* = 20), a sample of the class's observed texels
is predicted at the *true* parameters two ways and compared with the
observations that `freq` fits:

- the brute-force oracle (`freqbrdf.sphere.reference.ggx_radiance`: Mitsuba's principled BSDF
  without its extras, integrated over every pixel of the environment map):
  what the renderer's noise and the observation extraction leave;
- `freq`'s own model (`optimise.forward`, the config's lobe, weight per view,
  diffuse term and point sources, the light at each degree of ``--lmax``;
  ``--no-point-sources``: all of the map through the SH).

Error is the weighted L1 distance over the sample's observations relative to
the observations' weighted L1 norm. Beside them: the class's share of the
observed texels, its mean entropy (`freqbrdf.layout.ENTROPY`) and `freq`'s
mean per-texel squared parameter error (its estimate,
`freqbrdf.layout.ESTIMATE`: the pipeline's run). A class whose entropy is
low but whose model error at the truth is far above the oracle's is one the
entropy cannot flag: the spectra constrain its lobe, the model cannot
reproduce it. Every input (gt poses) is read from the repository's results
directory (`freqbrdf.layout.RESULTS`), or ``FREQBRDF_RESULTS``.

    python bench/model_error.py                                   # the default run's captures
    FREQBRDF_RESULTS=/path/to/results python bench/model_error.py --captures sphere/sunny --lmax 20 36

Writes ``bench/out/model_error.tsv`` (``model_error_no_point_sources.tsv`` with that flag).
"""

from __future__ import annotations

import argparse
import os
from pathlib import Path

import numpy as np
import yaml

from freqbrdf import layout
from freqbrdf.estimate.optimise.kernels import KernelModel
from freqbrdf.estimate.optimise.model import forward, light_terms, model_light, model_tables, point_terms
from freqbrdf.estimate.optimise.problem import build_problem, pack_params
from freqbrdf.estimate.optimise.settings import OptimiseSettings
from freqbrdf.artefacts import read_entropy, read_observations, read_svbrdf
from freqbrdf.sphere.brdf import TEXTURES
from freqbrdf.sphere.reference import ggx_radiance
from freqbrdf.util.io import read_exr
from freqbrdf.estimate.light import irradiance
from freqbrdf.report.metrics import parameter_error_map, pearson

REPO = Path(__file__).resolve().parents[1]
RESULTS = Path(os.environ.get("FREQBRDF_RESULTS", REPO / layout.RESULTS))
OUT = REPO / "bench" / "out"
CAPTURES = ("sphere/studio", "sphere/sunny", "torus/studio", "torus/sunny")
ROUGHNESS_EDGES = (0.0, 0.2, 0.356, 0.6, 1.01)


def flat(texture: np.ndarray, texel: np.ndarray) -> np.ndarray:
    """Rows ``texel`` of an (R, R, ...) texture as (T, ...)."""
    return texture.reshape(-1, *texture.shape[2:])[texel]


def relative_l1(prediction: np.ndarray, observed: np.ndarray, weight: np.ndarray) -> float:
    """Weighted L1 distance of (T, K, 3) radiances over the weighted L1 norm of ``observed``."""
    w = weight[..., None]
    return float((w * np.abs(prediction - observed)).sum() / (w * np.abs(observed)).sum())


def capture_rows(capture: str, settings: OptimiseSettings, lmaxes: list[int], point_sources: dict | None,
                 sample: int, rng: np.random.Generator) -> list[dict]:
    obj, env = capture.split("/")
    fields = {"object": obj, "env": env, "poses": "gt"}
    obs = read_observations(layout.located(layout.OBSERVATIONS, RESULTS, **fields))
    texel, seen = obs.texels.texel, obs.observed
    truth_maps = read_svbrdf({n: layout.located(layout.OBJECT_TEXTURE, RESULTS, object=obj, texture=n)
                              for n in TEXTURES})
    truth = {n: flat(getattr(truth_maps, n), texel) for n in TEXTURES}
    estimate = read_svbrdf(layout.located(layout.ESTIMATE, RESULTS, **fields, method="freq"))
    error = flat(parameter_error_map(dict(truth_maps), dict(estimate)), texel)
    entropy = flat(read_entropy(layout.located(layout.ENTROPY, RESULTS, **fields)).atlas, texel)
    envmap = read_exr(layout.located(layout.ENVMAP, RESULTS, env=env))
    problem = build_problem(obs, irradiance(envmap, obs.texels.normal), "float64")
    x = pack_params(truth, problem.n_texels)
    models = {}
    for lmax in lmaxes:
        quadrature = model_light(envmap, obs, "freq", lmax, point_sources)
        light = light_terms(truth["roughness"], problem, True, quadrature, settings.workers)
        models[lmax] = forward(x, problem, light, KernelModel(True, *model_tables(settings, "freq", lmax),
                                                              point_terms(problem, quadrature.sources, True)))
    frame = np.stack([obs.texels.tangent, obs.texels.bitangent, obs.texels.normal], axis=1)
    metal, rough = truth["metallic"] > 0.5, truth["roughness"]
    rows = [{"capture": capture, "class": "all", "share": 1.0, "entropy": round(float(entropy[seen].mean()), 3),
             "freq_error": round(float(error[seen].mean()), 4),
             "pearson_entropy_error": round(pearson(entropy[seen], error[seen]), 3)}]
    for is_metal in (True, False):
        for lo, hi in zip(ROUGHNESS_EDGES[:-1], ROUGHNESS_EDGES[1:]):
            members = np.nonzero(seen & (metal == is_metal) & (rough >= lo) & (rough < hi))[0]
            if members.size < sample:
                continue
            pick = np.sort(rng.choice(members, sample, replace=False))
            oracle = ggx_radiance(envmap, {"frame": frame[pick], "wo_local": obs.wo_local[pick],
                                           "weight": obs.weight[pick]}, {n: v[pick] for n, v in truth.items()})
            row = {"capture": capture, "class": f"{'metal' if is_metal else 'dielectric'} r [{lo:g}, {min(hi, 1):g})",
                   "share": round(members.size / seen.sum(), 3), "entropy": round(float(entropy[members].mean()), 3),
                   "freq_error": round(float(error[members].mean()), 4), "pearson_entropy_error": "",
                   "oracle_l1": round(relative_l1(oracle, obs.radiance[pick], obs.weight[pick]), 3)}
            for lmax, model in models.items():
                row[f"model_l1_lmax{lmax}"] = round(relative_l1(model[pick], obs.radiance[pick], obs.weight[pick]), 3)
            rows.append(row)
            print(row, flush=True)
    return rows


def main() -> None:
    parser = argparse.ArgumentParser(description=__doc__.splitlines()[0])
    parser.add_argument("--captures", nargs="+", default=list(CAPTURES), help="object/env pairs of the run")
    parser.add_argument("--lmax", nargs="+", type=int, default=None, help="degrees of the model (default: the config's)")
    parser.add_argument("--sample", type=int, default=40, help="texels per class (the oracle costs ~1 s per texel)")
    parser.add_argument("--seed", type=int, default=0)
    parser.add_argument("--workers", type=int, default=2)
    parser.add_argument("--no-point-sources", action="store_true", help="the whole map through the SH")
    args = parser.parse_args()
    config = yaml.safe_load((REPO / "config" / "config.yaml").read_text())["optimise"]
    settings = OptimiseSettings.from_config(config, workers=args.workers)
    lmaxes = args.lmax or [config["lmax"]]
    rng = np.random.default_rng(args.seed)
    point_sources = None if args.no_point_sources else config["point_sources"]
    rows = [row for capture in args.captures
            for row in capture_rows(capture, settings, lmaxes, point_sources, args.sample, rng)]
    columns = list(dict.fromkeys(key for row in rows for key in row))
    OUT.mkdir(parents=True, exist_ok=True)
    lines = ["\t".join(columns)] + ["\t".join(str(row.get(c, "")) for c in columns) for row in rows]
    (OUT / f"model_error{'_no_point_sources' if args.no_point_sources else ''}.tsv").write_text("\n".join(lines) + "\n")
    print("written", OUT / f"model_error{'_no_point_sources' if args.no_point_sources else ''}.tsv")


if __name__ == "__main__":
    main()
