"""Which settings bring the differentiable-rendering baseline (method ``mitsuba``) to convergence?

Builds tuning captures from scratch with the pipeline's library and seeds (object, textures,
environment, training views and masks, as rules build_object, build_env and render_capture
do), then runs `freqbrdf.estimate.mitsuba.optimise_textures` from the constant 0.5 under each
named setting, logging the parameter MSE after every epoch. The MSE is taken over the texels
the UV atlas uses (the pipeline's metrics use the texels some view observes: close, not equal).
A run counts as converged when its last epoch lowers the MSE by less than 1%.

Only for the tuning set (config/tuning.yaml's captures), never the reported ones. A GPU makes
it cheap (``--variant cuda_ad_rgb``); on 2 CPU cores one setting takes minutes per capture:

    python bench/mitsuba_sweep.py --captures die/museum vase/sunset --settings default recipe

Writes ``<out>/mitsuba_sweep.tsv`` (one row per capture, setting and epoch).
"""

from __future__ import annotations

import argparse
import functools
import time
from pathlib import Path

import numpy as np
import pandas as pd
import yaml

from freqbrdf.config import merge_config, run_config
from freqbrdf.util.seeds import derived_seed
from freqbrdf.estimate.mitsuba import constant_textures, optimise_textures
from freqbrdf.estimate.mitsuba_settings import InverseSettings
from freqbrdf.sphere.brdf import parameter_mse
from freqbrdf.scene import envmaps
from freqbrdf.scene.cameras import mitsuba_to_world, rig_cameras
from freqbrdf.scene.meshes import make_mesh
from freqbrdf.scene.ply import write_ply
from freqbrdf.scene.render import capture_bsdf, capture_scene, mask_scene, render_views, sunsky
from freqbrdf.scene.textures import svbrdf_textures
from freqbrdf.util.mitsuba_setup import setup_mitsuba

REPO = Path(__file__).resolve().parents[1]
# Named settings, each layered on the config's `mitsuba` block (docs/baseline.md, "The authors' recipe").
SETTINGS = {
    "default": {},
    "paper": {"epochs": 10, "spp": 32, "lr": 0.01, "tv_weight": 0.001},
    "recipe": {"epochs": 40, "spp": 8, "views_per_step": 4, "lr": 0.01, "loss": "l1rel", "tv_weight": 0.04},
    "recipe_cosine": {"epochs": 40, "spp": 8, "views_per_step": 4, "lr": 0.02, "loss": "l1rel", "tv_weight": 0.04,
                      "lr_decay": "cosine"},
    "views4": {"epochs": 24, "spp": 8, "views_per_step": 4, "lr_decay": "cosine"},
    "per_texture": {"epochs": 24, "spp": 8, "views_per_step": 4, "lr_decay": "cosine",
                    "lr": {"base_color": 0.01, "roughness": 0.03, "metallic": 0.05},
                    "tv_weight": {"base_color": 0.001, "roughness": 0.05, "metallic": 0.05}},
    "long": {"epochs": 24, "spp": 8, "lr_decay": "cosine"},
}


def capture(mi, config: dict, obj: str, env: str, work: Path):
    """The capture's mesh path, truth, environment map, training cameras, images and masks."""
    seed = config["seed"]
    mesh = make_mesh(obj, detail=config["meshes"]["detail"])
    path = work / f"{obj}.ply"
    write_ply(path, mesh)
    t = config["textures"]
    truth = svbrdf_textures(t["resolution"], seed=derived_seed(seed, "object", obj), cells=t["cells"],
                            grain_amplitude=t["grain"], grain_texels=t["grain_texels"])
    settings = dict(config["envs"][env])
    kind = settings.pop("kind")
    blur = settings.pop("blur", 0.0)
    if kind == "sunny":
        settings["sky"] = functools.partial(sunsky, mi)
    envmap = envmaps.normalise(envmaps.blur(getattr(envmaps, kind)(config["envmaps"]["height"], **settings), blur),
                               config["envmaps"]["mean_radiance"])
    r = config["render"]
    cameras = rig_cameras(r["train_views"], r["resolution"], r["fov_deg"], r["camera_distance"])
    to_world = np.stack([mitsuba_to_world(m) for m in cameras.world_to_camera])
    frame = dict(width=r["resolution"], height=r["resolution"], fov_x_deg=r["fov_deg"])
    scene = capture_scene(mi, path, capture_bsdf(mi, dict(truth)), envmap, spp=r["spp"], max_depth=r["max_depth"],
                          **frame)
    render_seed = derived_seed(seed, "render", obj, env, "train")
    images = np.stack(list(render_views(mi, scene, to_world, seed=render_seed)))
    masks = np.stack([c[..., 0] for c in render_views(mi, mask_scene(mi, path, spp=r["mask_spp"], **frame),
                                                       to_world, seed=render_seed)])
    return path, truth, envmap, cameras, images, masks


