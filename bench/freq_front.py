"""Time against accuracy of the frequency-domain estimator (method ``freq``) over its cost settings.

Each setting is config ``optimise`` (config/config.yaml) with named changes (`SETTINGS`), and
each (capture, setting) runs as its own job in a fresh Python process, as rule
``optimise_svbrdf`` does: imports, reading the observations, the map and the map's light table,
the method's light, the optimiser (`freqbrdf.estimate.optimise.solve.estimate_capture`) and
writing the textures. The table is fitted first, once per map and setting, in a job of its own
as rule ``light_table`` does (its time is ``table_s``, shared by the captures under the map).
The times are the processes' wall times, start-up included, on 2 threads; the accuracy is the
parameter MSE against the ground truth over the observed texels (as `bench/optimise_bench.py`).
Every input comes from the results directory (`freqbrdf.layout.RESULTS`, or ``FREQBRDF_RESULTS``):
choose settings on the tuning captures (config/tuning.yaml), report them on the default ones.

    python bench/freq_front.py --captures die/museum vase/sunset
    python bench/freq_front.py --captures sphere/studio --settings default "table off"

Writes ``bench/out/freq_front.tsv``: one row per capture and setting, and a mean row per setting.
A first job, not recorded, fills numba's cache, so every timed job loads compiled kernels as a
pipeline job does after the first. Time it on an otherwise idle machine.
"""

from __future__ import annotations

import argparse
import json
import os
import subprocess
import sys
import tempfile
import time
from pathlib import Path

REPO = Path(__file__).resolve().parents[1]
OUT = REPO / "bench" / "out"
# label: changes to config `optimise` (nested blocks replace only the keys they name)
SETTINGS = {
    "default": {},
    "table off": {"light_table": {"rows": 0}},
    "table 32 rows": {"light_table": {"rows": 32}},
    "table 64 rows": {"light_table": {"rows": 64}},
    "table 96 rows": {"light_table": {"rows": 96}},
    "table rank 6": {"light_table": {"rank": 6}},
    "100 steps": {"iterations": 100, "refit_every": 34},
    "75 steps": {"iterations": 75, "refit_every": 25},
    "75 steps, lr 0.1": {"iterations": 75, "refit_every": 25, "lr": 0.1},
    "50 steps": {"iterations": 50, "refit_every": 17},
    "50 steps, lr 0.1": {"iterations": 50, "refit_every": 17, "lr": 0.1},
    "30 steps, lr 0.1": {"iterations": 30, "refit_every": 10, "lr": 0.1},
    "lm": {"solver": "lm"},
    "lm, 24 sweeps": {"solver": "lm", "sweeps": 24, "sweep_refit_every": 6},
}


def _config(label: str) -> dict:
    """Config ``optimise`` with ``label``'s changes."""
    import yaml

    from freqbrdf.config import merge_config

    return merge_config(yaml.safe_load((REPO / "config" / "config.yaml").read_text())["optimise"], SETTINGS[label])


def table_job(env: str, label: str, results: Path, out: Path) -> dict:
    """One table job in this process: ``env``'s light table with ``label``'s settings, into ``out``."""
    from freqbrdf import layout
    from freqbrdf.estimate.light_table import TableSize, shadowed_light_table, write_light_table
    from freqbrdf.estimate.optimise.model import map_light
    from freqbrdf.util.io import read_exr

    config = _config(label)
    light = map_light(read_exr(layout.located(layout.ENVMAP, results, env=env)), config["lmax"], config["point_sources"])
    size = TableSize(**config["light_table"])
    write_light_table(out, shadowed_light_table(light, size.rows, size.rank, 2))
    return {}


def run_job(capture: str, label: str, results: Path, table: Path | None) -> dict:
    """One job in this process: estimate ``capture`` with ``label``'s settings (its map's table
    read from ``table``, if given); its MSE and phase times."""
    import numpy as np

    from freqbrdf import layout
    from freqbrdf.artefacts import Svbrdf, read_observations, read_svbrdf, write_svbrdf
    from freqbrdf.estimate.optimise.solve import estimate_capture
    from freqbrdf.sphere.brdf import TEXTURES
    from freqbrdf.util.io import read_exr

    imported = time.perf_counter()
    obj, env = capture.split("/")
    config = _config(label)
    obs = read_observations(layout.located(layout.OBSERVATIONS, results, object=obj, env=env, poses="gt"))
    envmap = read_exr(layout.located(layout.ENVMAP, results, env=env))
    start = time.perf_counter()
    fit = estimate_capture(obs, envmap, "freq", config, 2, light_table=table)
    params, curve = fit.params, fit.loss_curve
    estimated = time.perf_counter()
    with tempfile.TemporaryDirectory() as tmp:
        write_svbrdf(Path(tmp), Svbrdf.from_texels(obs.texels.resolution, obs.texels.texel, params, obs.observed))
    written = time.perf_counter()
    truth = read_svbrdf({g: layout.located(layout.OBJECT_TEXTURE, results, object=obj, texture=g) for g in TEXTURES})
    truth = truth.at_texels(obs.texels.texel)
    seen = obs.observed
    mse = {g: float(np.mean((np.asarray(params[g])[seen] - np.asarray(truth[g], dtype=np.float64)[seen]) ** 2))
           for g in TEXTURES}
    return {"mse": mse, "inputs_s": start - imported, "estimate_s": estimated - start,
            "write_s": written - estimated, "final_loss": float(curve[-1])}


