"""What the uncertainty results of a finished run cost (issue 19; docs/uncertainty.md, "Entropy agreement").

Reads, under the results directory (``--results``, default the working
directory's, `freqbrdf.layout.RESULTS`; read-only):
- every capture's ``agreement.json`` (`freqbrdf.layout.AGREEMENT`): the
  seconds of the Mitsuba grid entropy, the angular entropy and the
  power-spectrum entropy on each capture's texel sample, as the rule measured them;
- the ``benchmark:`` files (`freqbrdf.layout.benchmark`) of the jobs that produce the rest: the spectrum
  entropy of whole captures (``spectrum_search``), the entropy-guided merges
  (``merge_svbrdf``), the views sweep (``views_sweep``) and, where the run has
  them, the view ranking (``view_selection``).

    python bench/uncertainty_cost.py [--results DIR]

Writes ``bench/out/uncertainty_cost.tsv``: one row per step, with the number
of jobs and the mean, minimum and maximum seconds per job. Job times are
wall times on the run's machine: compare them only within one run.
"""

from __future__ import annotations

import argparse
import json
from pathlib import Path

import pandas as pd

from freqbrdf import layout

# step -> (benchmark directory, what one job does)
BENCHMARKED = {
    "spectrum entropy, whole capture": ("spectrum_search", "SH spectra grid search and entropy of every texel"),
    "entropy-guided merge": ("merge_svbrdf", "one object's captures merged by entropy"),
    "views sweep": ("views_sweep", "freq and the entropy at each view count of one capture"),
    "view ranking": ("view_selection", "expected entropy of the candidate views of one capture"),
}
# step -> agreement.json key
SAMPLED = {
    "Mitsuba grid entropy, texel sample": "time_mitsuba_s",
    "angular entropy, texel sample": "time_angular_s",
    "power-spectrum entropy, texel sample": "time_spectrum_s",
}


def _row(step: str, seconds: pd.Series, what: str) -> dict:
    return {"step": step, "jobs": len(seconds), "mean_s": seconds.mean(), "min_s": seconds.min(),
            "max_s": seconds.max(), "what": what}


def matching(results: Path, pattern: Path) -> list[Path]:
    """The files matching ``pattern`` (a path under ``results`` with ``*`` for some of its parts), sorted."""
    return sorted(results.glob(str(pattern.relative_to(results))))


def cost_table(results: Path) -> pd.DataFrame:
    """One row per step found under ``results`` (steps the run did not have are left out)."""
    rows = []
    agreements = layout.located(layout.AGREEMENT, results, object="*", env="*", poses="*", name="agreement.json")
    summaries = [json.loads(p.read_text()) for p in matching(results, agreements)]
    if summaries:
        texels = sorted({s["texels"] for s in summaries})
        for step, key in SAMPLED.items():
            rows.append(_row(step, pd.Series([s[key] for s in summaries]),
                             f"{'/'.join(map(str, texels))} texels, grid {summaries[0]['grid']}^3"))
    for step, (rule, what) in BENCHMARKED.items():
        files = matching(results, layout.located(layout.benchmark(rule, "*"), results))
        if files:
            rows.append(_row(step, pd.Series([pd.read_csv(f, sep="\t").s.iloc[0] for f in files]), what))
    return pd.DataFrame(rows, columns=["step", "jobs", "mean_s", "min_s", "max_s", "what"])


def main() -> None:
    parser = argparse.ArgumentParser(description=__doc__.splitlines()[0])
    parser.add_argument("--results", type=Path, default=Path(layout.RESULTS), help="the results directory")
    args = parser.parse_args()
    table = cost_table(args.results)
    if table.empty:
        raise SystemExit(f"{args.results}: no entropy_agreement or uncertainty benchmark outputs; run the pipeline first")
    out = Path("bench/out/uncertainty_cost.tsv")
    out.parent.mkdir(exist_ok=True)
    table.to_csv(out, sep="\t", index=False, float_format="%.4g")
    print(table.to_string(index=False, float_format=lambda v: f"{v:.4g}"))


if __name__ == "__main__":
    main()
