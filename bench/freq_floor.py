"""Each phase of a ``freq`` job beside its hardware floor on the machine the bench runs on.

A phase's floor is the larger of its bytes over the measured read bandwidth (at a working set
of the phase's own size, so that a cache that holds it counts) and its fused multiply-adds over
the measured float32 FMA peak (a matrix product's); both are measured here. The phases are those
of rule ``optimise_svbrdf`` with config ``optimise`` (config/config.yaml), on a results
directory that has the capture's observations, its map and the map's light table:

- ``start-up``: a fresh interpreter importing what the rule's script imports;
- ``light``: the method's light and irradiance (`freqbrdf.estimate.optimise.model.estimate_light`);
- ``problem``: `build_problem` and `ForwardModel.of`;
- ``light terms``: one full evaluation of the shadowed light at every pair (from the table);
- ``grid start``: the (roughness x metallic) grid search;
- ``lane terms``: the light terms laid out for the objective's kernel (`freqbrdf.estimate.optimise.lanes`),
  after the first evaluation and each refit;
- ``objective``: one loss-and-gradient evaluation (the Adam loop makes ``iterations + 1`` of them);
- ``adam update``: one update of every parameter;
- ``posterior``: the Laplace variances (`texel_information`, `posterior_variance`).

Bytes and FMA counts are what each phase must touch and compute at least (formulas beside
each phase below), not what the code happens to do; a phase without a useful floor (start-up,
light, problem) shows its time only.

    python bench/freq_floor.py --captures sphere/sky sphere/lobby

Writes ``bench/out/freq_floor.tsv`` (one row per capture and phase). Time it on an otherwise
idle machine: the floors and the times are measured in the same run.
"""

from __future__ import annotations

import argparse
import os
import subprocess
import sys
import time
from pathlib import Path

import numba
import numpy as np

REPO = Path(__file__).resolve().parents[1]
OUT = REPO / "bench" / "out"
SCRIPT_IMPORTS = ("import numpy; from freqbrdf.artefacts import read_observations; "
                  "from freqbrdf.estimate.optimise.solve import estimate_capture; "
                  "from freqbrdf.util.io import read_exr; from freqbrdf.util.logs import run_script")


@numba.njit(parallel=True, fastmath=True)
def _read_sum(a):  # pragma: no cover - compiled
    total = np.float32(0.0)
    for i in numba.prange(a.shape[0]):
        total += a[i]
    return total


def _best(fn, repeats: int) -> float:
    """Least wall time of ``repeats`` calls of ``fn`` after one warm-up call, in seconds."""
    fn()
    times = []
    for _ in range(repeats):
        start = time.perf_counter()
        fn()
        times.append(time.perf_counter() - start)
    return min(times)


