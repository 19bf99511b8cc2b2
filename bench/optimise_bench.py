"""Time, peak memory and accuracy of the gradient-descent estimator (freqbrdf.estimate.optimise).

Timing cases (each in a fresh Python process, so its peak RSS is its own),
named ``method[:changes]@threads`` (``freq@2threads``, ``freq:ggx@2threads``:
a method of the pipeline, what changes from the paper's settings, the
threads; no case name is a method's): `optimise` on 256x256 texels x 24
views with the paper's settings (`OptimiseSettings.paper`: 150 Adam
iterations, Gaussian lobe, Lambertian diffuse term, grid start), the light at
degree 20 (config ``optimise.lmax``), for ``freq`` (four fits of the shadowed
light: the grid start's, the first step's and two partial refits) and
``rh2001`` (one evaluation) with 2 and 1 threads, ``freq`` with the GGX lobe,
with it and the principled diffuse term, and by the ``lm`` solver (12 sweeps,
refits every 4). Issue 14's target: ``freq`` in at most 1 s on 2 cores.
Inputs are the real observations of sphere/studio (`freqbrdf.layout.OBSERVATIONS`,
gt poses) when they exist (read-only), else synthetic ones of the same shape.
Every input is read from the repository's results directory
(`freqbrdf.layout.RESULTS`), or ``FREQBRDF_RESULTS``.

Accuracy (needs the pipeline's results): parameter MSE against the
ground-truth textures (`freqbrdf.layout.OBJECT_TEXTURE`) over observed texels, for every method with the
paper's settings started from the grid (the preset's start), from 0.5 and
from the spectrum-only estimate, next to the spectrum-only estimate itself.

Sweep (``--sweep``): parameter MSE of ``freq`` for each setting of
`SWEEP` (the solvers included) on the given captures; run on the tuning set (config/tuning.yaml,
README "Tuning set"), never on the captures the default run reports.

    python bench/optimise_bench.py                          # timing + accuracy on sphere/studio
    python bench/optimise_bench.py --captures sphere/studio torus/sunny
    python bench/optimise_bench.py --no-accuracy
    python bench/optimise_bench.py --sweep --captures die/museum die/overcast vase/museum vase/overcast
    FREQBRDF_RESULTS=/path/to/clone/results python bench/optimise_bench.py --sweep ...  # results elsewhere

Writes ``bench/out/optimise.tsv`` (timing), ``bench/out/optimise_accuracy.tsv``
and ``bench/out/optimise_sweep.tsv``.
Time is one run after a warm-up run in the same process; "traced" memory is
the tracemalloc peak of the ``optimise`` call (numpy reports its buffers),
"max RSS" the peak resident size of the whole process (interpreter, numpy and
the loaded inputs included).
"""

from __future__ import annotations

import argparse
import functools
import json
import os
import resource
import subprocess
import sys
import time
import tracemalloc
from pathlib import Path

import numpy as np

from freqbrdf import layout
from freqbrdf.estimate.light_table import TableSize
from freqbrdf.sphere.brdf import TEXTURES
from freqbrdf.methods import METHODS

REPO = Path(__file__).resolve().parents[1]
OUT = REPO / "bench" / "out"
RESULTS = Path(os.environ.get("FREQBRDF_RESULTS", REPO / layout.RESULTS))  # e.g. a clone that ran the tuning preset
TIMING_CAPTURE = "sphere/studio"
TIMING_CASES = {
    # name (method[:changes]@threads, not a method's name): (method, workers, OptimiseSettings.paper overrides)
    "freq@2threads": ("freq", 2, {}),
    "freq:ggx@2threads": ("freq", 2, {"lobe": "ggx"}),
    "freq:ggx,principled@2threads": ("freq", 2, {"lobe": "ggx", "diffuse": "principled"}),
    "freq:lm@2threads": ("freq", 2, {"solver": "lm"}),
    "rh2001@2threads": ("rh2001", 2, {}),
    "freq@1thread": ("freq", 1, {}),
}
ACCURACY_METHODS = tuple(m for m, entry in METHODS.items() if "table4" in entry.paper_rows)  # the ablation
LMAX = 20


@functools.cache
def _config_optimise() -> dict:
    """config/config.yaml's ``optimise`` section, read once."""
    import yaml

    return yaml.safe_load((REPO / "config" / "config.yaml").read_text())["optimise"]


