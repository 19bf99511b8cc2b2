"""Time and peak memory of the frequency-domain stage (freqbrdf.estimate.shfit, freqbrdf.estimate.spectrum).

Cases (each runs in a fresh Python process so its peak RSS is its own):

- ``search``: spectrum-only grid search + entropy for 512x512 texels, RGB,
  an 8x8 (K_s, alpha) grid, lmax 6 (target < 1 s on 2 cores);
- ``fit``: SH fits of 256x256 texels x 24 observations at lmax 6, B and L
  (and the unit-DC channel of `diffuse_albedo`) in one call, since they share
  directions and weights (target < 10 s); with the K x K (dual, default) and
  n x n (primal) solvers, and with an unpenalised DC.

Inputs are synthetic but shaped like real observations: texel normals spread
over the sphere, 24 distant cameras on a Fibonacci upper hemisphere, a view
observes a texel when it faces it (and 10% of those pairs are dropped as
occluded), weights cos(theta_o), light from a few soft lamps over a sky
gradient, radiance from a diffuse plus a mirror-like lobe.

    python bench/spectral_bench.py          # all cases; writes bench/out/spectral.tsv

Time is the median of 3 runs (after one warm-up); "traced" memory is the
tracemalloc peak of one run (numpy reports its buffers), "max RSS" the peak
resident size of the whole process (interpreter, numpy and the inputs included).
"""

from __future__ import annotations

import json
import resource
import subprocess
import sys
import time
import tracemalloc
from pathlib import Path

import numpy as np

REPO = Path(__file__).resolve().parents[1]
OUT = REPO / "bench" / "out"
LMAX = 6
RUNS = 3
CASES = {
    # name: (kind, workers, solver, penalise_dc)
    "search_w1": ("search", 1, "", True),
    "search_w2": ("search", 2, "", True),
    "fit_w1": ("fit", 1, "auto", True),
    "fit_w2": ("fit", 2, "auto", True),
    "fit_w2_primal": ("fit", 2, "primal", True),
    "fit_w2_free_dc": ("fit", 2, "auto", False),
}


def observations(n_tex: int, n_views: int, seed: int = 0) -> tuple[np.ndarray, ...]:
    """Synthetic (wo_local, weight, radiance, incoming) shaped like the observation stage's."""
    from freqbrdf.sphere import sampling
    from freqbrdf.estimate import shfit

    rng = np.random.default_rng(seed)
    normal = rng.normal(size=(n_tex, 3))
    normal /= np.linalg.norm(normal, axis=1, keepdims=True)
    helper = np.where(np.abs(normal[:, 1:2]) < 0.9, [[0.0, 1.0, 0.0]], [[1.0, 0.0, 0.0]])
    tangent = np.cross(helper, normal)
    tangent /= np.linalg.norm(tangent, axis=1, keepdims=True)
    frame = np.stack([tangent, np.cross(normal, tangent), normal], axis=1)  # (T, 3, 3) rows = local axes
    cameras = sampling.fibonacci_hemisphere(n_views)  # distant cameras, world +Y up
    wo_local = np.einsum("tij,kj->tki", frame, cameras)
    weight = np.clip(wo_local[..., 2], 0.0, None) * (rng.random((n_tex, n_views)) > 0.1)
    wr_world = np.einsum("tji,tkj->tki", frame, shfit.mirror_directions(wo_local))
    lamps = rng.normal(size=(4, 3))
    lamps /= np.linalg.norm(lamps, axis=1, keepdims=True)
    incoming = 0.3 + 0.2 * wr_world[..., 1:2] + np.einsum(
        "tkl,lc->tkc", np.exp((wr_world @ lamps.T - 1.0) / 0.05), rng.uniform(1, 5, (4, 3))
    )
    kd = rng.uniform(0, 1, (n_tex, 1, 3))
    ks = rng.uniform(0, 1, (n_tex, 1, 1))
    radiance = (kd * 0.5 + ks * incoming) * (weight > 0)[..., None]
    f32 = np.float32
    return wo_local.astype(f32), weight.astype(f32), radiance.astype(f32), incoming.astype(f32)


