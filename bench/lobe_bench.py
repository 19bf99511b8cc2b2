"""How each model (``optimise.lobe``, ``view_weight``, ``diffuse``) recovers materials rendered with the
principled BSDF's lobes.

The texels, frames, views and occlusions of the recovery test of issue 12
(`freqbrdf.studies.recovery_capture`, 64 texels: roughness 0.35, 0.5, 0.7, 0.9, metallic 0
or 1) are rendered here not with the paper's model but with the lobes of
Mitsuba's principled BSDF without its extras (`freqbrdf.sphere.reference.ggx_radiance`: GGX,
separable Smith masking-shadowing, Schlick's Fresnel at the half vector, the
principled diffuse lobe), integrated per observation over every pixel of the
environment map (128 x 256) above the texel's horizon. `freq` then fits them
back (300 Adam steps at lr 0.01, no TV, the grid start, the light at degree
20) with each model, and the mean signed error of each (roughness, metallic)
group is printed. Then, at the true parameters, the ratio of the model's
radiance to the oracle's (median per group, over near-normal views,
cos theta_o > 0.7, and grazing ones, cos theta_o < 0.4): where the model
itself departs from the renderer's BSDF.

    python bench/lobe_bench.py                       # studio and sunny of the repository's results directory
    FREQBRDF_RESULTS=/path/to/results python bench/lobe_bench.py --envs studio sunny museum

The environment maps are the pipeline's (`freqbrdf.layout.ENVMAP`), under the
repository's results directory (`freqbrdf.layout.RESULTS`) or ``FREQBRDF_RESULTS``.

Writes ``bench/out/lobe.tsv`` and ``bench/out/lobe_ratio.tsv``.
"""

from __future__ import annotations

import argparse
import os
from pathlib import Path

import numpy as np

from freqbrdf import layout
from freqbrdf.estimate import light as lt
from freqbrdf.estimate.optimise.kernels import KernelModel
from freqbrdf.estimate.optimise.model import forward, light_terms
from freqbrdf.estimate.optimise.problem import build_problem, pack_params
from freqbrdf.estimate.optimise.settings import OptimiseSettings
from freqbrdf.estimate.optimise.solve import optimise
from freqbrdf.sphere.lobes import lobe_table, view_table
from freqbrdf.sphere.reference import ggx_radiance
from freqbrdf.studies.recovery_capture import ROUGHNESS, capture_observations, recovery_texels
from freqbrdf.util.io import read_exr

REPO = Path(__file__).resolve().parents[1]
RESULTS = Path(os.environ.get("FREQBRDF_RESULTS", REPO / layout.RESULTS))
OUT = REPO / "bench" / "out"
MODELS = (("gaussian", "paper", "lambert"), ("ggx", "paper", "lambert"), ("ggx", "paper", "principled"),
          ("ggx", "albedo", "principled"))  # (lobe, view weight, diffuse)


def model_ratios(env: np.ndarray, capture: dict, truth: dict, lobe: str, view_weight: str,
                 diffuse: str) -> list[dict]:
    """Median of model / GGX radiance (channel sums) at the true parameters, per roughness and
    metallic, over near-normal (cos theta_o > 0.7) and grazing (< 0.4) observations."""
    problem = build_problem(capture_observations(capture), lt.irradiance(env, capture["frame"][:, 2]), "float64")
    light = light_terms(truth["roughness"], problem, True, lt.light_quadrature(env, 20))
    model = forward(pack_params(truth, problem.n_texels), problem, light, KernelModel(True, lobe_table(lobe, 20), view_table(view_weight, diffuse, lobe, 20)))
    seen, cos_o = capture["weight"] > 0, capture["wo_local"][..., 2]
    ratio = model.sum(-1) / np.maximum(capture["radiance"].sum(-1), 1e-12)
    rows = []
    for r in ROUGHNESS:
        for metallic in (0.0, 1.0):
            sel = ((truth["roughness"] == r) & (truth["metallic"] == metallic))[:, None] & seen
            rows.append({"lobe": lobe, "view_weight": view_weight, "diffuse": diffuse, "roughness": r, "metallic": metallic,
                         "ratio_normal": round(float(np.median(ratio[sel & (cos_o > 0.7)])), 2),
                         "ratio_grazing": round(float(np.median(ratio[sel & (cos_o < 0.4)])), 2)})
    return rows


def write_tsv(rows: list[dict], path: Path) -> None:
    columns = list(rows[0])
    path.write_text("\n".join(["\t".join(columns)] + ["\t".join(str(r[c]) for c in columns) for r in rows]) + "\n")
    print(f"written {path}")


def main() -> None:
    parser = argparse.ArgumentParser(description=__doc__.splitlines()[0])
    parser.add_argument("--envs", nargs="+", default=["studio", "sunny"],
                        help="environment maps of the results directory (layout.ENVMAP)")
    args = parser.parse_args()
    rows, ratios = [], []
    for name in args.envs:
        env = lt.downsample_equirect(read_exr(layout.located(layout.ENVMAP, RESULTS, env=name)), 128)
        capture, truth = recovery_texels(seed=0)
        capture["radiance"] = ggx_radiance(env, capture, truth)
        for lobe, view_weight, diffuse in MODELS:
            ratios += [{"env": name} | row for row in model_ratios(env, capture, truth, lobe, view_weight, diffuse)]
            print(ratios[-1], flush=True)
            settings = OptimiseSettings.paper(iterations=300, lr=0.01, tv_weight=0.0, lobe=lobe,
                                              view_weight=view_weight, diffuse=diffuse)
            est = optimise(capture_observations(capture), lt.irradiance(env, capture["frame"][:, 2]),
                           lt.light_quadrature(env, 20), None, "freq", settings=settings).params
            for r in ROUGHNESS:
                for metallic in (0.0, 1.0):
                    sel = (truth["roughness"] == r) & (truth["metallic"] == metallic)
                    row = {"env": name, "lobe": lobe, "view_weight": view_weight, "diffuse": diffuse, "roughness": r,
                           "metallic": metallic}
                    for key in ("roughness", "metallic", "base_color"):
                        row[f"bias_{key}"] = round(float(np.mean(est[key][sel] - truth[key][sel])), 3)
                    rows.append(row)
                    print(row, flush=True)
    OUT.mkdir(parents=True, exist_ok=True)
    write_tsv(rows, OUT / "lobe.tsv")
    write_tsv(ratios, OUT / "lobe_ratio.tsv")


if __name__ == "__main__":
    main()
