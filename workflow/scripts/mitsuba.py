"""Rule mitsuba: SVBRDF textures by differentiable rendering (Mitsuba 3 prb + Adam);
method mitsuba starts from a constant 0.5, freq+mitsuba from the freq estimate."""

from pathlib import Path

import numpy as np
import pandas as pd

from freqbrdf.artefacts import read_observations, read_svbrdf, write_svbrdf
from freqbrdf.sphere.brdf import TEXTURES, parameter_mse
from freqbrdf.scene.cameras import cameras_from_json
from freqbrdf.estimate.mitsuba import InverseSettings, constant_textures, optimise_textures, step_table
from freqbrdf.util.io import atomic_directory, atomic_path, read_exr, read_json, read_views
from freqbrdf.util.logs import progress, run_script
from freqbrdf.util.mitsuba_setup import setup_mitsuba
from freqbrdf.util.previews import loss_figure


def start_textures(smk) -> dict[str, np.ndarray]:
    """The constant start of the baseline, or the estimate being fine-tuned."""
    resolution = smk.params.resolution
    if "init" not in smk.input.keys():
        return constant_textures(resolution)
    start = read_svbrdf(smk.input.init)
    if start.resolution != resolution:
        raise ValueError(f"{smk.input.init}: textures are {start.resolution}x{start.resolution}, "
                         f"config textures.resolution is {resolution}")
    return dict(start)


def evaluation(smk):
    """Parameter MSE against the ground truth over the observed texels (as the metrics rule
    scores it), for a synthetic capture; None for a real one."""
    if "truth" not in smk.input.keys():
        return None
    truth = read_svbrdf(dict(zip(TEXTURES, smk.input.truth)))
    obs = read_observations(smk.input.observations)
    texels = obs.texels.texel[obs.observed]
    return lambda textures: {f"mse_{k}": v for k, v in parameter_mse(truth, textures, texels).items()}


def main(smk, log):
    mi = setup_mitsuba(smk.params.variant, smk.threads)
    poses = Path(smk.input.poses) / "cameras.json"
    cameras = cameras_from_json(read_json(poses), poses)
    images, coverage, nonfinite = read_views(smk.input.capture, cameras.names, cameras.width, cameras.height)
    if nonfinite:
        log.warning("%d NaN/Inf pixel values in the views are ignored", nonfinite)
    settings = InverseSettings(**smk.params.settings)
    log.info("%s: %d views of %dx%d, %s", smk.wildcards.method, len(cameras), cameras.width, cameras.height, settings)

    def report_epoch(report):
        log.info("epoch %s: mean loss %.5g, %.0f MB resident", progress(report.epoch, report.epochs, report.elapsed_s),
                 report.loss, report.resident_mb)

    result = optimise_textures(mi, smk.input.mesh, read_exr(smk.input.envmap), cameras, images, coverage,
                               start_textures(smk), settings, progress=report_epoch, evaluate=evaluation(smk))

    with atomic_directory(smk.output.estimate) as tmp:
        write_svbrdf(tmp, result.textures)
        with atomic_path(tmp / "loss.tsv") as f:
            pd.DataFrame(step_table(result, cameras.names)).to_csv(f, sep="\t", index=False)
        if result.evaluations:
            with atomic_path(tmp / "mse_curve.tsv") as f:
                pd.DataFrame(result.evaluations).to_csv(f, sep="\t", index=False, float_format="%.6g")
            log.info("parameter MSE by epoch: %s", ", ".join(f"{r['mse_average']:.4f} at {r['elapsed_s']:.1f} s"
                                                            for r in result.evaluations))
        title = f"{smk.wildcards.object} / {smk.wildcards.env}: {smk.wildcards.method}"
        per_step = "one view" if settings.views_per_step == 1 else f"{settings.views_per_step} views"
        loss_figure(tmp / "loss.png", result.loss, title, ylabel=f"{settings.loss} + TV loss ({per_step} per step)")


run_script(main, snakemake)  # noqa: F821 (injected by Snakemake)
