"""The whole pipeline through Snakemake on a lent GPU machine (``cuda_ad_rgb``), timed per rule.

Two steps, because the GPU machine reaches no package registry and takes at most 64 MiB with it:

``pack`` (here) puts into one ``.tar.xz`` the Python packages the pipeline needs and that
machine's image lacks (`DEVICE_IMAGE`), as CPython 3.12 wheels of the versions installed here
(the pins of ``workflow/pyproject.toml`` and Snakemake's own), trimmed to what a CUDA run
loads: Mitsuba's ``cuda_ad_rgb`` and ``scalar_rgb`` variants and the plugins the pipeline's
scenes name (`MITSUBA_PLUGINS`), no type stubs or headers. Left out: the CPU's LLVM
(``llvm_ad_rgb`` only) and pycolmap (126 MB unpacked, over the transfer limit with the rest), so
the run there sets ``poses.evaluate_colmap: false`` and its DAG lacks rule ``colmap_poses``.

``run`` (there) unpacks it, runs ``snakemake --cores N --resources gpu=1`` on a config (the
embedded default unless ``--configfile``) with ``mitsuba.variant: cuda_ad_rgb`` into an empty
results tree (the asset package travels in its resources folder), stops it after ``--budget``
seconds if it has not ended, and writes under ``--out``: ``device_env.txt`` (GPU, CPU, package
versions), ``device_rules.tsv`` (per rule: jobs, summed job and CPU seconds, the longest job, the share of
the job seconds), ``device_jobs.tsv`` (every job's time and CPU time, `run_cost.job_costs`), ``snakemake.log`` and
``device_results.tar.gz`` (tables, logs, benchmarks, run config).

    python bench/device_pipeline.py pack --out bench/out/device_site.tar.xz
    # on the device, with bench/out/device_site.tar.xz and the results tree's resources folder carried:
    PYTHONPATH=workflow python3 bench/device_pipeline.py run --site bench/out/device_site.tar.xz --out "$OUT" --cores 16
"""

from __future__ import annotations

import argparse
import importlib.metadata
import os
import re
import shutil
import signal
import subprocess
import sys
import tarfile
import tempfile
import time
import zipfile
from pathlib import Path

import pandas as pd
from run_cost import job_costs, rule_costs

from freqbrdf import layout

REPO = Path(__file__).resolve().parents[1]

DEVICE_IMAGE = frozenset(
    """numpy scipy numba llvmlite matplotlib contourpy cycler fonttools kiwisolver pillow pyparsing
    scikit-image networkx tifffile imageio lazy-loader pyyaml psutil jinja2 markupsafe requests
    urllib3 idna certifi charset-normalizer packaging python-dateutil six attrs typing-extensions
    wrapt tabulate filelock mypy-extensions typing-inspect pip setuptools""".split()
)
"""Distributions the GPU machine's image holds (``.library/device/KINDS.md``), left out of the pack."""

LEFT_OUT = {"karellen-llvm-core": "LLVM for llvm_ad_rgb only", "pycolmap": "126 MB unpacked: over the transfer limit"}

MITSUBA_VARIANTS = ("cuda_ad_rgb", "scalar_rgb")
MITSUBA_PLUGINS = frozenset(
    # named by the pipeline's scene dictionaries (grep '"type":' workflow/freqbrdf) ...
    """aov area bitmap blendbsdf box diffuse disk envmap hdrfilm independent path perspective ply
    principled roughconductor sphere sunsky"""
    # ... and loaded by Mitsuba itself for those scenes (seen in /proc/<pid>/maps during the tiny
    # run) or as defaults of what they leave unset
    """ d65 merge regular srgb uniform gaussian irregular constant rectangle obj point twosided
    stratified conductor mesh_attribute tent directional""".split()
)

WHEEL_PLATFORMS = [f"manylinux_2_{n}_x86_64" for n in (17, 24, 27, 28, 31, 34, 35)] + ["manylinux2014_x86_64"]


def _normal(name: str) -> str:
    return re.sub(r"[-_.]+", "-", name).lower()


