"""What a finished run's jobs cost, from their ``benchmark:`` files: for a run made in parts,
or on a machine that was not idle, where the wall clock does not say it.

Per rule: the jobs, the sum of their wall times (``s``) and of their CPU times
(``cpu_time``: user and system seconds of the job's processes, which other load on the
machine barely changes). ``cpu_time / cores`` over every job is the wall time the run would
take on that many idle cores if they were never short of work: a lower bound, since a DAG
leaves cores idle while one job waits for another.

    python bench/run_cost.py --results DIR [--cores 2]

Prints a table per rule and the totals; writes nothing.
"""

from __future__ import annotations

import argparse
from pathlib import Path

import pandas as pd


def job_costs(benchmarks: Path) -> pd.DataFrame:
    """One row per ``benchmarks/{rule}/{job}.tsv``, or ``benchmarks/{rule}.tsv`` for a rule of one
    job (`freqbrdf.layout.benchmark`): rule, job, ``s``, ``cpu_time``.

    Raises naming the directory if it holds no benchmark file, and the file if it lacks a column.
    """
    rows = []
    for path in sorted([*benchmarks.glob("*/*.tsv"), *benchmarks.glob("*.tsv")]):
        table = pd.read_csv(path, sep="\t")
        missing = {"s", "cpu_time"} - set(table.columns)
        if missing or table.empty:
            raise ValueError(f"{path}: not a benchmark file (columns {sorted(table.columns)})")
        single = path.parent == benchmarks
        rows.append({"rule": path.stem if single else path.parent.name, "job": "" if single else path.stem,
                     "s": float(table["s"].iloc[-1]),
                     "cpu_time": float(table["cpu_time"].iloc[-1])})
    if not rows:
        raise ValueError(f"{benchmarks}: no benchmark files (benchmarks/<rule>/<job>.tsv, benchmarks/<rule>.tsv)")
    return pd.DataFrame(rows)


def rule_costs(jobs: pd.DataFrame) -> pd.DataFrame:
    """Per rule, jobs and summed ``s`` and ``cpu_time``, the costliest rule first."""
    table = jobs.groupby("rule").agg(jobs=("job", "size"), s=("s", "sum"), cpu_time=("cpu_time", "sum"))
    return table.sort_values("cpu_time", ascending=False)


def main() -> None:
    parser = argparse.ArgumentParser(description=__doc__, formatter_class=argparse.RawDescriptionHelpFormatter)
    parser.add_argument("--results", type=Path, required=True, help="a finished run's results directory")
    parser.add_argument("--cores", type=int, default=2, help="cores the run had (default 2)")
    args = parser.parse_args()
    if args.cores < 1:
        parser.error(f"--cores must be >= 1, got {args.cores}")
    jobs = job_costs(args.results / "benchmarks")
    print(rule_costs(jobs).to_string(float_format=lambda v: f"{v:.1f}"))
    cpu, wall = jobs["cpu_time"].sum(), jobs["s"].sum()
    print(f"{len(jobs)} jobs: wall times summed {wall / 3600:.2f} h, CPU {cpu / 3600:.2f} h; "
          f"on {args.cores} idle cores never short of work: {cpu / args.cores / 3600:.2f} h")


if __name__ == "__main__":
    main()
