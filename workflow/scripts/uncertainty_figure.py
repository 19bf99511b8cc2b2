"""Rule uncertainty_figure: sparsification curves of the entropy and the trivial baselines, per capture;
the reliability diagram of the posterior, per parameter."""

import numpy as np
import pandas as pd

from freqbrdf.report.figures import reliability_figure, sparsification_figure
from freqbrdf.util.logs import run_script


def benchmark_rows(path, smk) -> pd.DataFrame:
    """The rows of a table of rule metrics on the run's poses and the benchmark's captures."""
    table = pd.read_csv(path, sep="\t", keep_default_na=False)
    benchmark = {tuple(capture) for capture in smk.params.captures}
    ours = np.array([(o, e) in benchmark for o, e in zip(table.object, table.env)], dtype=bool)
    return table[(table.poses == smk.params.poses).to_numpy() & ours]


def main(smk, log):
    curves = benchmark_rows(smk.input.curves, smk)
    sparsification_figure(smk.output.sparsification, curves, smk.params.method)
    log.info("%s: %s's curves on %d captures", smk.output.sparsification, smk.params.method,
             len(curves[curves.method == smk.params.method][["object", "env"]].drop_duplicates()))
    levels = benchmark_rows(smk.input.reliability, smk)
    reliability_figure(smk.output.reliability, levels, smk.params.method)
    at90 = levels[(levels.method == smk.params.method) & (levels.level == 0.9)]
    log.info("%s: 90%% coverage from %.3f to %.3f over captures and parameters", smk.output.reliability,
             at90.coverage.min(), at90.coverage.max())


run_script(main, snakemake)  # noqa: F821 (injected by Snakemake)
