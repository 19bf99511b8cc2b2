"""Time and peak memory of observation extraction at the default and the paper scale.

Runs the real `extract_observations` rule through Snakemake in bench/out/ (cheap
4-spp renders, since only the extraction is measured) and collects its
`benchmark:` files into bench/out/observations.tsv.

    python bench/observations_bench.py            # 256x256 x 24 views and 512x512 x 100 views

Targets (issue 14, "Faster observations"), each the `benchmark:` time of one
job on 2 cores (Python start and imports included): at most 2 s for 256^2
texels x 24 views and at most 25 s for 512^2 texels x 100 views, with memory
bounded by the chunking over texels (issue 3). Run it on an idle machine: the
times scale with the load.
"""

import subprocess
import sys
from pathlib import Path

import pandas as pd
import yaml

from freqbrdf import layout

REPO = Path(__file__).resolve().parents[1]
OUT = REPO / "bench" / "out"
CASES = {
    "256x24": {"textures": {"resolution": 256}, "render": {"resolution": 256, "train_views": 24}},
    "512x100": {"textures": {"resolution": 512}, "envmaps": {"height": 512},
                "render": {"resolution": 512, "train_views": 100}},
}
COMMON = {"objects": ["sphere", "torus"], "capture_envs": ["studio"],
          "render": {"spp": 4, "test_views": 1, "mask_spp": 4}}


def merged(case: dict) -> dict:
    out = {k: (dict(v) if isinstance(v, dict) else v) for k, v in COMMON.items()}
    for key, value in case.items():
        out[key] = {**out.get(key, {}), **value} if isinstance(value, dict) else value
    return out


def main() -> None:
    rows = []
    for name, case in CASES.items():
        workdir = OUT / name
        workdir.mkdir(parents=True, exist_ok=True)
        config = workdir / "config.yaml"
        config.write_text(yaml.safe_dump(merged(case)))
        targets = [layout.fill(layout.OBSERVATIONS, object=o, env="studio", poses="gt") for o in COMMON["objects"]]
        subprocess.run([sys.executable, "-m", "snakemake", "-s", str(REPO / "workflow" / "Snakefile"), "-d", str(workdir),
                        "--cores", "2", *targets, "--configfile", str(config)], check=True)
        for obj in COMMON["objects"]:
            bench = pd.read_csv(workdir / layout.benchmark("extract_observations", f"{obj}_studio_gt"), sep="\t")
            rows.append({"case": name, "object": obj, "seconds": bench["s"].iloc[-1],
                         "peak_rss_mb": bench["max_rss"].iloc[-1]})
    table = pd.DataFrame(rows)
    table.to_csv(OUT / "observations.tsv", sep="\t", index=False)
    print(table.to_string(index=False))


if __name__ == "__main__":
    main()
