"""Rule uncertainty_figure: sparsification curves of the entropy and the trivial baselines, per capture."""

import numpy as np
import pandas as pd

from freqbrdf.report.figures import sparsification_figure
from freqbrdf.util.logs import run_script


def main(smk, log):
    curves = pd.read_csv(smk.input.curves, sep="\t", keep_default_na=False)
    benchmark = {tuple(capture) for capture in smk.params.captures}
    ours = np.array([(o, e) in benchmark for o, e in zip(curves.object, curves.env)], dtype=bool)
    curves = curves[(curves.poses == smk.params.poses).to_numpy() & ours]
    sparsification_figure(smk.output[0], curves, smk.params.method)
    log.info("%s: %s's curves on %d captures", smk.output[0], smk.params.method,
             len(curves[curves.method == smk.params.method][["object", "env"]].drop_duplicates()))


run_script(main, snakemake)  # noqa: F821 (injected by Snakemake)