def read_bandwidth(nbytes: int, threads: int) -> float:
    """Read bandwidth (bytes/s) over a float32 array of ``nbytes``, re-read as a phase re-reads its data."""
    numba.set_num_threads(threads)
    a = np.ones(max(nbytes // 4, 1 << 16), np.float32)
    return a.nbytes / _best(lambda: _read_sum(a), 7)


def fma_peak() -> float:
    """float32 FMA per second of a 1024^3 matrix product (OpenBLAS's threads: one per core),
    the most this machine's cores were seen to sustain."""
    rng = np.random.default_rng(0)
    a, b = rng.random((1024, 1024), np.float32), rng.random((1024, 1024), np.float32)
    return 1024**3 / _best(lambda: a @ b, 5)


def start_up_seconds() -> float:
    """Least wall time of 3 fresh interpreters importing the rule script's imports (numba's cache warm)."""
    env = dict(os.environ, PYTHONPATH=str(REPO / "workflow"))
    times = []
    for _ in range(3):
        start = time.perf_counter()
        subprocess.run([sys.executable, "-c", SCRIPT_IMPORTS], check=True, env=env)
        times.append(time.perf_counter() - start)
    return min(times)


def phases(capture: str, results: Path, threads: int) -> list[dict]:
    """Time and floor inputs (bytes, FMA) of each phase of ``capture``'s ``freq`` job."""
    import yaml

    from freqbrdf import layout
    from freqbrdf.artefacts import read_observations
    from freqbrdf.estimate.light_table import read_light_table
    from freqbrdf.estimate.optimise.kernels import adam_update, texel_information
    from freqbrdf.estimate.optimise.model import ForwardModel, estimate_light
    from freqbrdf.estimate.optimise.posterior import posterior_variance
    from freqbrdf.estimate.optimise.problem import build_problem
    from freqbrdf.estimate.optimise.settings import OptimiseSettings
    from freqbrdf.util.io import read_exr
    from freqbrdf.util.threads import set_threads

    obj, env = capture.split("/")
    config = yaml.safe_load((REPO / "config" / "config.yaml").read_text())["optimise"]
    settings = OptimiseSettings.from_config(config, workers=threads)
    set_threads(threads)
    obs = read_observations(layout.located(layout.OBSERVATIONS, results, object=obj, env=env, poses="gt"))
    envmap = read_exr(layout.located(layout.ENVMAP, results, env=env))
    rows = []

    start = time.perf_counter()
    light, irradiance = estimate_light(envmap, obs, "freq", config["lmax"], config["point_sources"])
    rows.append({"phase": "light", "seconds": time.perf_counter() - start})
    table = read_light_table(layout.located(layout.LIGHT_TABLE, results, env=env), light, settings.light_table)
    start = time.perf_counter()
    model = ForwardModel.of(build_problem(obs, irradiance, settings.dtype), light, "freq", settings, table)
    rows.append({"phase": "problem", "seconds": time.perf_counter() - start})
    p = model.problem
    n, t, deg = p.n_pairs, p.n_observed, config["lmax"] + 1
    coeffs = deg * deg  # SH coefficients per channel
    sources = 0 if model.kernel.point is None else model.kernel.point[0].shape[1]
    terms_bytes = n * deg * 3 * np.dtype(settings.dtype).itemsize
    pair_bytes = n * (3 + 2) * np.dtype(settings.dtype).itemsize + n * sources * 3 * 4  # radiance, schlick, tan2, geometry
    texel_bytes = t * (5 + 3 + 5 + 1) * 8  # parameters, irradiance, gradient, loss

    roughness = np.full(p.n_texels, 0.5)
    terms = model.light_terms(roughness, threads)
    corners = table.weights(p.normal[:1], roughness[:1])[0].shape[1]
    rows.append({"phase": "light terms", "seconds": _best(lambda: model.light_terms(roughness, threads), 3),
                 # written once; per texel its corners x rank rows of 3 coeffs combined, per pair the SH
                 # at its mirror direction (~2 FMA a coefficient) and the 3-channel sums per degree
                 "bytes": terms_bytes + n * 3 * 8, "fma": t * corners * table.basis.rank * 3 * coeffs + n * 5 * coeffs})
    grid_r = np.linspace(0.0, 1.0, settings.grid_roughness)
    grid_m = np.linspace(0.0, 1.0, settings.grid_metallic)
    start_x = model.grid_start(terms, grid_r, grid_m, threads)
    rows.append({"phase": "grid start", "seconds": _best(lambda: model.grid_start(terms, grid_r, grid_m, threads), 3),
                 # every roughness: the lobe-filtered light (3 per degree) and the point sources; every
                 # metallic: the base colour's two sums and the L1 cost over 3 channels (~4 FMA each)
                 "bytes": terms_bytes + pair_bytes,
                 "fma": grid_r.size * n * (3 * deg + 10 * sources + grid_m.size * 3 * 4)})
    xp = np.ascontiguousarray(start_x[p.perm])
    lane_terms = model.lane_terms(terms)  # as the Adam loop reads them (None where the lanes do not apply)
    if lane_terms is not None:
        rows.append({"phase": "lane terms", "seconds": _best(lambda: model.lane_terms(terms, lane_terms), 3),
                     "bytes": 2 * terms_bytes, "fma": 0})  # read, and written in the lanes' order
    rows.append({"phase": "objective", "seconds": _best(lambda: model.objective(xp, terms, settings.tv_weight,
                                                                                 lane_terms), 10),
                 # the light's sums and their slopes (6 per degree), each source's term and slope (~20)
                 "bytes": terms_bytes + pair_bytes + texel_bytes, "fma": n * (6 * deg + 20 * sources)})
    grad = model.objective(xp, terms, settings.tv_weight)[1]
    m1, m2, x = np.zeros_like(xp), np.zeros_like(xp), xp.copy()
    floor = np.zeros(5)
    rows.append({"phase": "adam update", "bytes": 7 * xp.nbytes, "fma": 6 * xp.size,  # 4 arrays read, 3 written
                 "seconds": _best(lambda: adam_update(x, grad, m1, m2, 1, settings.lr, settings.betas, settings.eps,
                                                      floor), 10)})
    def posterior() -> None:
        curvature, squares = texel_information(xp[:t], terms, p.pair_data, model.kernel)
        posterior_variance(curvature, squares, np.diff(p.start), settings.variance_scale)

    rows.append({"phase": "posterior", "seconds": _best(posterior, 3),
                 # the objective's pass with each pair's 3 Jacobian rows' 15 products; 5 x 5 inverses
                 "bytes": terms_bytes + pair_bytes + t * 26 * 8, "fma": n * (6 * deg + 20 * sources + 3 * 15)})
    return rows


def with_floors(rows: list[dict], threads: int) -> list[dict]:
    """``rows`` with each phase's floor (s) and its time as a multiple of it, from bandwidth and FMA
    measured now at the phase's own working set."""
    peak = fma_peak()
    for row in rows:
        if "bytes" not in row:
            continue
        bandwidth = read_bandwidth(row["bytes"], threads)
        row["floor"] = max(row["bytes"] / bandwidth, row["fma"] / peak)
        row["multiple"] = row["seconds"] / row["floor"]
        row["GB_per_s"] = bandwidth / 1e9
        row["GFMA_per_s"] = peak / 1e9
    return rows


def main() -> None:
    parser = argparse.ArgumentParser(description=__doc__, formatter_class=argparse.RawDescriptionHelpFormatter)
    parser.add_argument("--captures", nargs="+", default=["sphere/sky", "sphere/lobby"], help="object/env (gt poses)")
    parser.add_argument("--results", type=Path, default=None, help="results directory (default: FREQBRDF_RESULTS or ./results)")
    parser.add_argument("--threads", type=int, default=2)
    parser.add_argument("--out", type=Path, default=OUT / "freq_floor.tsv")
    args = parser.parse_args()
    import pandas as pd

    from freqbrdf import layout

    results = args.results or Path(os.environ.get("FREQBRDF_RESULTS", REPO / layout.RESULTS))
    start_up = start_up_seconds()
    table = []
    for capture in args.captures:
        rows = [{"phase": "start-up", "seconds": start_up}] + phases(capture, results, args.threads)
        table += [{"capture": capture, **row} for row in with_floors(rows, args.threads)]
    frame = pd.DataFrame(table)
    frame["bytes"] = frame["bytes"] / 1e6
    frame = frame.rename(columns={"bytes": "MB", "fma": "FMA"})
    args.out.parent.mkdir(parents=True, exist_ok=True)
    frame.to_csv(args.out, sep="\t", index=False, float_format="%.4g")
    with pd.option_context("display.width", 200, "display.float_format", "{:.4g}".format):
        print(frame.to_string(index=False))
    print(f"wrote {args.out}")


if __name__ == "__main__":
    main()
