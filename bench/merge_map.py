"""Which per-texel map should the merge of rule ``merge_svbrdf`` (paper Table 6) take texels by?

Reads a finished run: the tuning preset's (config/tuning.yaml) to choose the map, a reported
run's only to report the choice's effect there. For each
object with several captures and each capture the merge is filed under, merges ``freq``'s
estimates of all the object's captures, per texel from the capture lowest in:

- ``entropy``: the spectrum entropy (the paper's choice);
- ``posterior``: the expected squared parameter error under the fit's posterior
  (`freqbrdf.estimate.optimise.posterior.expected_error_atlas`, from the ``std_*.exr`` of each
  estimate);
- ``views``: minus the number of views that observe the texel (a trivial baseline);
- ``oracle``: the true per-texel error (a bound no map can pass);

and scores each merge, and the filed capture's own estimate (``single``), by parameter MSE
over the texels the filed capture observes (as metrics.csv scores a merge).

    python bench/merge_map.py --results DIR        (DIR: a finished run's results)

Prints one row per object and filed capture, and the means.
"""

from __future__ import annotations

import argparse
from pathlib import Path

import numpy as np
import pandas as pd
import yaml

from freqbrdf import layout
from freqbrdf.artefacts import read_entropy, read_observations, read_posterior_std, read_svbrdf
from freqbrdf.estimate.merge import lowest_merge
from freqbrdf.estimate.optimise.posterior import expected_error_atlas
from freqbrdf.report.metrics import parameter_error_map
from freqbrdf.sphere.brdf import TEXTURES, parameter_mse
from freqbrdf.report.sparsification import baseline_maps


def capture_maps(results: Path, obj: str, env: str, truth, method: str) -> dict:
    """One capture's estimate, observed texels and score maps (R, R)."""
    where = dict(object=obj, env=env, poses="gt")
    estimate_dir = layout.located(layout.ESTIMATE, results, method=method, **where)
    estimate = read_svbrdf(estimate_dir)
    obs = read_observations(layout.located(layout.OBSERVATIONS, results, **where))
    shape = estimate.roughness.shape
    texels = obs.texels.texel[obs.observed]
    views = np.zeros(shape[0] * shape[1])  # texels no view sees: 0 views, last choice
    views[texels] = baseline_maps(obs)["views"]
    return {"estimate": estimate, "texels": texels,
            "entropy": read_entropy(layout.located(layout.ENTROPY, results, **where)).atlas,
            "posterior": expected_error_atlas(read_posterior_std(estimate_dir)),
            "views": views.reshape(shape),
            "oracle": parameter_error_map(truth, estimate)}


def main() -> None:
    parser = argparse.ArgumentParser(description=__doc__.splitlines()[0])
    parser.add_argument("--results", type=Path, required=True)
    parser.add_argument("--method", default="freq")
    args = parser.parse_args()
    config = yaml.safe_load((args.results / Path(layout.RUN_CONFIG).name).read_text())
    rows = []
    for obj in config["objects"]:
        envs = config["capture_envs"]
        truth = read_svbrdf({g: layout.located(layout.OBJECT_TEXTURE, args.results, object=obj, texture=g)
                             for g in TEXTURES})
        maps = {env: capture_maps(args.results, obj, env, truth, args.method) for env in envs}
        for filed in envs:
            order = [filed] + [e for e in envs if e != filed]
            texels = maps[filed]["texels"]
            row = {"object": obj, "filed": filed,
                   "single": parameter_mse(truth, maps[filed]["estimate"], texels)["average"]}
            for score in ("entropy", "posterior", "views", "oracle"):
                merged, _ = lowest_merge([maps[e]["estimate"] for e in order], [maps[e][score] for e in order])
                row[score] = parameter_mse(truth, merged, texels)["average"]
            rows.append(row)
    table = pd.DataFrame(rows)
    print(table.to_string(index=False, float_format="%.4f"))
    print(table.drop(columns=["object", "filed"]).mean().to_string(float_format="%.4f"))


if __name__ == "__main__":
    main()