def config_setting(**changes: object) -> dict:
    """The estimator of config/config.yaml (its ``optimise`` section) as overrides of the paper's
    settings, with ``changes``: the sweep's baseline since the tuning set went to captured light
    (labels "config, ..." are relative to the config of the day; the tuning log records the values)."""
    optimise = _config_optimise()
    keys = ("lr", "tv_weight", "lobe", "diffuse", "view_weight", "iterations", "refit_every", "point_sources")
    return {key: optimise[key] for key in keys} | {"light_table": TableSize(**optimise["light_table"])} | changes


# label: overrides of the paper's settings (OptimiseSettings.paper: lr 0.02, TV weight 1e-3, 150 iterations,
# refits every 50) in a sweep run; the rows "config, ..." change config/config.yaml's estimator (config_setting)
SWEEP = {
    "default": {},
    "lr 0.01": {"lr": 0.01},
    "lr 0.05": {"lr": 0.05},
    "tv 0": {"tv_weight": 0.0},
    "tv 0.01": {"tv_weight": 0.01},
    "start 0.5": {"grid_start": False},
    "min_roughness 0.2": {"min_roughness": 0.2},
    "min_roughness auto (0.287)": {"min_roughness": 0.287},
    "lmax 16": {"lmax": 16},
    "lr 0.05, tv 0.01": {"lr": 0.05, "tv_weight": 0.01},
    "lr 0.05, tv 0.03": {"lr": 0.05, "tv_weight": 0.03},
    "lr 0.05, tv 0.1": {"lr": 0.05, "tv_weight": 0.1},
    "lr 0.05, tv 0.03, min_roughness auto": {"lr": 0.05, "tv_weight": 0.03, "min_roughness": 0.287},
    "lr 0.05, tv 0.03, start 0.5": {"lr": 0.05, "tv_weight": 0.03, "grid_start": False},
    "lm, tv 0.03": {"solver": "lm", "tv_weight": 0.03},
    "lm 20 sweeps, tv 0.03": {"solver": "lm", "tv_weight": 0.03, "sweeps": 20, "sweep_refit_every": 5},
    "lm, tv 0.1": {"solver": "lm", "tv_weight": 0.1},
    "lr 0.05, tv 0.03, ggx lobe": {"lr": 0.05, "tv_weight": 0.03, "lobe": "ggx"},
    "lr 0.05, tv 0.01, ggx lobe": {"lr": 0.05, "tv_weight": 0.01, "lobe": "ggx"},
    "lr 0.02, tv 0.03, ggx lobe": {"lr": 0.02, "tv_weight": 0.03, "lobe": "ggx"},
    "lr 0.05, tv 0.03, ggx lobe, lmax 24": {"lr": 0.05, "tv_weight": 0.03, "lobe": "ggx", "lmax": 24},
    "lr 0.05, tv 0.03, ggx lobe, lmax 28": {"lr": 0.05, "tv_weight": 0.03, "lobe": "ggx", "lmax": 28},
    "lr 0.05, tv 0.03, ggx lobe, principled": {"lr": 0.05, "tv_weight": 0.03, "lobe": "ggx", "diffuse": "principled"},
    "lr 0.05, tv 0.01, ggx lobe, principled": {"lr": 0.05, "tv_weight": 0.01, "lobe": "ggx", "diffuse": "principled"},
    "lr 0.02, tv 0.03, ggx lobe, principled": {"lr": 0.02, "tv_weight": 0.03, "lobe": "ggx", "diffuse": "principled"},
    "lr 0.05, tv 0.1, ggx lobe, principled": {"lr": 0.05, "tv_weight": 0.1, "lobe": "ggx", "diffuse": "principled"},
    "lr 0.05, tv 0.03, ggx lobe, principled, lmax 24": {"lr": 0.05, "tv_weight": 0.03, "lobe": "ggx",
                                                         "diffuse": "principled", "lmax": 24},
    "lr 0.05, tv 0.03, ggx lobe, albedo": {"lr": 0.05, "tv_weight": 0.03, "lobe": "ggx", "view_weight": "albedo"},
    **{f"lr 0.05, tv 0.03, ggx lobe, principled, point sources {r:g} deg": {
        "lr": 0.05, "tv_weight": 0.03, "lobe": "ggx", "diffuse": "principled",
        "point_sources": {"max_radius_deg": r, "min_radiance": 20.0}} for r in (2.0, 3.0, 5.0)},
    "lr 0.05, tv 0.03, ggx lobe, albedo, principled": {"lr": 0.05, "tv_weight": 0.03, "lobe": "ggx",
                                                       "view_weight": "albedo", "diffuse": "principled"},
    "config": config_setting(),
    **{f"config, point sources {r:g} deg, {m:g}x": config_setting(point_sources={"max_radius_deg": r, "min_radiance": m})
       for r, m in ((0.0, 20.0), (1.0, 20.0), (2.0, 20.0), (2.0, 50.0), (2.0, 100.0), (2.0, 200.0), (2.0, 300.0))},
    **{f"config, tv {w:g}": config_setting(tv_weight=w) for w in (0.01, 0.03, 0.1, 0.2)},
    "config, lr 0.02": config_setting(lr=0.02),
    "config, lr 0.1": config_setting(lr=0.1),
    "config, light per texel": config_setting(light_table=TableSize(rows=0, rank=4)),
    "config, gaussian lobe": config_setting(lobe="gaussian"),
    "config, lambert": config_setting(diffuse="lambert"),
    **{f"config, lm, tv {w:g}": config_setting(solver="lm", tv_weight=w) for w in (0.05, 0.1, 0.2, 0.4)},
    "config, lm 24 sweeps, tv 0.2": config_setting(solver="lm", tv_weight=0.2, sweeps=24, sweep_refit_every=6),
}


