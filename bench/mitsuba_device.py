"""Rule ``mitsuba``'s optimisation timed on another machine (a lent GPU machine), on a finished run's captures.

Two steps, because the GPU machine has neither Snakemake nor room for a results tree:

``pack`` (here) reads, for each capture, what rule ``mitsuba`` reads (training views and masks,
cameras, mesh, environment map, the start estimate of ``freq+mitsuba``) and what its per-epoch
evaluation needs (ground truth, observed texels), with the settings the rule passes for each
method (`freqbrdf.estimate.mitsuba_settings.run_settings` on the run's recorded config), into one
compressed file per capture. The views are stored as half floats (relative rounding 5e-4, far
below the 8-spp render noise) so that four captures travel in a few tens of MB.

``run`` (there) makes the same library call as the rule (`freqbrdf.estimate.mitsuba.optimise_textures`)
on the variant given (``auto``: ``cuda_ad_rgb`` where a CUDA device works) and writes
``<out>/mitsuba_device.tsv``: per capture and method, the variant, the optimisation's time, the
parameter MSE after the last epoch and the last epoch's relative change; and
``<out>/mse_curves.tsv``, the MSE after every epoch.

    python bench/mitsuba_device.py pack --results results --bundle bench/out/mitsuba_bundle \\
        --captures sphere/studio torus/sunny
    python bench/mitsuba_device.py run --bundle bench/out/mitsuba_bundle --out bench/out/mitsuba_device
"""

from __future__ import annotations

import argparse
import json
import tempfile
import time
from pathlib import Path

import numpy as np
import pandas as pd
import yaml

from freqbrdf import layout
from freqbrdf.artefacts import read_observations, read_svbrdf
from freqbrdf.estimate.mitsuba import constant_textures, optimise_textures
from freqbrdf.estimate.mitsuba_settings import InverseSettings, run_settings
from freqbrdf.layout import fill
from freqbrdf.methods import METHODS
from freqbrdf.sphere.brdf import TEXTURES, parameter_mse
from freqbrdf.scene.cameras import cameras_from_json
from freqbrdf.util.io import read_exr, read_json, read_views

REPO = Path(__file__).resolve().parents[1]
METHODS_OF_RULE = [name for name, method in METHODS.items() if method.rule == "mitsuba"]


def pack(results: Path, bundle: Path, captures: list[str]) -> None:
    """One ``<object>_<env>.npz`` per capture in ``bundle`` (see the module docstring)."""
    config = yaml.safe_load((results / Path(layout.RUN_CONFIG).name).read_text())
    root = results.resolve().parent
    bundle.mkdir(parents=True, exist_ok=True)
    for pair in captures:
        obj, env = pair.split("/")
        at = lambda pattern, **names: root / fill(pattern, object=obj, env=env, poses="gt", **names)  # noqa: E731
        capture = at(layout.CAPTURE, split="train")
        camera_json = read_json(capture / "cameras.json")
        cameras = cameras_from_json(camera_json, capture / "cameras.json")
        images, coverage, _ = read_views(capture, cameras.names, cameras.width, cameras.height)
        obs = read_observations(at(layout.OBSERVATIONS))
        truth = read_svbrdf({t: at(layout.OBJECT_TEXTURE, texture=t) for t in TEXTURES})
        arrays = {"images": images.astype(np.float16), "coverage": np.round(coverage * 255).astype(np.uint8),
                  "envmap": read_exr(at(layout.ENVMAP)), "texels": obs.texels.texel[obs.observed],
                  "mesh": np.frombuffer(at(layout.OBJECT_MESH).read_bytes(), np.uint8),
                  "cameras": np.array(json.dumps(camera_json)),
                  "settings": np.array(json.dumps({m: run_settings(config, obj, env, "gt", m) for m in METHODS_OF_RULE})),
                  "resolution": np.array(config["textures"]["resolution"])}
        arrays |= {f"truth_{t}": truth[t] for t in TEXTURES}
        for method in METHODS_OF_RULE:
            start = METHODS[method].start
            if start is not None:
                estimate = read_svbrdf(at(layout.ESTIMATE, method=start))
                arrays |= {f"start_{method}_{t}": estimate[t] for t in TEXTURES}
        np.savez_compressed(bundle / f"{obj}_{env}.npz", **arrays)
        print(f"{pair}: {(bundle / f'{obj}_{env}.npz').stat().st_size / 1e6:.1f} MB", flush=True)


