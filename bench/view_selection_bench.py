"""Time of the entropy-guided view ranking (freqbrdf.studies.view_selection) on a real capture.

Cases, on the observations of OBJECT/ENV (`freqbrdf.layout.OBSERVATIONS`, gt
poses, under the results directory ``--results``, default the repository's
`freqbrdf.layout.RESULTS`; its 24 views with images give the posterior) and
the default 100 candidate poses of rule ``view_selection`` (a Fibonacci
hemisphere rotated by 7 degrees), with the config's ``sh``, ``spectrum`` and
``view_selection`` settings:

- ``geometry``: which sampled texels each candidate sees (projection, facing, a
  Mitsuba ray cast per pair) and the light along the mirror directions;
- ``rank_100``: one ranking of the 100 candidates (the expected decrease of the
  mean entropy for each), per texel count;
- ``greedy_8``: greedy selection of 8 of them (9 rankings, each after the first
  re-evaluating only the texels the last pick sees).

    python bench/view_selection_bench.py [--results DIR] [--object sphere --env studio]

Writes ``bench/out/view_selection.tsv``: seconds (one run after a warm-up that
compiles the kernel), threads, texels, candidates, and the machine's 1-minute
load average when the case ran (the machine is shared: a load above the core
count slows every case).
"""

from __future__ import annotations

import argparse
import functools
import os
import time
from pathlib import Path

import numpy as np
import pandas as pd
import yaml

from freqbrdf import layout
from freqbrdf.artefacts import read_observations, sample_texels
from freqbrdf.scene.cameras import rig_cameras
from freqbrdf.util.io import read_exr
from freqbrdf.util.mitsuba_setup import setup_mitsuba
from freqbrdf.capture.observations import band_limit_parameter, band_limited_envmap
from freqbrdf.scene.raycast import mesh_scene, occlusion_test
from freqbrdf.studies.view_selection import (
    SelectionModel,
    greedy_selection,
    rank_views,
    set_threads,
)
from freqbrdf.studies.candidates import capture_and_candidates

REPO = Path(__file__).resolve().parents[1]
OUT = REPO / "bench" / "out"


def main() -> None:
    parser = argparse.ArgumentParser(description=__doc__.splitlines()[0])
    parser.add_argument("--results", type=Path, default=REPO / layout.RESULTS, help="the results directory")
    parser.add_argument("--object", default="sphere")
    parser.add_argument("--env", default="studio")
    parser.add_argument("--texels", type=int, nargs="+", default=[1024, 2048, 4096])
    parser.add_argument("--threads", type=int, default=2)
    args = parser.parse_args()
    config = yaml.safe_load((REPO / "config" / "config.yaml").read_text())
    settings, render = config["view_selection"], config["render"]
    mi = setup_mitsuba(threads=args.threads)
    set_threads(args.threads)
    capture = {"object": args.object, "env": args.env, "poses": "gt"}
    obs = read_observations(layout.located(layout.OBSERVATIONS, args.results, **capture))
    envmap = read_exr(layout.located(layout.ENVMAP, args.results, env=args.env))
    cameras = rig_cameras(settings["candidates"], render["resolution"], render["fov_deg"], render["camera_distance"],
                          azimuth_deg=settings["candidate_azimuth_deg"], prefix="candidate_")
    n_capture = len(obs.meta["views"])
    a_prime = band_limit_parameter(n_capture + settings["select"], config["observations"]["band_limit"])
    incoming_map = band_limited_envmap(envmap, a_prime)
    mesh = layout.located(layout.OBJECT_MESH, args.results, object=args.object)
    occluded = functools.partial(occlusion_test, mi, mesh_scene(mi, mesh))
    model = SelectionModel.from_config(config["sh"], config["spectrum"], a_prime, settings["posterior_min_views"])
    rows = []

    def record(case: str, texels: int, seconds: float) -> None:
        rows.append({"case": case, "object": args.object, "env": args.env, "texels": texels,
                     "candidates": len(cameras), "capture_views": n_capture, "threads": args.threads,
                     "seconds": round(seconds, 3), "load_1min": round(os.getloadavg()[0], 2)})
        print(rows[-1], flush=True)

    for n in args.texels:
        texels = sample_texels(np.arange(len(obs.texels)), n, seed=0)
        start = time.perf_counter()
        views = capture_and_candidates(obs, texels, cameras, incoming_map, occluded,
                                       config["observations"]["ray_offset"])
        record("geometry", n, time.perf_counter() - start)
        rank_views(model, views, range(n_capture))  # warm-up: compiles (or loads) the kernel
        start = time.perf_counter()
        rank_views(model, views, range(n_capture))
        record("rank_100", n, time.perf_counter() - start)
        start = time.perf_counter()
        greedy_selection(model, views, settings["select"], chosen=range(n_capture))
        record(f"greedy_{settings['select']}", n, time.perf_counter() - start)
    OUT.mkdir(parents=True, exist_ok=True)
    pd.DataFrame(rows).to_csv(OUT / "view_selection.tsv", sep="\t", index=False)


if __name__ == "__main__":
    main()
