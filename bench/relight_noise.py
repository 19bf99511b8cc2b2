"""Does the relighting score rank the methods as a noise-free render would?

For one capture of a finished run, renders the ground truth and every method's estimate
from a test rig of ``--views`` views under each held-out environment three times: at the
run's sample count with the reference's seed (what rule ``relight`` does: common random
numbers), at the run's sample count with an independent seed, and at ``--high-spp``
(default 1,024) against a reference at that count (nearly noise-free). Each is scored by
PSNR-H under every per-channel scale (``evaluate.hdr_scale``: clipped, orb, none), per
view. The summary gives, per scale and seeding, every method's mean score beside its
high-count score, the largest gap, and whether the ranking of the methods agrees.

Needs a finished run's results (``--results``, default the layout's): the ground truth
(`freqbrdf.layout.OBJECT_TEXTURE`, `freqbrdf.layout.OBJECT_MESH`), the estimates
(`freqbrdf.layout.ESTIMATE`) and the environment maps (`freqbrdf.layout.ENVMAP`); the
test rig and masks are rendered here from the config. A GPU makes the high counts cheap:

    python bench/relight_noise.py --capture sphere/studio --variant cuda_ad_rgb

Writes ``<out>/relight_noise_{object}_{env}.tsv`` (per view) and ``..._summary.tsv``.
"""

from __future__ import annotations

import argparse
import time
from pathlib import Path

import numpy as np
import pandas as pd

from freqbrdf import layout
from freqbrdf.artefacts import read_svbrdf
from freqbrdf.config import relight_envs, run_config
from freqbrdf.util.seeds import derived_seed
from freqbrdf.report.relight_metrics import HDR_SCALES, HdrScoring, psnr_h, scored_pixels
from freqbrdf.scene.cameras import mitsuba_to_world, rig_cameras
from freqbrdf.scene.render import mask_scene, relit_views, render_views
from freqbrdf.sphere.brdf import TEXTURES
from freqbrdf.util.io import read_exr
from freqbrdf.util.mitsuba_setup import setup_mitsuba

SEEDINGS = ("shared", "independent", "high")  # the run's spp with the reference's seed, another seed; --high-spp


def relit_under(config: dict, env: str) -> list[str]:
    """The environments the run relit the capture lit by ``env`` under."""
    return relight_envs(config["envs"], config["evaluate"]["relight_envs"], env, [env])


def score_rows(method: str, env: str, seeding: str, images, refs, masks, clip: float) -> list[dict]:
    """PSNR-H of each view under every scale."""
    rows = []
    for view, (image, ref, mask) in enumerate(zip(images, refs, masks)):
        for scale in HDR_SCALES:
            value = psnr_h(image, ref, mask, HdrScoring(clip=clip, scale=scale))
            rows.append(dict(method=method, relight_env=env, view=view, seeding=seeding, scale=scale, psnr_h=value))
    return rows


def summary(table: pd.DataFrame) -> pd.DataFrame:
    """Per scale and seeding: each method's mean beside its high-count mean, the gap, the ranking's agreement."""
    means = table.groupby(["scale", "seeding", "method"]).psnr_h.mean().unstack("seeding")
    out = []
    for scale, block in means.groupby(level="scale"):
        block = block.droplevel("scale")
        for seeding in ("shared", "independent"):
            gap = block[seeding] - block["high"]
            same = bool((block[seeding].rank().to_numpy() == block["high"].rank().to_numpy()).all())
            out += [dict(scale=scale, seeding=seeding, method=m, score=block.loc[m, seeding],
                         high=block.loc[m, "high"], gap=gap[m], max_abs_gap=gap.abs().max(), same_ranking=same)
                    for m in block.index]
    return pd.DataFrame(out)