def run(bundle: Path, out: Path, variant: str) -> None:
    """Rule mitsuba's optimisation on every packed capture and method; timings and MSE to ``out``."""
    from freqbrdf.util.mitsuba_setup import resolve_variant, setup_mitsuba

    variant = resolve_variant(variant)
    mi = setup_mitsuba(variant)
    rows, curves = [], []
    for path in sorted(bundle.glob("*.npz")):
        data = np.load(path)
        capture = path.stem.replace("_", "/", 1)
        cameras = cameras_from_json(json.loads(str(data["cameras"])), path)
        truth = {t: data[f"truth_{t}"] for t in TEXTURES}
        texels = data["texels"]
        settings = json.loads(str(data["settings"]))
        with tempfile.TemporaryDirectory() as tmp:
            mesh = Path(tmp) / "mesh.ply"
            mesh.write_bytes(data["mesh"].tobytes())
            for method, kwargs in settings.items():
                start = ({t: data[f"start_{method}_{t}"] for t in TEXTURES} if f"start_{method}_base_color" in data
                         else constant_textures(int(data["resolution"])))
                began = time.perf_counter()
                result = optimise_textures(
                    mi, mesh, data["envmap"], cameras, data["images"].astype(np.float32),
                    data["coverage"].astype(np.float32) / 255.0, start, InverseSettings(**kwargs),
                    evaluate=lambda textures: {f"mse_{k}": v for k, v in parameter_mse(truth, textures, texels).items()})
                wall = time.perf_counter() - began
                curve = pd.DataFrame(result.evaluations)
                mse = curve["mse_average"].to_numpy()
                rows.append({"capture": capture, "method": method, "variant": variant,
                             "epochs": int(curve["epoch"].iloc[-1]), "wall_s": wall,
                             "optimise_s": float(curve["elapsed_s"].iloc[-1]), "mse": mse[-1],
                             "last_epoch_change": (mse[-2] - mse[-1]) / mse[-2]})
                curves.append(curve.assign(capture=capture, method=method))
                print(rows[-1], flush=True)
    out.mkdir(parents=True, exist_ok=True)
    pd.DataFrame(rows).to_csv(out / "mitsuba_device.tsv", sep="\t", index=False, float_format="%.6g")
    pd.concat(curves).to_csv(out / "mse_curves.tsv", sep="\t", index=False, float_format="%.6g")


def main() -> None:
    parser = argparse.ArgumentParser(description=__doc__.splitlines()[0])
    sub = parser.add_subparsers(dest="step", required=True)
    packing = sub.add_parser("pack")
    packing.add_argument("--results", type=Path, default=REPO / layout.RESULTS)
    packing.add_argument("--bundle", type=Path, default=REPO / "bench" / "out" / "mitsuba_bundle")
    packing.add_argument("--captures", nargs="+", required=True, help="object/env pairs")
    running = sub.add_parser("run")
    running.add_argument("--bundle", type=Path, default=REPO / "bench" / "out" / "mitsuba_bundle")
    running.add_argument("--out", type=Path, default=REPO / "bench" / "out" / "mitsuba_device")
    running.add_argument("--variant", default="auto", choices=["auto", "llvm_ad_rgb", "cuda_ad_rgb"])
    args = parser.parse_args()
    if args.step == "pack":
        pack(args.results, args.bundle, args.captures)
    else:
        run(args.bundle, args.out, args.variant)


if __name__ == "__main__":
    main()
