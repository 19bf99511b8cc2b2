"""Running the workflow from a test: Snakemake on this checkout's Snakefile in a directory of the
test's own, and the jobs a dry run plans (tests/test_pipeline.py, tests/test_docs_numbers.py)."""

import os
import re
import subprocess
import sys
from pathlib import Path


def without_npm(directory: Path) -> dict[str, str]:
    """The environment with an ``npm`` first on PATH that fails as an absent one would (exit 127):
    a run that needs the npm package fails in it."""
    directory.mkdir(parents=True, exist_ok=True)
    npm = directory / "npm"
    npm.write_text("#!/bin/sh\necho 'npm: not available in this test' >&2\nexit 127\n")
    npm.chmod(0o755)
    return {**os.environ, "PATH": f"{directory}{os.pathsep}{os.environ.get('PATH', '')}"}


def snakemake(repo, workdir, *args, extra_config=(), check=True, base="tiny.yaml", env=None):
    """``snakemake -s <repo>/workflow/Snakefile -d <workdir> --cores 2 <args>`` on the preset ``base``
    (a name in config/ or a path) and ``extra_config`` layered on it; ``base=None``: the embedded
    default alone (no --configfile), as the README's plain ``snakemake``; ``env``: the process's
    environment (default: this one's)."""
    # --configfile takes several values, so it goes last, after any targets.
    configs = [*([str(repo / "config" / base)] if base is not None else []), *map(str, extra_config)]
    command = [sys.executable, "-m", "snakemake", "-s", str(repo / "workflow" / "Snakefile"), "-d", str(workdir), "--cores", "2",
               *args, *(["--configfile", *configs] if configs else [])]
    run = subprocess.run(command, capture_output=True, text=True, timeout=900, env=env)
    if check and run.returncode != 0:
        raise AssertionError(f"snakemake {' '.join(args)} failed:\n{run.stderr[-4000:]}")
    return run


def planned_jobs(output: str) -> dict[str, int]:
    """Rule -> jobs, from a dry run's "Job stats" table (its standard output)."""
    table = output.split("Job stats:")[1].split("total")[0]
    return {m.group(1): int(m.group(2)) for m in re.finditer(r"^(\w+)\s+(\d+)$", table, re.M)}