def load_capture(capture: str) -> dict | None:
    """Observations and irradiance of ``object/env`` (gt poses), or None if absent."""
    from freqbrdf.artefacts import read_observations
    from freqbrdf.util.io import read_exr
    from freqbrdf.estimate.light import irradiance

    obj, env = capture.split("/")
    directory = layout.located(layout.OBSERVATIONS, RESULTS, object=obj, env=env, poses="gt")
    envmap = layout.located(layout.ENVMAP, RESULTS, env=env)
    if not ((directory / "views.json").is_file() and envmap.is_file()):
        return None
    obs = read_observations(directory)
    data = {"obs": obs, "weight": obs.weight, "texel": obs.texels.texel, "envmap": read_exr(envmap)}
    data["irradiance"] = irradiance(data["envmap"], obs.texels.normal)
    data["source"] = layout.fill(layout.OBSERVATIONS, object=obj, env=env, poses="gt")
    return data


def synthetic_capture(n_side: int = 256, n_views: int = 24, seed: int = 0) -> dict:
    """Observations shaped like the real ones: random normals, 24 distant cameras on the
    upper hemisphere, a pair observed when the texel faces the camera (10% dropped as occluded),
    a few soft lamps over a sky gradient, radiance of a diffuse plus a glossy lobe."""
    from freqbrdf.sphere import sampling
    from freqbrdf.estimate import shfit
    from freqbrdf.artefacts import Observations

    rng = np.random.default_rng(seed)
    n_tex = n_side * n_side
    normal = rng.normal(size=(n_tex, 3))
    normal /= np.linalg.norm(normal, axis=1, keepdims=True)
    helper = np.where(np.abs(normal[:, 1:2]) < 0.9, [[0.0, 1.0, 0.0]], [[1.0, 0.0, 0.0]])
    tangent = np.cross(helper, normal)
    tangent /= np.linalg.norm(tangent, axis=1, keepdims=True)
    frame = np.stack([tangent, np.cross(normal, tangent), normal], axis=1)
    wo = np.einsum("tij,kj->tki", frame, sampling.fibonacci_hemisphere(n_views))
    weight = np.clip(wo[..., 2], 0.0, None) * (rng.random((n_tex, n_views)) > 0.1)
    wr = np.einsum("tji,tkj->tki", frame, shfit.mirror_directions(wo))
    lamps = rng.normal(size=(4, 3))
    lamps /= np.linalg.norm(lamps, axis=1, keepdims=True)
    colours = rng.uniform(1, 5, (4, 3))

    def light(d: np.ndarray) -> np.ndarray:
        return 0.3 + 0.2 * d[..., 1:2] + np.exp((d @ lamps.T - 1.0) / 0.05) @ colours

    from freqbrdf.estimate.light import irradiance

    env = light(sampling.equirect_directions(128, 256))
    kd = rng.uniform(0, 1, (n_tex, 1, 3))
    radiance = (0.5 * kd + 0.3 * light(wr)) * (weight > 0)[..., None]
    f32 = np.float32
    obs = Observations.from_arrays(radiance.astype(f32), weight.astype(f32), wo.astype(f32), frame, np.arange(n_tex),
                                   n_side)
    return {"obs": obs, "weight": obs.weight, "texel": obs.texels.texel, "envmap": env,
            "irradiance": irradiance(env, normal), "source": "synthetic"}


