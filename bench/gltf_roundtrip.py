"""The ground truth's .glb rendered back with Mitsuba from a training view, against the capture.

    python bench/gltf_roundtrip.py [--results DIR] --object sphere --env studio [--view 000]

Reads, under the results directory (``--results``, default the working
directory's, `freqbrdf.layout.RESULTS`), the ground truth's .glb
(`freqbrdf.layout.TRUTH_GLTF`: mesh and textures, as any glTF reader would:
base colour sRGB-decoded, roughness from G, metallic from B), renders it as
rule ``render_capture`` rendered the training view (same settings from the
config, same seed, so the Monte Carlo noise is the same and cancels), and
compares with the training capture (`freqbrdf.layout.CAPTURE`, split ``train``).
Only the first view has the capture's own seed (view k mixes k into it), so
views other than 000 are rendered with theirs as render_views does.

Prints PSNR over the whole image and over the object's pixels (peak: the
capture's largest value), the largest per-pixel relative error on lit
object pixels, and, as a check of the set-up, the same for the EXR
textures, which must reproduce the capture exactly.
"""

from __future__ import annotations

import argparse
import sys
import tempfile
from pathlib import Path

import numpy as np
import yaml

from freqbrdf import layout

REPO = Path(__file__).resolve().parents[1]


def psnr(a: np.ndarray, b: np.ndarray, peak: float) -> float:
    mse = float(np.mean((np.asarray(a, np.float64) - b) ** 2))
    return float("inf") if mse == 0.0 else 10.0 * np.log10(peak**2 / mse)


def main(argv: list[str] | None = None) -> int:
    parser = argparse.ArgumentParser(description=__doc__.split("\n")[0])
    parser.add_argument("--results", type=Path, default=Path(layout.RESULTS), help="the results directory")
    parser.add_argument("--object", default="sphere")
    parser.add_argument("--env", default="studio")
    parser.add_argument("--view", default="000")
    parser.add_argument("--glb", type=Path, help="default: the ground truth's under --results (layout.TRUTH_GLTF)")
    parser.add_argument("--configfile", type=Path, action="append", default=[],
                        help="config layered on config/config.yaml, as given to snakemake")
    args = parser.parse_args(argv)

    from freqbrdf.artefacts import read_svbrdf
    from freqbrdf.scene.cameras import Cameras, cameras_from_json
    from freqbrdf.util.seeds import derived_seed
    from freqbrdf.export.gltf import read_glb
    from freqbrdf.util.io import read_exr, read_json, read_png
    from freqbrdf.scene.ply import write_ply
    from freqbrdf.util.mitsuba_setup import setup_mitsuba
    from freqbrdf.scene.render import relit_views
    from freqbrdf.sphere.brdf import TEXTURES

    config = yaml.safe_load((REPO / "config" / "config.yaml").read_text())
    for extra in args.configfile:
        for key, value in (yaml.safe_load(extra.read_text()) or {}).items():
            config[key] = {**config[key], **value} if isinstance(value, dict) and isinstance(config.get(key), dict) else value
    render = config["render"]
    capture = layout.located(layout.CAPTURE, args.results, object=args.object, env=args.env, split="train")
    all_cameras = cameras_from_json(read_json(capture / "cameras.json"), capture / "cameras.json")
    k = all_cameras.names.index(args.view)
    cameras = Cameras(K=all_cameras.K[k : k + 1], world_to_camera=all_cameras.world_to_camera[k : k + 1],
                      width=all_cameras.width, height=all_cameras.height, names=(args.view,))
    seed = (derived_seed(config["seed"], "render", args.object, args.env, "train") + k * 0x9E3779B1) & 0xFFFFFFFF
    reference = read_exr(capture / "images" / f"{args.view}.exr")
    coverage = read_png(capture / "masks" / f"{args.view}.png") / 255.0
    envmap = read_exr(layout.located(layout.ENVMAP, args.results, env=args.env))
    scene = read_glb(args.glb or layout.located(layout.TRUTH_GLTF, args.results, object=args.object))

    mi = setup_mitsuba("llvm_ad_rgb")
    settings = dict(fov_x_deg=render["fov_deg"], spp=render["spp"], max_depth=render["max_depth"], seed=seed)
    with tempfile.TemporaryDirectory() as tmp:
        write_ply(Path(tmp) / "mesh.ply", scene.mesh)
        from_glb = next(relit_views(mi, Path(tmp) / "mesh.ply", scene.material(layout.TRUTH).textures(), envmap,
                                    cameras, **settings))
    exr = read_svbrdf({n: layout.located(layout.OBJECT_TEXTURE, args.results, object=args.object, texture=n)
                       for n in TEXTURES})
    from_exr = next(relit_views(mi, layout.located(layout.OBJECT_MESH, args.results, object=args.object),
                                {n: getattr(exr, n) for n in ("base_color", "roughness", "metallic")}, envmap,
                                cameras, **settings))
    peak = float(reference.max())
    inside = coverage >= 1.0
    lit = inside & (reference.mean(axis=2) > 0.02 * peak)
    for name, image in (("glb", from_glb), ("exr", from_exr)):
        rel = np.abs(image - reference)[lit] / np.maximum(reference[lit], 1e-6)
        print(f"{args.object}/{args.env} view {args.view}, {name} textures: PSNR {psnr(image, reference, peak):.1f} dB "
              f"(object pixels {psnr(image[inside], reference[inside], peak):.1f} dB), relative error on lit object "
              f"pixels: median {np.median(rel):.4f}, 99th percentile {np.percentile(rel, 99):.4f}, max {rel.max():.4f}")
    return 0


if __name__ == "__main__":
    sys.exit(main())
