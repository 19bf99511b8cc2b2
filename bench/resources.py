"""Declared scheduler resources against what a finished run's jobs used (issue 18; docs/cluster.md).

Every rule declares ``mem_mb`` and ``runtime`` (minutes), scaled from the
default config's measurements by `freqbrdf.util.sizing.size_factor`
(``rules/common.smk``: ``memory``, ``minutes``). This script lists, for each
rule of a finished run, the declared values (from a forced dry run of the
same config) beside the largest ``max_rss`` (MB) and ``s`` of its jobs'
``benchmark:`` files, and flags the rules whose jobs went over.

    python bench/resources.py [--directory .] [--configfile config/paper.yaml]

Writes ``bench/out/resources.tsv`` (rule, jobs, declared and measured memory
and time, ``over``); exits 1 if a job went over what its rule declares.
"""

from __future__ import annotations

import argparse
import re
import subprocess
import sys
from pathlib import Path

import pandas as pd

_BLOCK = re.compile(r"^(?:local)?rule (\w+):$", re.M)


def declared_resources(dry_run: str) -> pd.DataFrame:
    """Per job of a dry run's output: rule, benchmark file, declared ``mem_mb`` and ``runtime``."""
    rows = []
    starts = [m.start() for m in _BLOCK.finditer(dry_run)] + [len(dry_run)]
    for start, end in zip(starts, starts[1:]):
        block = dry_run[start:end]
        bench = re.search(r"^\s+benchmark: (\S+)$", block, re.M)
        resources = re.search(r"^\s+resources: (.*)$", block, re.M)
        if not (bench and resources):
            continue
        values = dict(item.split("=", 1) for item in resources.group(1).split(", ") if "=" in item)
        rows.append({"rule": _BLOCK.match(block).group(1), "benchmark": bench.group(1),
                     "mem_mb": float(values["mem_mb"]), "runtime_min": float(values["runtime"])})
    return pd.DataFrame(rows, columns=["rule", "benchmark", "mem_mb", "runtime_min"])


def measured(directory: Path, declared: pd.DataFrame) -> pd.DataFrame:
    """The declared jobs whose benchmark file exists, with its ``s`` and ``max_rss``."""
    rows = []
    for job in declared.itertuples():
        path = directory / job.benchmark
        if path.is_file():
            first = pd.read_csv(path, sep="\t").iloc[0]
            rows.append(job._asdict() | {"s": float(first["s"]), "max_rss": pd.to_numeric(first["max_rss"],
                                                                                            errors="coerce")})
    table = pd.DataFrame(rows)
    if table.empty:
        return table
    table = table.drop(columns="Index")
    table["over"] = (table.max_rss > table.mem_mb) | (table.s > 60 * table.runtime_min)
    return table


def by_rule(jobs: pd.DataFrame) -> pd.DataFrame:
    """One row per rule: jobs, declared memory and time, the largest measured, and whether any job went over."""
    return jobs.groupby("rule").agg(jobs=("s", "size"), mem_mb=("mem_mb", "max"), max_rss=("max_rss", "max"),
                                    runtime_min=("runtime_min", "max"), max_s=("s", "max"),
                                    over=("over", "any")).reset_index()


def dry_run(directory: Path, snakefile: Path, configfiles: list[str]) -> str:
    """The output of ``snakemake -n -F`` (every job of the DAG, as declared)."""
    command = [sys.executable, "-m", "snakemake", "-s", str(snakefile), "-d", str(directory), "-n", "-F",
               "--cores", "2"] + (["--configfile", *configfiles] if configfiles else [])
    result = subprocess.run(command, capture_output=True, text=True, check=True)
    return result.stdout + result.stderr


def main() -> None:
    parser = argparse.ArgumentParser(description=__doc__.splitlines()[0])
    parser.add_argument("--directory", type=Path, default=Path("."), help="the run's working directory")
    parser.add_argument("--snakefile", type=Path, default=Path(__file__).resolve().parents[1] / "workflow" / "Snakefile")
    parser.add_argument("--configfile", nargs="*", default=[])
    args = parser.parse_args()
    jobs = measured(args.directory, declared_resources(dry_run(args.directory, args.snakefile, args.configfile)))
    if jobs.empty:
        raise SystemExit(f"{args.directory}: no benchmark files of the declared jobs; run the pipeline first")
    table = by_rule(jobs)
    out = Path("bench/out/resources.tsv")
    out.parent.mkdir(exist_ok=True)
    table.to_csv(out, sep="\t", index=False, float_format="%.1f")
    print(table.to_string(index=False, float_format=lambda v: f"{v:.1f}"))
    if table.over.any():
        raise SystemExit(f"jobs over their declared resources: {', '.join(table.rule[table.over])}")


if __name__ == "__main__":
    main()