def main() -> None:
    parser = argparse.ArgumentParser(description=__doc__.splitlines()[0])
    parser.add_argument("--captures", nargs="+", default=["die/museum", "vase/sunset"])
    parser.add_argument("--settings", nargs="+", default=list(SETTINGS))
    parser.add_argument("--extra", default="", help="YAML mapping of further named settings, e.g. '{fast: {lr: 0.05}}'")
    parser.add_argument("--config", default=str(REPO / "config" / "tuning.yaml"), help="layered on the default")
    parser.add_argument("--override", default="", help="YAML mapping layered last (e.g. smaller sizes for a smoke test)")
    parser.add_argument("--variant", default="auto")
    parser.add_argument("--threads", type=int, default=2)
    parser.add_argument("--out", default="bench/out")
    args = parser.parse_args()

    named = SETTINGS | (yaml.safe_load(args.extra) or {} if args.extra else {})
    unknown = [s for s in args.settings if s not in named]
    if unknown:
        raise SystemExit(f"--settings: unknown {unknown} (known: {sorted(named)})")
    config = run_config(args.config, REPO / "config" / "config.yaml")
    config = merge_config(config, yaml.safe_load(args.override) or {}) if args.override else config
    default = yaml.safe_load((REPO / "config" / "config.yaml").read_text())
    reported = {f"{o}/{e}" for o in default["objects"] for e in default["capture_envs"]}
    for capture_name in args.captures:
        if capture_name in reported:
            raise SystemExit(f"{capture_name}: a capture the default run reports; sweep the tuning set only")
    mi = setup_mitsuba(args.variant, args.threads)
    out, rows = Path(args.out), []
    out.mkdir(parents=True, exist_ok=True)
    for name in args.captures:
        obj, env = name.split("/")
        start = time.perf_counter()
        mesh, truth, envmap, cameras, images, masks = capture(mi, config, obj, env, out)
        texels = np.nonzero(truth["roughness"].ravel() >= 0)[0]  # every texel of the atlas
        print(f"{name}: captured in {time.perf_counter() - start:.0f} s ({mi.variant()})", flush=True)
        for setting in args.settings:
            base = {k: v for k, v in config["mitsuba"].items() if k not in ("finetune", "variant")}
            settings = InverseSettings(**(base | named[setting] | {"seed": derived_seed(config["seed"], "sweep", name)}))
            result = optimise_textures(mi, mesh, envmap, cameras, images, masks,
                                       constant_textures(truth["roughness"].shape[0]), settings,
                                       evaluate=lambda tex: {f"mse_{k}": v for k, v in
                                                             parameter_mse(truth, tex, texels).items()})
            curve = pd.DataFrame(result.evaluations)
            mse = curve.mse_average.to_numpy()
            change = (mse[-2] - mse[-1]) / mse[-2]
            print(f"  {setting}: MSE {mse[-1]:.4f} (metallic {curve.mse_metallic.iloc[-1]:.3f}, roughness "
                  f"{curve.mse_roughness.iloc[-1]:.3f}), last epoch {-100 * change:+.1f}% "
                  f"{'converged' if change < 0.01 else 'still falling'}, {curve.elapsed_s.iloc[-1]:.0f} s", flush=True)
            rows += [dict(capture=name, setting=setting, **r) for r in result.evaluations]
            pd.DataFrame(rows).to_csv(out / "mitsuba_sweep.tsv", sep="\t", index=False, float_format="%.5g")


if __name__ == "__main__":
    main()
