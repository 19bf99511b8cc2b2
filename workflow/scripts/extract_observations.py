"""Rule extract_observations: per-texel radiance, directions and incoming light of one capture."""

import os

# One OpenBLAS thread, set before NumPy loads it: the matrix products here are
# tiny, and OpenBLAS's idle threads spin on the job's cores while Dr.Jit traces
# rays (and vice versa), which made the distance maps 10x slower (1.3 s instead
# of 0.13 s at 256^2 x 24 views on 2 cores). Results do not depend on it.
os.environ.setdefault("OPENBLAS_NUM_THREADS", "1")

import functools
import time
from pathlib import Path

import numpy as np

from freqbrdf.artefacts import ObservationsWriter
from freqbrdf.scene.cameras import cameras_from_json
from freqbrdf.util.io import atomic_directory, read_exr, read_json, read_views
from freqbrdf.util.logs import progress, run_script
from freqbrdf.scene.ply import read_ply
from freqbrdf.util.mitsuba_setup import setup_mitsuba
from freqbrdf.capture.exchange import capture_source
from freqbrdf.capture.kernels import set_threads as set_kernel_threads
from freqbrdf.capture.observations import (
    band_limit_parameter,
    band_limited_envmap,
    edge_free_distances,
    observe,
    rasterise_uv,
)
from freqbrdf.capture.view_usability import check_views, nonfinite_views
from freqbrdf.util.previews import coverage_figure
from freqbrdf.scene.raycast import distance_maps, mesh_scene, occlusion_test


def main(smk, log):
    mi = setup_mitsuba(smk.params.variant, smk.threads)
    set_kernel_threads(smk.threads)
    settings = smk.params.settings
    with atomic_directory(smk.output[0]) as tmp:
        _extract(mi, smk, log, settings, tmp)


def _extract(mi, smk, log, settings, tmp):
    start = time.perf_counter()
    cameras_file = Path(smk.input.poses) / "cameras.json"
    cameras = cameras_from_json(read_json(cameras_file), source=cameras_file)
    images, coverage, nonfinite_pixels = read_views(smk.input.capture, cameras.names, cameras.width, cameras.height)
    # Messages name the capture as the user gave it: an import's transforms file and frames.
    source, labels = capture_source(smk.input.capture, cameras.names)
    if nonfinite_pixels:
        log.warning("%s: NaN/Inf pixels, masked and never observed, in %s", source, nonfinite_views(labels, images))
    texels = rasterise_uv(read_ply(smk.input.mesh), smk.params.resolution, settings["dilate_texels"])
    log.info("%d valid texels (%d by dilation), %d views, loaded in %.1f s",
             len(texels), texels.dilated.sum(), len(cameras), time.perf_counter() - start)

    a_prime = band_limit_parameter(len(cameras), settings["band_limit"])
    incoming_map = band_limited_envmap(read_exr(smk.input.envmap), a_prime)
    log.info("environment band-limited with a' = %.4f (%s rule)", a_prime, settings["band_limit"])

    n_tex = len(texels)
    writer = ObservationsWriter(tmp, texels, cameras.names)
    scene = mesh_scene(mi, smk.input.mesh)
    occluded = functools.partial(occlusion_test, mi, scene)
    distances = edge_free_distances(
        distance_maps(mi, scene, cameras.K, cameras.world_to_camera, cameras.width, cameras.height),
        jump=settings["edge_jump"],
    )
    nonfinite_pairs = 0
    view_pairs, view_candidates = np.zeros(len(cameras), np.int64), np.zeros(len(cameras), np.int64)
    chunk = settings["chunk_texels"]
    for s in range(0, n_tex, chunk):
        obs = observe(texels.subset(slice(s, s + chunk)), cameras, images, coverage, incoming_map, occluded,
                      distances=distances, min_coverage=settings["min_coverage"],
                      ray_offset=settings["ray_offset"], footprint_slack=settings["footprint_slack"])
        writer.write(s, obs)
        nonfinite_pairs += obs["nonfinite"]
        view_pairs += (obs["weight"] > 0).sum(axis=0)
        view_candidates += obs["view_candidates"]
        log.info("texels %d-%d observed: chunk %s", s, min(s + chunk, n_tex),
                 progress(s // chunk + 1, -(-n_tex // chunk), time.perf_counter() - start))
    views_per_texel = writer.views_per_texel()
    # Raises when fewer views than the minimum give observations (none: later stages would fail).
    lost = check_views(labels, view_pairs, images, coverage, view_candidates,
                       min_usable=settings["min_usable_views"], source=source)
    if lost:
        log.warning("%s", lost)
    writer.close({
        "poses": smk.wildcards.poses,
        "band_limit": {"rule": settings["band_limit"], "a_prime": a_prime},
        "observed_pairs": int(views_per_texel.sum()),
        "unobserved_texels": int((views_per_texel == 0).sum()),
        "nonfinite_pixels": nonfinite_pixels,
        "nonfinite_pairs_dropped": nonfinite_pairs,
        "views_without_observations": [name for name, n in zip(cameras.names, view_pairs) if n == 0],
    })
    coverage_figure(tmp / "coverage.png", texels.resolution, texels.texel, views_per_texel,
                    f"{smk.wildcards.object} / {smk.wildcards.env} ({smk.wildcards.poses} poses)")
    log.info("mean %.1f views per texel, %d texels unobserved; %.1f s in all",
             views_per_texel.mean(), (views_per_texel == 0).sum(), time.perf_counter() - start)


run_script(main, snakemake)  # noqa: F821 (injected by Snakemake)
