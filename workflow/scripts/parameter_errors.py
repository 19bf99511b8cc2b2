"""Rule parameter_errors: parameter MSE of every method on every synthetic capture (tidy table)."""

from pathlib import Path

import numpy as np
import pandas as pd

from freqbrdf.io import atomic_path, read_svbrdf
from freqbrdf.logs import run_script
from freqbrdf.metrics import parameter_mse
from freqbrdf.spectral import observed_texels


def main(smk, log):
    rows = []
    for (obj, env, poses, method), estimate_dir in zip(smk.params.captures, smk.input.estimates):
        truth = read_svbrdf(*(Path(f"results/objects/{obj}/{n}.exr") for n in ("base_color", "roughness", "metallic")))
        estimate = read_svbrdf(*(Path(estimate_dir) / f"{n}.exr" for n in ("base_color", "roughness", "metallic")))
        obs = Path(f"results/observations/{obj}/{env}/{poses}")
        texel = np.load(obs / "texels.npz")["texel"]
        scores = parameter_mse(truth, estimate, texel[observed_texels(np.load(obs / "weight.npy", mmap_mode="r"))])
        rows += [{"object": obj, "env": env, "poses": poses, "method": method, "metric": f"mse_{k}", "value": v}
                 for k, v in scores.items()]
    table = pd.DataFrame(rows)
    with atomic_path(smk.output[0]) as tmp:
        table.to_csv(tmp, sep="\t", index=False, float_format="%.6g")
    average = table[table.metric == "mse_average"].pivot_table(index=["object", "env"], columns="method", values="value")
    log.info("parameter MSE (average of base colour, roughness, metallic) over observed texels:\n%s",
             average.to_string(float_format=lambda v: f"{v:.3f}"))


run_script(main, snakemake)  # noqa: F821 (injected by Snakemake)
