"""Rule view_selection_table: every capture's view-selection sweep in one table and one figure."""

import pandas as pd

from freqbrdf.report.figures import view_selection_figure
from freqbrdf.util.io import atomic_path
from freqbrdf.util.logs import run_script


def main(smk, log):
    tables = []
    for (o, e), path in zip(smk.params.captures, smk.input.sweeps):
        tables.append(pd.read_csv(path, sep="\t").assign(object=o, env=e))
    table = pd.concat(tables, ignore_index=True)
    table = table[["object", "env"] + [c for c in table.columns if c not in ("object", "env")]]
    with atomic_path(smk.output.table) as f:
        table.to_csv(f, sep="\t", index=False, float_format="%.6g")
    view_selection_figure(smk.output.figure, table)
    # mean over the captures swept at each k (random: over seeds too) of freq's MSE per strategy
    summary = table.groupby(["views", "strategy"])["mse_average"].mean().unstack("strategy")
    summary["captures"] = table.drop_duplicates(["object", "env", "views"]).groupby("views").size()
    log.info("mean parameter MSE per k over the captures swept at it:\n%s", summary.to_string(float_format="%.4f"))


run_script(main, snakemake)  # noqa: F821 (injected by Snakemake)