def optimise_capture(data: dict, method: str, init: dict | None, lmax: int = LMAX, point_sources: dict | None = None,
                     **settings) -> tuple[dict, np.ndarray]:
    """`optimise` on a loaded capture with the paper's settings changed by ``settings``, its light as
    the rule builds it (`model_light`)."""
    from freqbrdf.estimate.optimise.model import model_light
    from freqbrdf.estimate.optimise.settings import OptimiseSettings
    from freqbrdf.estimate.optimise.solve import optimise

    light = model_light(data["envmap"], data["obs"], method, lmax, point_sources)
    fit = optimise(data["obs"], data["irradiance"], light, init, method, settings=OptimiseSettings.paper(**settings))
    return fit.params, fit.loss_curve


def run_timing(name: str) -> dict:
    """Run one timing case in this process; return its measurements."""
    method, workers, overrides = TIMING_CASES[name]
    data = load_capture(TIMING_CAPTURE) or synthetic_capture()
    settings = {"workers": workers, "iterations": 150} | overrides
    optimise_capture(data, method, None, **settings)  # warm-up (imports, first page faults)
    start = time.perf_counter()
    _, curve = optimise_capture(data, method, None, **settings)
    seconds = time.perf_counter() - start
    tracemalloc.start()
    optimise_capture(data, method, None, **settings)
    _, traced_peak = tracemalloc.get_traced_memory()
    tracemalloc.stop()
    n_tex, n_views = data["weight"].shape
    return {
        "case": name,
        "method": method,
        "solver": settings.get("solver", "adam"),
        "workers": workers,
        "texels": n_tex,
        "views": n_views,
        "observed_pairs": int((data["weight"] > 0).sum()),
        "steps": len(curve),
        "lmax": LMAX,
        "inputs": data["source"],
        "seconds": round(seconds, 2),
        "traced_peak_mb": round(traced_peak / 2**20, 1),
        "max_rss_mb": round(resource.getrusage(resource.RUSAGE_SELF).ru_maxrss / 1024, 1),
        "final_loss": round(float(curve[-1]), 5),
    }


def truth_textures(obj: str) -> dict[str, Path]:
    """The ground truth's texture files of ``obj``."""
    return {g: layout.located(layout.OBJECT_TEXTURE, RESULTS, object=obj, texture=g) for g in TEXTURES}


def estimate_textures(capture: str, method: str) -> dict[str, Path]:
    """The texture files of ``method``'s estimate of ``object/env`` (gt poses)."""
    obj, env = capture.split("/")
    directory = layout.located(layout.ESTIMATE, RESULTS, object=obj, env=env, poses="gt", method=method)
    return {g: directory / f"{g}.exr" for g in TEXTURES}


def read_textures(paths: dict[str, Path]) -> dict[str, np.ndarray] | None:
    """``base_color`` (R*R, 3), ``roughness``, ``metallic`` (R*R,) of texture files, flat ``i * R + j``
    (None when one is missing)."""
    from freqbrdf.artefacts import read_svbrdf

    if not all(paths[g].is_file() for g in TEXTURES):
        return None
    svbrdf = read_svbrdf(paths)
    return {g: v.astype(np.float64) for g, v in svbrdf.at_texels(np.arange(svbrdf.resolution**2)).items()}


def mse_row(label: str, capture: str, est: dict, truth: dict, observed: np.ndarray, seconds: float | str) -> dict:
    row = {"capture": capture, "estimate": label}
    for g in TEXTURES:
        row[g] = float(np.mean((est[g][observed] - truth[g][observed]) ** 2))
    row["mean"] = float(np.mean([row[g] for g in TEXTURES]))
    row = {k: (round(v, 4) if isinstance(v, float) else v) for k, v in row.items()}
    row["seconds"] = seconds
    return row


