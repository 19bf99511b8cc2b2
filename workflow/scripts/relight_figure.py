"""Rule relight_figure: a capture's first test view relit with every method's textures beside the reference."""

from pathlib import Path

import numpy as np

from freqbrdf.report.figures import relight_figure
from freqbrdf.report.relight_metrics import HdrScoring, scored_pixels
from freqbrdf.scene.cameras import cameras_from_json
from freqbrdf.util.io import read_exr, read_json, read_views
from freqbrdf.util.logs import run_script


def first_view(test: Path, min_coverage: float) -> tuple[str, np.ndarray, np.ndarray]:
    """Name, linear image and scored pixels (as metrics scores them) of a test capture's first view."""
    cameras = cameras_from_json(read_json(test / "cameras.json"), f"{test}/cameras.json")
    images, coverage, _ = read_views(test, cameras.names[:1], cameras.width, cameras.height)
    return cameras.names[0], images[0], scored_pixels(coverage[0], min_coverage)


def main(smk, log):
    w = smk.wildcards
    settings = smk.params.metrics
    references, names = {}, {}
    for relight_env, test in zip(smk.params.references, smk.input.references):
        names[relight_env], image, mask = first_view(Path(test), settings["mask_min_coverage"])
        references[relight_env] = (image, mask)
    relit = {}
    for (method, relight_env), directory in zip(smk.params.relights, smk.input.relit):
        view = Path(directory) / relight_env / "images" / f"{names[relight_env]}.exr"
        relit.setdefault(relight_env, {})[method] = read_exr(view)
    scores = relight_figure(smk.output[0], references, relit,
                            f"{w.object} captured under {w.env}: the first test view relit under held-out environments",
                            HdrScoring.from_config(settings))
    log.info("PSNR-H of the first test view: %s",
             ", ".join(f"{m} under {r} {v:.2f}" for (r, m), v in scores.items()) or "no relighting")


run_script(main, snakemake)  # noqa: F821 (injected by Snakemake)
