"""Which SfM settings register every view of a capture, and how well: pycolmap on rendered captures.

For each capture (``object/env``, the training split of a results tree) and each setting (config
``poses.colmap`` overrides as ``key=value``, several joined by ``,``; ``default`` for none), runs
`freqbrdf.capture.sfm.reconstruct`, aligns it to the renderer's cameras as rule ``colmap_poses``
does, and prints the registered views, the median rotation and centre errors after the alignment,
and the median relative rotation error (`freqbrdf.capture.sfm_alignment.relative_rotation_errors`),
which no alignment enters: where it is as large as the aligned error, the SfM's own poses are off,
not their alignment. Only for tuning captures; the setting chosen then goes to the
config.

    python bench/sfm_options.py --results DIR --captures die/sunrise suzi/forest \
        --settings default use_mask=true,mask_erosion_px=2 [--out bench/out]

Writes ``<out>/sfm_options.tsv``.
"""

from __future__ import annotations

import argparse
import tempfile
import time
from pathlib import Path

import pandas as pd
import yaml

from freqbrdf import layout
from freqbrdf.capture import sfm
from freqbrdf.capture.sfm_alignment import aligned_cameras, pose_errors
from freqbrdf.capture.sfm_options import SfmOptions
from freqbrdf.scene.cameras import cameras_from_json
from freqbrdf.util.io import read_json

REPO = Path(__file__).resolve().parents[1]


def parse_setting(text: str) -> dict[str, object]:
    """``key=value[,key=value]`` (values read as YAML) -> overrides; ``default`` -> none."""
    if text == "default":
        return {}
    pairs = [item.split("=", 1) for item in text.split(",")]
    if any(len(p) != 2 for p in pairs):
        raise ValueError(f"setting {text!r}: expected key=value[,key=value] or 'default'")
    return {key: yaml.safe_load(value) for key, value in pairs}


def score(capture: Path, options: SfmOptions) -> dict[str, float]:
    """One SfM run of a capture: registered views and the pose errors."""
    reference = cameras_from_json(read_json(capture / "cameras.json"), capture / "cameras.json")
    start = time.perf_counter()
    with tempfile.TemporaryDirectory() as work:
        reconstruction = sfm.reconstruct(capture, Path(work), reference, options)
    seconds = time.perf_counter() - start
    cameras, _ = aligned_cameras(reconstruction, reference, seed=options.seed)
    errors = pose_errors(cameras, reference)
    return {"registered": len(cameras), "views": len(reference),
            "rotation_deg": float(errors.rotation_error_deg.median()),
            "centre_rel": float(errors.centre_error_rel.median()),
            "relative_rotation_deg": float(errors.relative_rotation_error_deg.median()),
            "seconds": seconds}


def main() -> None:
    parser = argparse.ArgumentParser(description=__doc__.split("\n\n")[0])
    parser.add_argument("--results", type=Path, required=True, help="a results tree holding the captures")
    parser.add_argument("--captures", nargs="+", required=True, help="object/env")
    parser.add_argument("--settings", nargs="+", default=["default"])
    parser.add_argument("--config", type=Path, default=REPO / "config" / "config.yaml",
                        help="the config whose poses.colmap the settings override")
    parser.add_argument("--out", type=Path, default=REPO / "bench" / "out")
    args = parser.parse_args()
    base = yaml.safe_load(args.config.read_text())["poses"]["colmap"]
    rows = []
    for setting in args.settings:
        options = SfmOptions.from_config(base | parse_setting(setting))
        for capture in args.captures:
            obj, env = capture.split("/")
            directory = layout.located(layout.CAPTURE, args.results, object=obj, env=env, split="train")
            try:
                row = score(directory, options)
            except Exception as error:  # a setting that registers nothing is a result, not a crash
                row = {"error": f"{type(error).__name__}: {error}".splitlines()[0]}
            rows.append({"setting": setting, "capture": capture} | row)
            print(pd.DataFrame([rows[-1]]).to_string(index=False, header=len(rows) == 1, float_format="%.3f"),
                  flush=True)
    table = pd.DataFrame(rows)
    summary = table.groupby("setting", sort=False)[["registered", "rotation_deg", "relative_rotation_deg"]].agg(
        ["min", "median", "max"])
    print(summary.to_string(float_format="%.3f"))
    args.out.mkdir(parents=True, exist_ok=True)
    table.to_csv(args.out / "sfm_options.tsv", sep="\t", index=False, float_format="%.6g")


if __name__ == "__main__":
    main()
