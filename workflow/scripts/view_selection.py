"""Rule view_selection: a capture's candidate poses ranked by the expected decrease of mean entropy."""

import functools
import time

import numpy as np

from freqbrdf.artefacts import read_observations, sample_texels
from freqbrdf.scene.cameras import cameras_from_json, cameras_to_json, rig_cameras
from freqbrdf.util.io import atomic_path, read_exr, read_json, write_json
from freqbrdf.util.logs import run_script
from freqbrdf.util.mitsuba_setup import setup_mitsuba
from freqbrdf.capture.kernels import set_threads as set_kernel_threads
from freqbrdf.capture.observations import band_limit_parameter, band_limited_envmap
from freqbrdf.scene.raycast import mesh_scene, occlusion_test
from freqbrdf.studies.view_selection import (
    SelectionModel,
    greedy_selection,
    ranking_table,
)
from freqbrdf.studies.candidates import capture_and_candidates


def candidate_poses(smk):
    """The candidates of `view_selection.candidate_poses`, or a rotated Fibonacci rig like the capture's."""
    if "candidates" in smk.input.keys():
        return cameras_from_json(read_json(smk.input.candidates), source=smk.input.candidates)
    p, render = smk.params.settings, smk.params.render
    return rig_cameras(p["candidates"], render["resolution"], render["fov_deg"], render["camera_distance"],
                       azimuth_deg=p["candidate_azimuth_deg"], prefix="candidate_")


def main(smk, log):
    mi = setup_mitsuba(smk.params.variant, smk.threads)
    set_kernel_threads(smk.threads)
    p = smk.params
    obs = read_observations(smk.input.observations)
    cameras = candidate_poses(smk)
    n_capture = len(obs.meta["views"])
    select = min(p.settings["select"], len(cameras))
    a_prime = band_limit_parameter(n_capture + select, p.band_limit)
    texels = sample_texels(np.arange(len(obs.texels)), p.settings["texels"], p.seed)
    start = time.perf_counter()
    occluded = functools.partial(occlusion_test, mi, mesh_scene(mi, smk.input.mesh))
    views = capture_and_candidates(obs, texels, cameras, band_limited_envmap(read_exr(smk.input.envmap), a_prime),
                                   occluded, p.ray_offset)
    log.info("%d candidates seen on %d of %d sampled texels (a' = %.3f of %d views) in %.1f s", len(cameras),
             int((views.weight[:, n_capture:] > 0).any(axis=1).sum()), len(texels), a_prime, n_capture + select,
             time.perf_counter() - start)
    model = SelectionModel.from_config(p.sh, p.spectrum, a_prime, p.settings["posterior_min_views"])
    start = time.perf_counter()
    picks, rankings = greedy_selection(model, views, select, chosen=range(n_capture))
    seconds = time.perf_counter() - start
    table = ranking_table(views, n_capture, picks, rankings)
    log.info("expected mean entropy %.4f with the capture's %d views, %.4f with %d picks (%s); %d rankings of "
             "%d-%d candidates in %.1f s", rankings[0].current, n_capture, rankings[-1].current, len(picks),
             ", ".join(table.view[:len(picks)]), len(rankings), len(cameras) - len(picks), len(cameras), seconds)
    with atomic_path(smk.output.ranked) as f:
        table.to_csv(f, sep="\t", index=False, float_format="%.6g")
    write_json(smk.output.candidates, cameras_to_json(cameras))


run_script(main, snakemake)  # noqa: F821 (injected by Snakemake)
