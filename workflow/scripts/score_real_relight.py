"""Rule score_real_relight: every method's relit test views of a real capture against its test photographs.

Scored like rule metrics scores synthetic relighting (freqbrdf.report.relight_metrics.relight_scores),
over the pixels the test mask covers and whose photograph is finite.
"""

import dataclasses
from pathlib import Path

import numpy as np
import pandas as pd

from freqbrdf.scene.cameras import cameras_from_json
from freqbrdf.util.io import atomic_path, read_exr, read_json, read_views
from freqbrdf.util.logs import run_script
from freqbrdf.report.relight_metrics import HdrScoring, relight_scores
from freqbrdf.report.tables.tidy import TIDY_COLUMNS

COLUMNS = list(TIDY_COLUMNS)


def main(smk, log):
    settings = smk.params.metrics
    test = Path(smk.input.test)
    cameras = cameras_from_json(read_json(test / "cameras.json"), test / "cameras.json")
    images, coverage, nonfinite = read_views(test, cameras.names, cameras.width, cameras.height)
    masks = (coverage >= settings["mask_min_coverage"] - 1e-6) & np.isfinite(images).all(axis=-1)
    if nonfinite:
        log.warning("%d NaN/Inf pixel values in the test photographs: not scored", nonfinite)
    refs = list(np.nan_to_num(images, nan=0.0, posinf=0.0, neginf=0.0))
    w = smk.wildcards
    scoring = HdrScoring.from_config(settings)
    if scoring.scale == "none":  # a photograph's exposure is not the renderer's: a scale must be fitted
        scoring = dataclasses.replace(scoring, scale="clipped")
    rows = []
    for method, relit in zip(smk.params.methods, smk.input.relit):
        preds = [read_exr(f"{relit}/images/{name}.exr") for name in cameras.names]
        scores = relight_scores(preds, refs, list(masks), scoring)
        key = dict(object=w.object, env=w.env, poses=w.poses, method=method, relight_env="test_views")
        rows += [key | dict(metric=k, value=v) for k, v in scores.items()]
    table = pd.DataFrame(rows, columns=COLUMNS)
    with atomic_path(smk.output[0]) as tmp:
        table.to_csv(tmp, index=False)
    log.info("psnr_h: %s", table[table.metric == "psnr_h"].set_index("method").value.round(2).to_dict())


run_script(main, snakemake)  # noqa: F821 (injected by Snakemake)