def spectra_inputs(n_tex: int, seed: int = 0) -> tuple[np.ndarray, np.ndarray]:
    """Synthetic (S_B, S_L), (T, LMAX+1, 3) float32: model spectra with 5% noise."""
    rng = np.random.default_rng(seed)
    l = np.arange(LMAX + 1)
    s_l = rng.uniform(0.1, 2.0, (n_tex, 1, 3)) * np.exp(-rng.uniform(0.1, 1.0, (n_tex, 1, 1)) * l[:, None])
    ks = rng.uniform(0, 1, (n_tex, 1, 3))
    alpha = rng.uniform(0, 1, (n_tex, 1, 1))
    s_b = ks**2 * np.exp(-2 * (alpha * l[:, None]) ** 2) * s_l * (1 + 0.05 * rng.normal(size=s_l.shape))
    return s_b.astype(np.float32), s_l.astype(np.float32)


def run_case(name: str) -> dict:
    """Run one case in this process; return its measurements."""
    from freqbrdf.estimate import shfit, spectrum

    kind, workers, solver, penalise_dc = CASES[name]
    if kind == "search":
        n_tex = 512 * 512
        s_b, s_l = spectra_inputs(n_tex)
        grid = spectrum.default_grid(8, 8, 24**-0.5)

        def work() -> None:
            spectrum.spectrum_search(s_b, s_l, *grid, workers=workers)

        row = {"texels": n_tex, "views": "", "grid": "8x8", "target_s": 1.0}
    else:
        n_tex, n_views = 256 * 256, 24
        wo, weight, radiance, incoming = observations(n_tex, n_views)
        values = np.concatenate([radiance, incoming, np.ones_like(radiance[..., :1])], axis=-1)
        directions = shfit.mirror_directions(wo)

        def work() -> None:
            shfit.fit_sh(
                directions, values, weight, LMAX, "exp", 1e-3, solver=solver, workers=workers, penalise_dc=penalise_dc
            )

        row = {"texels": n_tex, "views": n_views, "grid": "", "target_s": 10.0}
    work()  # warm-up (imports, page faults of first buffers)
    times = []
    for _ in range(RUNS):
        t0 = time.perf_counter()
        work()
        times.append(time.perf_counter() - t0)
    tracemalloc.start()
    work()
    _, traced_peak = tracemalloc.get_traced_memory()
    tracemalloc.stop()
    rss_kb = resource.getrusage(resource.RUSAGE_SELF).ru_maxrss  # KiB on Linux
    return {
        "case": name,
        "kind": kind,
        **row,
        "lmax": LMAX,
        "workers": workers,
        "solver": solver,
        "penalise_dc": penalise_dc if kind == "fit" else "",
        "seconds": round(float(np.median(times)), 3),
        "seconds_min": round(min(times), 3),
        "traced_peak_mb": round(traced_peak / 2**20, 1),
        "max_rss_mb": round(rss_kb / 1024, 1),
    }


def main() -> None:
    if len(sys.argv) == 3 and sys.argv[1] == "--case":
        print(json.dumps(run_case(sys.argv[2])))
        return
    rows = []
    for name in CASES:
        out = subprocess.run([sys.executable, __file__, "--case", name], check=True, capture_output=True, text=True)
        rows.append(json.loads(out.stdout.strip().splitlines()[-1]))
    columns = list(rows[0])
    OUT.mkdir(parents=True, exist_ok=True)
    lines = ["\t".join(columns)] + ["\t".join(str(r[c]) for c in columns) for r in rows]
    (OUT / "spectral.tsv").write_text("\n".join(lines) + "\n")
    widths = [max(len(c), *(len(str(r[c])) for r in rows)) for c in columns]
    for line in lines:
        print("  ".join(cell.ljust(w) for cell, w in zip(line.split("\t"), widths)))
    print(f"\nwritten {OUT / 'spectral.tsv'}")


if __name__ == "__main__":
    main()