def main() -> None:
    parser = argparse.ArgumentParser(description=__doc__.splitlines()[0])
    parser.add_argument("--capture", default="sphere/studio", help="object/env of a synthetic capture")
    parser.add_argument("--poses", default="gt")
    parser.add_argument("--methods", nargs="*", default=None, help="default: the config's methods that are on disk")
    parser.add_argument("--views", type=int, default=4)
    parser.add_argument("--high-spp", type=int, default=1024)
    parser.add_argument("--config", default="config/config.yaml", help="the run's config (render settings, seed, envs)")
    parser.add_argument("--results", default=None, help="the run's results directory (default: the layout's)")
    parser.add_argument("--variant", default="auto")
    parser.add_argument("--threads", type=int, default=2)
    parser.add_argument("--out", default="bench/out")
    args = parser.parse_args()

    obj, env = args.capture.split("/")
    config = run_config(args.config, Path(__file__).resolve().parents[1] / "config" / "config.yaml")
    render, root = config["render"], args.results
    mi = setup_mitsuba(args.variant, args.threads)
    print(f"variant {mi.variant()}", flush=True)
    # the run's test rig (rule render_capture's, split test) with --views views
    cameras = rig_cameras(args.views, render["resolution"], render["fov_deg"], render["camera_distance"],
                          azimuth_deg=render["test_azimuth_deg"])
    to_world = np.stack([mitsuba_to_world(m) for m in cameras.world_to_camera])
    frame = dict(width=cameras.width, height=cameras.height, fov_x_deg=render["fov_deg"])
    mesh = layout.located(layout.OBJECT_MESH, root, object=obj)
    coverage = render_views(mi, mask_scene(mi, mesh, spp=render["mask_spp"], **frame), to_world, seed=0)
    masks = [scored_pixels(c[..., 0], config["evaluate"]["mask_min_coverage"]) for c in coverage]
    truth = read_svbrdf({t: layout.located(layout.OBJECT_TEXTURE, root, object=obj, texture=t) for t in TEXTURES})
    estimates = {}
    for method in args.methods or config["methods"]:
        path = layout.located(layout.ESTIMATE, root, object=obj, env=env, poses=args.poses, method=method)
        if path.is_dir():
            estimates[method] = dict(read_svbrdf(path))
    print(f"{obj}/{env}: {len(estimates)} methods ({', '.join(estimates)}), {args.views} views", flush=True)

    rows, start = [], time.perf_counter()
    for relight in relit_under(config, env):
        envmap = read_exr(layout.located(layout.ENVMAP, root, env=relight))
        seed = derived_seed(config["seed"], "render", obj, relight, "test")  # the reference views' (rule relight)
        seeds = {"shared": seed, "independent": derived_seed(config["seed"], "bench", obj, relight, "independent"),
                 "high": derived_seed(config["seed"], "bench", obj, relight, "high")}

        def views(textures, seeding, spp):
            return list(relit_views(mi, mesh, textures, envmap, cameras, fov_x_deg=render["fov_deg"], spp=spp,
                                    max_depth=render["max_depth"], seed=seeds[seeding]))

        refs = {"shared": views(dict(truth), "shared", render["spp"]),
                "high": views(dict(truth), "high", args.high_spp)}
        refs["independent"] = refs["shared"]
        # the truth's own score: the noise floor each seeding leaves
        rows += score_rows("truth", relight, "independent", views(dict(truth), "independent", render["spp"]),
                           refs["shared"], masks, config["evaluate"]["hdr_clip"])
        for method, textures in estimates.items():
            for seeding in SEEDINGS:
                spp = args.high_spp if seeding == "high" else render["spp"]
                # a high-count estimate against another seed's high-count reference: both nearly noise-free
                images = views(textures, "independent" if seeding == "high" else seeding, spp)
                rows += score_rows(method, relight, seeding, images, refs[seeding], masks, config["evaluate"]["hdr_clip"])
        print(f"relit under {relight}: {time.perf_counter() - start:.0f} s", flush=True)

    table = pd.DataFrame(rows)
    out = Path(args.out)
    out.mkdir(parents=True, exist_ok=True)
    table.to_csv(out / f"relight_noise_{obj}_{env}.tsv", sep="\t", index=False, float_format="%.4f")
    result = summary(table[table.method != "truth"])
    result.to_csv(out / f"relight_noise_{obj}_{env}_summary.tsv", sep="\t", index=False, float_format="%.3f")
    floor = table[table.method == "truth"].groupby("scale").psnr_h.mean()
    print("the truth at another seed (noise floor):", floor.round(2).to_dict())
    with pd.option_context("display.width", 200, "display.max_rows", 500):
        print(result.to_string(index=False, float_format=lambda v: f"{v:.2f}"))


if __name__ == "__main__":
    main()
