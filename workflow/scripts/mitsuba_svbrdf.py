"""Rule mitsuba_svbrdf: SVBRDF textures by differentiable rendering (Mitsuba 3 prb + Adam);
method mitsuba starts from a constant 0.5, freq+mitsuba from the freq estimate."""

from pathlib import Path

import numpy as np
import pandas as pd

from freqbrdf.artefacts import read_svbrdf, write_svbrdf
from freqbrdf.cameras import cameras_from_json
from freqbrdf.inverse import InverseSettings, constant_textures, optimise_textures
from freqbrdf.io import atomic_directory, atomic_path, read_exr, read_json, read_views
from freqbrdf.logs import run_script
from freqbrdf.mitsuba_setup import setup_mitsuba
from freqbrdf.plots import loss_figure


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


def main(smk, log):
    mi = setup_mitsuba(threads=smk.threads)
    poses = Path(smk.input.poses) / "cameras.json"
    cameras = cameras_from_json(read_json(poses), poses)
    images, coverage, nonfinite = read_views(smk.input.capture, cameras.names, cameras.width, cameras.height)
    if nonfinite:
        log.warning("%d NaN/Inf pixel values in the views are ignored", nonfinite)
    settings = InverseSettings(**smk.params.settings)
    log.info("%s: %d views of %dx%d, %s", smk.wildcards.method, len(cameras), cameras.width, cameras.height, settings)

    def progress(report):
        log.info("epoch %d/%d: mean loss %.5g, %.1f s elapsed, %.0f MB resident", report.epoch, report.epochs,
                 report.loss, report.elapsed_s, report.resident_mb)

    result = optimise_textures(mi, smk.input.mesh, read_exr(smk.input.envmap), cameras, images, coverage,
                               start_textures(smk), settings, progress=progress)

    with atomic_directory(smk.output.estimate) as tmp:
        write_svbrdf(tmp, result.textures)
        steps = np.arange(len(result.loss))
        table = pd.DataFrame({"iteration": steps, "loss": result.loss, "epoch": steps // len(cameras) + 1,
                              "view": [cameras.names[k] for k in result.view]})
        with atomic_path(tmp / "loss.tsv") as f:
            table.to_csv(f, sep="\t", index=False)
        title = f"{smk.wildcards.object} / {smk.wildcards.env}: {smk.wildcards.method}"
        loss_figure(tmp / "loss.png", result.loss, title, ylabel=f"{settings.loss} + TV loss (one view per step)")


run_script(main, snakemake)  # noqa: F821 (injected by Snakemake)
