"""Which parameter's error costs a method its relighting score?

Relights one capture's estimate exactly as rule ``relight`` does (same scene,
sample count and seed as the reference test views), once as estimated and
once with each texture in turn replaced by the ground truth, plus the ground
truth with its roughness raised to ``--min-roughness`` (what an estimator
bounded below at that value could reach at best). Scores are the metrics
rule's (PSNR-H, PSNR-L, SSIM, MSE over the fully covered pixels).

Needs a finished default run in the working directory (its results
directory, `freqbrdf.layout.RESULTS`): the ground truth
(`freqbrdf.layout.OBJECT_TEXTURE`, `freqbrdf.layout.OBJECT_MESH`), the
estimate (`freqbrdf.layout.ESTIMATE`), the test captures
(`freqbrdf.layout.CAPTURE`) and environment maps (`freqbrdf.layout.ENVMAP`):

    python bench/relight_swap.py                                  # sphere/studio, freq
    python bench/relight_swap.py --capture torus/sunny --method mitsuba

Writes ``bench/out/relight_swap_{object}_{env}_{method}.tsv``.
"""

from __future__ import annotations

import argparse
from pathlib import Path

import numpy as np
import pandas as pd

from freqbrdf import layout
from freqbrdf.config import relight_envs, run_config
from freqbrdf.scene.cameras import cameras_from_json
from freqbrdf.util.seeds import derived_seed
from freqbrdf.artefacts import read_svbrdf
from freqbrdf.sphere.brdf import TEXTURES
from freqbrdf.util.io import read_exr, read_json, read_views
from freqbrdf.report.relight_metrics import relight_scores
from freqbrdf.util.mitsuba_setup import setup_mitsuba
from freqbrdf.scene.render import relit_views


def variants(truth: dict[str, np.ndarray], estimate: dict[str, np.ndarray], min_roughness: float) -> dict[str, dict]:
    """The estimate, the estimate with one true texture each, and the bounded truth."""
    out = {"estimate": estimate}
    out |= {f"estimate, true {name}": {**estimate, name: truth[name]} for name in TEXTURES}
    out[f"truth, roughness >= {min_roughness:g}"] = {**truth, "roughness": np.maximum(truth["roughness"], min_roughness)}
    return out


def main() -> None:
    parser = argparse.ArgumentParser(description=__doc__.splitlines()[0])
    parser.add_argument("--capture", default="sphere/studio", help="object/env of a synthetic capture")
    parser.add_argument("--method", default="freq")
    parser.add_argument("--poses", default="gt")
    parser.add_argument("--min-roughness", type=float, default=0.3)
    parser.add_argument("--config", default="config/config.yaml", help="the run's config (render settings, seed, envs)")
    parser.add_argument("--threads", type=int, default=2)
    args = parser.parse_args()

    obj, env = args.capture.split("/")
    config = run_config(args.config, Path(__file__).resolve().parents[1] / "config" / "config.yaml")
    render = config["render"]
    truth = read_svbrdf({n: layout.located(layout.OBJECT_TEXTURE, object=obj, texture=n) for n in TEXTURES})
    estimate = read_svbrdf(layout.located(layout.ESTIMATE, object=obj, env=env, poses=args.poses, method=args.method))
    mi = setup_mitsuba(threads=args.threads)

    rows = []
    for relight_env in relight_envs(config["envs"], config["evaluate"]["relight_envs"], env, [env]):
        test = layout.located(layout.CAPTURE, object=obj, env=relight_env, split="test")
        cameras = cameras_from_json(read_json(test / "cameras.json"), test / "cameras.json")
        references, coverage, _ = read_views(test, cameras.names, cameras.width, cameras.height)
        # as the metrics rule scores them (the tolerance absorbs the masks' PNG quantisation)
        masks = [c >= config["evaluate"]["mask_min_coverage"] - 1e-6 for c in coverage]
        seed = derived_seed(config["seed"], "render", obj, relight_env, "test")  # rules/relight.smk's
        envmap = read_exr(layout.located(layout.ENVMAP, env=relight_env))
        for name, textures in variants(truth, estimate, args.min_roughness).items():
            relit = list(relit_views(mi, layout.located(layout.OBJECT_MESH, object=obj), textures, envmap, cameras,
                                     fov_x_deg=render["fov_deg"], spp=render["spp"], max_depth=render["max_depth"],
                                     seed=seed))
            scores = relight_scores(relit, list(references), masks, clip=config["evaluate"]["hdr_clip"],
                                    normalise=config["evaluate"]["hdr_normalise"])
            rows.append({"relight_env": relight_env, "textures": name} | scores)
            print(rows[-1], flush=True)

    table = pd.DataFrame(rows)
    out = Path("bench/out") / f"relight_swap_{obj}_{env}_{args.method}.tsv"
    out.parent.mkdir(parents=True, exist_ok=True)
    table.to_csv(out, sep="\t", index=False, float_format="%.3f")
    print(table.to_string(index=False, float_format=lambda v: f"{v:.2f}"))
    print(f"\nwritten {out}")


if __name__ == "__main__":
    main()
