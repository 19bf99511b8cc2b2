"""Rule score_real_capture: parameter MSE and entropy-error correlation of a real capture with ground truth.

Rows have the columns of the metrics table (rule metrics), computed the
same way: MSE over the texels some training view observes, Pearson's r between
the entropy and the per-texel error of the entropy-scored methods.
"""

import warnings

import pandas as pd
from scipy.stats import ConstantInputWarning, pearsonr

from freqbrdf.artefacts import read_entropy, read_observations, read_svbrdf
from freqbrdf.sphere.brdf import TEXTURES, parameter_mse
from freqbrdf.util.io import atomic_path
from freqbrdf.util.logs import run_script
from freqbrdf.report.metrics import parameter_error_map

COLUMNS = ["object", "env", "poses", "method", "relight_env", "metric", "value"]


def main(smk, log):
    truth = read_svbrdf(dict(zip(TEXTURES, smk.input.truth)))
    obs = read_observations(smk.input.observations)
    texels = obs.texels.texel[obs.observed]
    entropy = read_entropy(smk.input.entropy).atlas.ravel()
    w = smk.wildcards
    rows = []
    for method, directory in zip(smk.params.methods, smk.input.estimates):
        estimate = read_svbrdf(directory)
        key = dict(object=w.object, env=w.env, poses=w.poses, method=method, relight_env="")
        rows += [key | dict(metric=f"mse_{k}", value=v) for k, v in parameter_mse(truth, estimate, texels).items()]
        if method in smk.params.entropy_methods:
            error = parameter_error_map(truth, estimate).ravel()
            with warnings.catch_warnings():
                warnings.simplefilter("ignore", ConstantInputWarning)
                r = float(pearsonr(entropy[texels], error[texels]).statistic)
            rows.append(key | dict(metric="pearson_entropy_error", value=r))
    table = pd.DataFrame(rows, columns=COLUMNS)
    with atomic_path(smk.output[0]) as tmp:
        table.to_csv(tmp, index=False)
    log.info("%d rows; mse_average: %s", len(table),
             table[table.metric == "mse_average"].set_index("method").value.round(5).to_dict())


run_script(main, snakemake)  # noqa: F821 (injected by Snakemake)
