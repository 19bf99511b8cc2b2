"""Choose ``entropy_agreement.sigma`` on the tuning set (docs/uncertainty.md, "Entropy agreement"; docs/tuning_log.md).

For each capture of the tuning set (config/tuning.yaml, never a reported
capture), reads what rule entropy_agreement saved (``entropy.npz`` of
`freqbrdf.layout.AGREEMENT`: the light-normalised objective D of the Mitsuba
grid and of the angular grid on a texel sample) and scores each candidate
sigma by the Pearson correlation of the Mitsuba grid's entropy with
``freq``'s per-texel squared parameter error (its estimate,
`freqbrdf.layout.ESTIMATE`, against `freqbrdf.layout.OBJECT_TEXTURE`), the
criterion `spectrum.sigma` was chosen by. The angular entropy shares the
sigma (same D), so the choice does not look at the agreement it is reported
for.

``--targets`` prints what Snakemake must make first (each capture's
agreement and ``freq`` estimate, gt poses) and exits; ``--results`` reads
another results directory than the working directory's (`freqbrdf.layout.RESULTS`).

    CAPTURES="die/museum die/overcast vase/museum vase/overcast"
    snakemake --cores 2 --configfile config/tuning.yaml \\
        --config 'entropy_agreement={captures: 4, texels: 256, grid: 8, spp: 8, sigma: 0.03}' -- \\
        $(python bench/entropy_sigma.py --targets --captures $CAPTURES)
    python bench/entropy_sigma.py --captures $CAPTURES

Writes ``bench/out/entropy_sigma.tsv``: one row per capture and sigma, and the
means over the captures (capture ``mean``).
"""

from __future__ import annotations

import argparse
from pathlib import Path

import numpy as np
import pandas as pd

from freqbrdf import layout
from freqbrdf.artefacts import read_svbrdf
from freqbrdf.sphere.brdf import TEXTURES
from freqbrdf.report.metrics import pearson
from freqbrdf.studies.entropy_agreement import likelihood_entropy
from freqbrdf.report.metrics import parameter_error_map

SIGMAS = (0.3, 0.1, 0.03, 0.01, 0.003, 0.001)


def targets(capture: str) -> list[str]:
    """The Snakemake targets `score` reads from for one capture: its agreement and its freq estimate."""
    obj, env = capture.split("/")
    return [layout.fill(layout.AGREEMENT, object=obj, env=env, poses="gt", name="agreement.json"),
            layout.fill(layout.ESTIMATE, object=obj, env=env, poses="gt", method="freq")]


def score(results: Path, capture: str, sigmas: tuple[float, ...]) -> list[dict]:
    """Pearson(entropy, freq's squared error) on one capture's texel sample, per sigma."""
    obj, env = capture.split("/")
    saved = np.load(layout.located(layout.AGREEMENT, results, object=obj, env=env, poses="gt", name="entropy.npz"))
    truth = read_svbrdf({n: layout.located(layout.OBJECT_TEXTURE, results, object=obj, texture=n) for n in TEXTURES})
    estimate = read_svbrdf(layout.located(layout.ESTIMATE, results, object=obj, env=env, poses="gt", method="freq"))
    error = parameter_error_map(dict(truth), dict(estimate)).ravel()[saved["texel"]][saved["scored"]]
    rows = []
    for sigma in sigmas:
        row = {"capture": capture, "sigma": sigma}
        for grid in ("mitsuba", "angular"):
            h = likelihood_entropy(saved[f"objective_{grid}"], sigma)[saved["scored"]]
            row[f"pearson_error_{grid}"] = pearson(h, error)
            row[f"mean_entropy_{grid}"] = float(h.mean())
        row["pearson_angular_mitsuba"] = pearson(
            likelihood_entropy(saved["objective_angular"], sigma)[saved["scored"]],
            likelihood_entropy(saved["objective_mitsuba"], sigma)[saved["scored"]])
        rows.append(row)
    return rows


def main() -> None:
    parser = argparse.ArgumentParser(description=__doc__.splitlines()[0])
    parser.add_argument("--captures", nargs="+", required=True, help="object/env of the tuning set")
    parser.add_argument("--results", type=Path, default=Path(layout.RESULTS), help="the results directory")
    parser.add_argument("--sigmas", type=float, nargs="+", default=list(SIGMAS))
    parser.add_argument("--targets", action="store_true", help="print the Snakemake targets of --captures and exit")
    args = parser.parse_args()
    if args.targets:
        print(" ".join(t for c in args.captures for t in targets(c)))
        return
    table = pd.DataFrame([r for c in args.captures for r in score(args.results, c, tuple(args.sigmas))])
    mean = table.drop(columns="capture").groupby("sigma", sort=False).mean().reset_index().assign(capture="mean")
    table = pd.concat([table, mean[table.columns]], ignore_index=True)
    out = Path("bench/out/entropy_sigma.tsv")
    out.parent.mkdir(exist_ok=True)
    table.to_csv(out, sep="\t", index=False, float_format="%.4f")
    print(table[table.capture == "mean"].to_string(index=False, float_format=lambda v: f"{v:.3f}"))


if __name__ == "__main__":
    main()