def closure(roots: list[str]) -> dict[str, str]:
    """Installed distributions ``roots`` need, transitively: normalised name -> version."""
    found: dict[str, str] = {}
    todo = list(roots)
    while todo:
        name = _normal(todo.pop())
        if name in found:
            continue
        try:
            dist = importlib.metadata.distribution(name)
        except importlib.metadata.PackageNotFoundError:
            continue  # a requirement for another Python or platform
        found[name] = dist.version
        for requirement in dist.requires or []:
            if "extra ==" not in requirement:
                todo.append(re.split(r"[ ;<>=!~\[(]", requirement, maxsplit=1)[0])
    return found


def _wheel(name: str, version: str, into: Path) -> Path:
    """A CPython 3.12 x86-64 wheel of ``name==version`` in ``into`` (built here when PyPI has only an sdist)."""
    before = set(into.iterdir())
    platforms = [arg for p in WHEEL_PLATFORMS for arg in ("--platform", p)]
    pip = [sys.executable, "-m", "pip", "-q"]
    done = subprocess.run(
        [
            *pip,
            "download",
            "--no-deps",
            "--only-binary=:all:",
            "--python-version",
            "3.12",
            "--implementation",
            "cp",
            *platforms,
            "-d",
            str(into),
            f"{name}=={version}",
        ],
        capture_output=True,
    )
    if done.returncode != 0:
        subprocess.run([*pip, "wheel", "--no-deps", "-w", str(into), f"{name}=={version}"], check=True)
    (new,) = set(into.iterdir()) - before
    return new


def _trim(site: Path) -> None:
    """Remove what a CUDA run never loads (see the module docstring)."""
    mitsuba = site / "mitsuba"
    for module in mitsuba.glob("*_*.cpython-*.so"):
        variant = module.name.split(".")[0]
        if re.fullmatch(r"(scalar|llvm|cuda)_\w+", variant) and variant not in MITSUBA_VARIANTS:
            module.unlink()
    for plugin in (mitsuba / "plugins").glob("*.so"):
        if plugin.stem not in MITSUBA_PLUGINS:
            plugin.unlink()
    (mitsuba / "data" / "srgb.coeff").unlink(missing_ok=True)  # spectral upsampling: spectral variants only
    for junk in [
        *site.rglob("*.pyi"),
        *site.glob("*.data"),
        site / "mitsuba/include",
        site / "drjit/include",
        *site.rglob("__pycache__"),
        site / "pulp/solverdir",
    ]:
        if junk.is_dir():
            shutil.rmtree(junk, ignore_errors=True)
        elif junk.exists():
            junk.unlink()


def pack(out: Path) -> None:
    """Write the trimmed packages the GPU machine lacks to ``out`` (``.tar.xz``)."""
    wanted = {
        name: version
        for name, version in closure(["freqbrdf", "snakemake"]).items()
        if name not in DEVICE_IMAGE | set(LEFT_OUT) | {"freqbrdf"}
    }
    with tempfile.TemporaryDirectory() as tmp:
        wheels, site = Path(tmp, "wheels"), Path(tmp, "site")
        wheels.mkdir()
        for name, version in sorted(wanted.items()):
            with zipfile.ZipFile(_wheel(name, version, wheels)) as wheel:
                wheel.extractall(site)
        _trim(site)
        out.parent.mkdir(parents=True, exist_ok=True)
        partial = out.with_name(out.name + ".partial")
        with tarfile.open(partial, "w:xz", preset=9) as tar:
            tar.add(site, arcname=".")
        partial.replace(out)
    print(
        f"{out}: {len(wanted)} distributions, {out.stat().st_size / 2**20:.1f} MiB "
        f"(left out: {', '.join(f'{k} ({v})' for k, v in LEFT_OUT.items())})"
    )


def _environment(python: str, env: dict[str, str]) -> str:
    """GPU, CPU and package versions on the machine the run is on."""
    probe = (
        "import importlib.metadata as m, os\n"
        "for n in ('numpy','numba','scipy','pandas','scikit-image','matplotlib','mitsuba','drjit','snakemake'):\n"
        "    print(n, m.version(n))\n"
        "print('cpus', os.cpu_count())\n"
    )
    lines = [subprocess.run([python, "-c", probe], env=env, capture_output=True, text=True).stdout]
    for command in (
        "nvidia-smi --query-gpu=name,driver_version,memory.total --format=csv,noheader",
        "grep -m1 'model name' /proc/cpuinfo",
    ):
        lines.append(subprocess.run(["sh", "-c", command], capture_output=True, text=True).stdout)
    return "".join(lines)


