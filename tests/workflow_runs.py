"""Running the workflow from a test: Snakemake on this checkout's Snakefile in a directory of the
test's own, and the jobs a dry run plans (tests/test_pipeline.py, tests/test_docs_numbers.py)."""

import re
import subprocess
import sys


def snakemake(repo, workdir, *args, extra_config=(), check=True, base="tiny.yaml"):
    """``snakemake -s <repo>/workflow/Snakefile -d <workdir> --cores 2 <args>`` on the preset ``base``
    (a name in config/ or a path) and ``extra_config`` layered on it; ``base=None``: the embedded
    default alone (no --configfile), as the README's plain ``snakemake``."""
    # --configfile takes several values, so it goes last, after any targets.
    configs = [*([str(repo / "config" / base)] if base is not None else []), *map(str, extra_config)]
    command = [sys.executable, "-m", "snakemake", "-s", str(repo / "workflow" / "Snakefile"), "-d", str(workdir), "--cores", "2",
               *args, *(["--configfile", *configs] if configs else [])]
    run = subprocess.run(command, capture_output=True, text=True, timeout=900)
    if check and run.returncode != 0:
        raise AssertionError(f"snakemake {' '.join(args)} failed:\n{run.stderr[-4000:]}")
    return run


def planned_jobs(output: str) -> dict[str, int]:
    """Rule -> jobs, from a dry run's "Job stats" table (its standard output)."""
    table = output.split("Job stats:")[1].split("total")[0]
    return {m.group(1): int(m.group(2)) for m in re.finditer(r"^(\w+)\s+(\d+)$", table, re.M)}