def run_accuracy(capture: str) -> list[dict]:
    """MSE of every method (init 0.5 and init spectrum) and of the spectrum-only estimate."""
    data = load_capture(capture)
    gt = read_textures(truth_textures(capture.split("/")[0]))
    if data is None or gt is None:
        print(f"{capture}: observations or ground truth missing, accuracy skipped")
        return []
    texel = data["texel"]
    observed = (data["weight"] > 0).any(axis=1)
    truth = {g: v[texel] for g, v in gt.items()}
    rows = []
    spectrum = read_textures(estimate_textures(capture, "spectrum"))
    inits: dict[str, dict | None] = {"grid": None, "0.5": "constant"}
    if spectrum is not None:
        spectrum = {g: np.clip(v[texel], 0.0, 1.0) for g, v in spectrum.items()}
        rows.append(mse_row("spectrum", capture, spectrum, truth, observed, ""))
        inits["spectrum"] = spectrum
    for method in ACCURACY_METHODS:
        for init_name, init in inits.items():
            start = time.perf_counter()
            start_kw = {"grid_start": False} if init == "constant" else {}
            est, _ = optimise_capture(data, method, None if init == "constant" else init, workers=2, **start_kw)
            rows.append(mse_row(f"{method} (init {init_name})", capture, est, truth, observed,
                                round(time.perf_counter() - start, 2)))
            print(rows[-1], flush=True)
    return rows


def run_sweep(captures: list[str], labels: list[str] | None = None) -> list[dict]:
    """Parameter MSE of freq for every setting of SWEEP (or those named), per capture and averaged."""
    rows = []
    loaded = {}
    for capture in captures:
        obj = capture.split("/")[0]
        data, gt = load_capture(capture), read_textures(truth_textures(obj))
        if data is None or gt is None:
            raise SystemExit(f"{capture}: observations or ground truth missing; run the tuning preset first")
        loaded[capture] = (data, {g: v[data["texel"]] for g, v in gt.items()}, (data["weight"] > 0).any(axis=1))
    for label, overrides in SWEEP.items():
        if labels and label not in labels:
            continue
        per_capture = []
        for capture, (data, truth, observed) in loaded.items():
            start = time.perf_counter()
            est, _ = optimise_capture(data, "freq", None, workers=2, **overrides)
            per_capture.append(mse_row(label, capture, est, truth, observed, round(time.perf_counter() - start, 2)))
            print(per_capture[-1], flush=True)
        mean = {g: round(float(np.mean([r[g] for r in per_capture])), 4) for g in (*TEXTURES, "mean")}
        rows += per_capture + [{"capture": "mean", "estimate": label, **mean,
                                "seconds": round(sum(r["seconds"] for r in per_capture), 2)}]
    return rows


def write_table(rows: list[dict], path: Path) -> None:
    columns = list(rows[0])
    lines = ["\t".join(columns)] + ["\t".join(str(r[c]) for c in columns) for r in rows]
    path.write_text("\n".join(lines) + "\n")
    widths = [max(len(c), *(len(str(r[c])) for r in rows)) for c in columns]
    for line in lines:
        print("  ".join(cell.ljust(w) for cell, w in zip(line.split("\t"), widths)))
    print(f"\nwritten {path}\n")


def main() -> None:
    parser = argparse.ArgumentParser(description=__doc__.splitlines()[0])
    parser.add_argument("--case", help=argparse.SUPPRESS)  # internal: run one timing case, print JSON
    parser.add_argument("--captures", nargs="+", default=[TIMING_CAPTURE], help="object/env pairs for accuracy")
    parser.add_argument("--no-accuracy", action="store_true", help="timing only")
    parser.add_argument("--no-timing", action="store_true", help="accuracy only")
    parser.add_argument("--sweep", action="store_true", help="only the settings sweep of freq on --captures")
    parser.add_argument("--settings", nargs="+", help="sweep only these labels of SWEEP")
    args = parser.parse_args()
    if args.case:
        print(json.dumps(run_timing(args.case)))
        return
    OUT.mkdir(parents=True, exist_ok=True)
    if args.sweep:
        write_table(run_sweep(args.captures, args.settings), OUT / "optimise_sweep.tsv")
        return
    if not args.no_timing:
        rows = []
        for name in TIMING_CASES:
            out = subprocess.run([sys.executable, __file__, "--case", name], check=True, capture_output=True, text=True)
            rows.append(json.loads(out.stdout.strip().splitlines()[-1]))
        write_table(rows, OUT / "optimise.tsv")
    if not args.no_accuracy:
        rows = [row for capture in args.captures for row in run_accuracy(capture)]
        if rows:
            write_table(rows, OUT / "optimise_accuracy.tsv")


if __name__ == "__main__":
    main()