def rule_shares(jobs: pd.DataFrame) -> pd.DataFrame:
    """`run_cost.rule_costs` with each rule's longest job and its share of all jobs' seconds."""
    rules = rule_costs(jobs)
    rules["longest_s"] = jobs.groupby("rule")["s"].max()
    rules["share"] = rules["s"] / rules["s"].sum()
    return rules.round(3)


def run(site: Path, out: Path, cores: int, budget: float, configfile: Path | None) -> int:
    """Run the pipeline on the GPU and write the files the module docstring lists; Snakemake's exit code."""
    out.mkdir(parents=True, exist_ok=True)
    unpacked = Path(tempfile.mkdtemp(prefix="freqbrdf-site-"))
    with tarfile.open(site) as tar:
        tar.extractall(unpacked, filter="fully_trusted")
    env = os.environ | {"PYTHONPATH": os.pathsep.join([str(unpacked), str(REPO / "workflow")]), "PYTHONUNBUFFERED": "1"}
    (out / "device_env.txt").write_text(_environment(sys.executable, env))
    overlay = Path(unpacked, "device.yaml")
    overlay.write_text("mitsuba: {variant: cuda_ad_rgb}\nposes: {evaluate_colmap: false}\n")
    # The asset package travels in the resources folder: newer than its rule's code, it is not fetched again.
    for tarball in (REPO / layout.RESOURCE).parent.glob("*.tgz"):
        tarball.touch()
    configs = ["--configfile", *([str(configfile)] if configfile else []), str(overlay)]
    command = [
        sys.executable,
        "-m",
        "snakemake",
        "--cores",
        str(cores),
        "--resources",
        "gpu=1",
        "--scheduler",
        "greedy",
        "--keep-going",
        *configs,
    ]
    start = time.perf_counter()
    with open(out / "snakemake.log", "w") as log:
        snakemake = subprocess.Popen(
            command, cwd=REPO, env=env, stdout=log, stderr=subprocess.STDOUT, start_new_session=True
        )
        try:
            code = snakemake.wait(timeout=budget)
        except subprocess.TimeoutExpired:
            os.killpg(snakemake.pid, signal.SIGTERM)  # Snakemake stops its jobs and removes their outputs
            code = snakemake.wait()
            log.write(f"\nstopped by device_pipeline.py after its budget of {budget:.0f} s\n")
    wall = time.perf_counter() - start
    results = REPO / layout.RESULTS
    try:
        jobs = job_costs(results / "benchmarks")
    except ValueError as error:  # no job got as far as its benchmark file
        print(error)
        jobs = pd.DataFrame(columns=["rule", "job", "s", "cpu_time"])
    else:
        jobs.to_csv(out / "device_jobs.tsv", sep="\t", index=False)
        rule_shares(jobs).to_csv(out / "device_rules.tsv", sep="\t")
    with open(out / "device_env.txt", "a") as env_file:
        env_file.write(f"snakemake exit {code}, wall {wall:.1f} s, {len(jobs)} jobs benchmarked, cores {cores}\n")
    with tarfile.open(out / "device_results.tar.gz", "w:gz") as tar:
        for name in ("tables", "logs", "benchmarks", "run_config.yaml"):
            if (results / name).exists():
                tar.add(results / name, arcname=name)
    print(f"snakemake exit {code} after {wall:.1f} s; {len(jobs)} jobs benchmarked")
    return code


def main() -> None:
    parser = argparse.ArgumentParser(description=__doc__.splitlines()[0])
    sub = parser.add_subparsers(dest="step", required=True)
    packing = sub.add_parser("pack")
    packing.add_argument("--out", type=Path, default=REPO / "bench/out/device_site.tar.xz")
    running = sub.add_parser("run")
    running.add_argument("--site", type=Path, default=REPO / "bench/out/device_site.tar.xz")
    running.add_argument("--out", type=Path, required=True)
    running.add_argument("--cores", type=int, default=os.cpu_count())
    running.add_argument("--budget", type=float, default=480.0, help="seconds before Snakemake is stopped")
    running.add_argument("--configfile", type=Path, help="a preset layered on the embedded default")
    args = parser.parse_args()
    if args.step == "pack":
        pack(args.out)
    else:
        sys.exit(run(args.site, args.out, args.cores, args.budget, args.configfile))


if __name__ == "__main__":
    main()
