"""How should the packaged HDR maps' negative texels be removed? (issue 35)

The maps of ``@pmndrs/assets`` ring around suns and lamps with the alternating signs of a
sharpening resampling filter. Their originals are not in the package, so the ringing is
re-made where the truth is known: each of the twelve maps, clamped and blurred (its own
ringing removed), is upsampled 4x, given a sun of 3x3 fine texels (30,000 x the map's mean,
at a seeded place), and brought back to 512 x 256 twice: by area averaging (the truth) and
by PIL's Lanczos filter (the artefact). Each clean-up is scored against the truth by the
relative error of the SH coefficients up to degree 20 (the light the estimators see) and the
change of the map's power.

    python bench/hdri_cleaning.py   # after snakemake has fetched the package (rule fetch_asset_package)

Writes ``<out>/hdri_cleaning.tsv`` (map, clean-up, SH error, power change) and prints the means.
"""

from __future__ import annotations

import argparse
from pathlib import Path

import numpy as np
import pandas as pd
from PIL import Image
from scipy import ndimage

from freqbrdf.layout import RESOURCE, fill
from freqbrdf.scene.assets import TARBALL
from freqbrdf.scene.hdri import MAPS, clean_envmap, read_map
from freqbrdf.sphere.sampling import equirect_solid_angles
from freqbrdf.sphere.sh import project_equirect

REPO = Path(__file__).resolve().parents[1]


def power(env: np.ndarray) -> float:
    return float((env * equirect_solid_angles(*env.shape[:2])[:, None, None]).sum())


def resized(image: np.ndarray, size: tuple[int, int], method) -> np.ndarray:
    return np.stack([np.asarray(Image.fromarray(image[..., c].astype(np.float32), "F").resize(size, method))
                     for c in range(3)], axis=-1).astype(np.float64)


def test_pair(source: np.ndarray, rng: np.random.Generator) -> tuple[np.ndarray, np.ndarray]:
    """(truth, ringing) versions of one map with a sun added."""
    base = ndimage.gaussian_filter(np.maximum(source.astype(np.float64), 0.0), (1, 1, 0))
    fine = np.repeat(np.repeat(base, 4, axis=0), 4, axis=1)
    rows, cols = fine.shape[:2]
    i, j = int(rng.integers(rows // 8, rows // 2)), int(rng.integers(0, cols - 3))
    # 9 of a coarse texel's 16 fine texels: the coarse texel's radiance is about 30,000 x the mean
    fine[i:i + 3, j:j + 3] += 3e4 * power(base) / (4 * np.pi) * 16 / 9
    size = (source.shape[1], source.shape[0])
    return resized(fine, size, Image.BOX), resized(fine, size, Image.LANCZOS)


CLEANUPS = {
    "none": lambda env: env,
    "clamp": lambda env: np.maximum(env, 0.0),
    "clamp, power rescaled": lambda env: np.maximum(env, 0.0) * power(env) / power(np.maximum(env, 0.0)),
    **{f"regions, radius {r}": (lambda env, r=r: clean_envmap(env, radius=r)[0]) for r in (1, 2, 3, 5)},
}


def main() -> None:
    parser = argparse.ArgumentParser(description=__doc__.splitlines()[0])
    parser.add_argument("--package", type=Path, default=REPO / fill(RESOURCE, name=TARBALL))
    parser.add_argument("--out", type=Path, default=REPO / "bench" / "out" / "hdri_cleaning")
    parser.add_argument("--seed", type=int, default=0)
    args = parser.parse_args()
    rng = np.random.default_rng(args.seed)
    rows = []
    for name in MAPS:
        truth, ringing = test_pair(read_map(args.package, name), rng)
        reference = project_equirect(truth.astype(np.float32), 20)
        for cleanup, clean in CLEANUPS.items():
            cleaned = clean(ringing)
            coeffs = project_equirect(np.asarray(cleaned, np.float32), 20)
            rows.append({"map": name, "cleanup": cleanup, "negative_texels": int((ringing < 0).any(axis=2).sum()),
                         "sh_error": np.linalg.norm(coeffs - reference) / np.linalg.norm(reference),
                         "power_change": power(cleaned) / power(truth) - 1.0})
    table = pd.DataFrame(rows)
    args.out.mkdir(parents=True, exist_ok=True)
    table.to_csv(args.out / "hdri_cleaning.tsv", sep="\t", index=False, float_format="%.6g")
    summary = table.groupby("cleanup", sort=False).agg(
        sh_error_mean=("sh_error", "mean"), sh_error_max=("sh_error", "max"),
        power_change_max=("power_change", lambda v: v.abs().max()))
    print(summary.to_string(float_format=lambda v: f"{100 * v:.2f}%"))


if __name__ == "__main__":
    main()
