"""Rule convergence_figure: parameter MSE against time, Mitsuba's runs beside the frequency-domain methods."""

from pathlib import Path

import pandas as pd

from freqbrdf.report.figures import convergence_figure
from freqbrdf.report.tables.tidy import read_tidy
from freqbrdf.util.logs import run_script
from freqbrdf.util.mitsuba_setup import timing_note


def main(smk, log):
    w = smk.wildcards
    metrics = read_tidy(smk.input.metrics)
    rows = metrics[(metrics.object == w.object) & (metrics.env == w.env) & (metrics.poses == w.poses)
                   & (metrics.view == "")]
    value = {(m, k): float(v) for m, k, v in zip(rows.method, rows.metric, rows.value)}
    extract_s = pd.read_csv(smk.input.extraction, sep="\t")["s"].mean()
    # one-shot methods at their whole time from the capture (extraction included)
    points = {m: (extract_s + value[m, "time_total_s"], value[m, "mse_average"]) for m in smk.params.points
              if (m, "time_total_s") in value and (m, "mse_average") in value}
    curves = {}
    for method, start, directory in zip(smk.params.curves, smk.params.starts, smk.input.curves):
        curve = pd.read_csv(Path(directory) / "mse_curve.tsv", sep="\t")
        offset = points[start][0] if start in points else 0.0  # a fine-tuning run starts after its start method
        curves[method] = (offset + curve.elapsed_s.to_numpy(), curve.mse_average.to_numpy())
    convergence_figure(smk.output[0], curves, points, f"{w.object} captured under {w.env}: parameter MSE against time",
                       timing_note(smk.params.variant))
    log.info("convergence of %s; one-shot %s", ", ".join(curves), ", ".join(points))


run_script(main, snakemake)  # noqa: F821 (injected by Snakemake)