def _run(*args: str) -> tuple[float, dict]:
    """This script in a fresh process with ``args``: its wall time and the JSON it prints last."""
    start = time.perf_counter()
    done = subprocess.run([sys.executable, __file__, *args], capture_output=True, text=True, check=False)
    seconds = time.perf_counter() - start
    if done.returncode:
        raise SystemExit(f"{' '.join(args)} failed:\n{done.stderr[-3000:]}")
    return seconds, json.loads(done.stdout.strip().splitlines()[-1])


def fit_table(env: str, label: str, results: Path, out: Path) -> float | None:
    """Fit ``env``'s light table with ``label``'s settings into ``out`` in a fresh process: its
    wall time, or None if the setting fits the light per texel (``light_table.rows`` 0)."""
    if not _config(label)["light_table"]["rows"]:
        return None
    return _run("--table-job", env, label, str(out), "--results", str(results))[0]


def measure(capture: str, label: str, results: Path, table: Path | None) -> dict:
    """Run one job in a fresh process (reading ``table``, if given); its wall time beside what it reports."""
    seconds, report = _run("--job", capture, label, "--results", str(results),
                           *(("--table", str(table)) if table is not None else ()))
    row = {"capture": capture, "setting": label, "seconds": round(seconds, 2)}
    row |= {k: round(v, 5) for k, v in report["mse"].items()}
    row["mean"] = round(sum(report["mse"].values()) / len(report["mse"]), 5)
    row |= {k: round(report[k], 2) for k in ("inputs_s", "estimate_s", "write_s")}
    return row


def main() -> None:
    parser = argparse.ArgumentParser(description=__doc__, formatter_class=argparse.RawDescriptionHelpFormatter)
    parser.add_argument("--captures", nargs="+", default=["sphere/studio"], help="object/env (gt poses)")
    parser.add_argument("--settings", nargs="+", choices=list(SETTINGS), default=list(SETTINGS))
    parser.add_argument("--results", type=Path, default=None, help="results directory (default: FREQBRDF_RESULTS or ./results)")
    parser.add_argument("--job", nargs=2, metavar=("CAPTURE", "SETTING"), help=argparse.SUPPRESS)
    parser.add_argument("--table-job", nargs=3, metavar=("ENV", "SETTING", "OUT"), help=argparse.SUPPRESS)
    parser.add_argument("--table", type=Path, default=None, help=argparse.SUPPRESS)
    parser.add_argument("--out", type=Path, default=OUT / "freq_front.tsv")
    args = parser.parse_args()
    from freqbrdf import layout

    results = args.results or Path(os.environ.get("FREQBRDF_RESULTS", REPO / layout.RESULTS))
    if args.job:
        print(json.dumps(run_job(*args.job, results, args.table)))
        return
    if args.table_job:
        env, label, out = args.table_job
        print(json.dumps(table_job(env, label, results, Path(out))))
        return
    import pandas as pd

    rows = []
    with tempfile.TemporaryDirectory() as tmp:
        # warm-up: numba compiles its kernels into its cache once, as a pipeline's first jobs do
        first_env = args.captures[0].split("/")[1]
        warm = fit_table(first_env, args.settings[0], results, Path(tmp) / "warm")
        measure(args.captures[0], args.settings[0], results, None if warm is None else Path(tmp) / "warm")
        for k, label in enumerate(args.settings):
            tables: dict[str, tuple[Path | None, float]] = {}
            per_capture = []
            for capture in args.captures:
                env = capture.split("/")[1]
                if env not in tables:
                    out = Path(tmp) / f"{k}_{env}"
                    seconds = fit_table(env, label, results, out)
                    tables[env] = (None, 0.0) if seconds is None else (out, round(seconds, 2))
                table, table_s = tables[env]
                per_capture.append(measure(capture, label, results, table) | {"table_s": table_s})
                print(per_capture[-1], flush=True)
            mean = pd.DataFrame(per_capture).drop(columns=["capture", "setting"]).mean().round(5).to_dict()
            rows += per_capture + [{"capture": "mean", "setting": label, **mean}]
    args.out.parent.mkdir(parents=True, exist_ok=True)
    pd.DataFrame(rows).to_csv(args.out, sep="\t", index=False)
    print(f"wrote {args.out}")


if __name__ == "__main__":
    main()
