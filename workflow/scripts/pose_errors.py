"""Rule pose_errors: the SfM summary of every synthetic capture as one table."""

from pathlib import Path

import pandas as pd

from freqbrdf.util.io import atomic_path, read_json
from freqbrdf.util.logs import run_script


def main(smk, log):
    rows = [
        {"object": obj, "env": env, **read_json(Path(poses) / "summary.json")}
        for (obj, env), poses in zip(smk.params.captures, smk.input.poses)
    ]
    table = pd.DataFrame(rows)
    with atomic_path(smk.output[0]) as tmp:
        table.to_csv(tmp, sep="\t", index=False, float_format="%.6g")
    log.info("SfM pose errors:\n%s", table.to_string(index=False, float_format=lambda v: f"{v:.4g}"))


run_script(main, snakemake)  # noqa: F821 (injected by Snakemake)
