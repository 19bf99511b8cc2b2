"""The calibration ``optimise.variance_scale`` that makes freq's 90% posterior intervals hold 90%.

Reads a finished run of the tuning preset (config/tuning.yaml; never a reported run): for
each capture, ``freq``'s estimate and posterior deviations (``std_*.exr``, written with the
run's own ``variance_scale``, from its recorded config, `freqbrdf.layout.RUN_CONFIG`), the ground truth, and the
texels some view observes (the texels metrics.csv scores). The scale is the one for which
|estimate - truth| <= 1.645 std holds for 90% of every parameter of every observed texel,
pooled over the captures: the run's scale times (q90(|estimate - truth| / std) / 1.645)^2.

    python bench/variance_scale.py --results DIR --captures die/sunrise ...   (DIR: the tuning run's results)

Prints the pooled scale, the per-capture and per-parameter ones, and the coverage the run's
own scale gives.
"""

from __future__ import annotations

import argparse
from pathlib import Path

import numpy as np
import yaml

from freqbrdf import layout
from freqbrdf.artefacts import read_observations, read_posterior_std, read_svbrdf
from freqbrdf.report.metrics import texel_parameter_columns
from freqbrdf.sphere.brdf import TEXTURES

Z90 = 1.645  # half-width of a Gaussian's central 90% interval, in standard deviations
PARAMETERS = ("base_color_r", "base_color_g", "base_color_b", "roughness", "metallic")


def standardised_errors(results: Path, capture: str, method: str = "freq") -> np.ndarray:
    """|estimate - truth| / std of every parameter of every observed texel: (T, 5)."""
    obj, env = capture.split("/")
    where = dict(object=obj, env=env, poses="gt")
    obs = read_observations(layout.located(layout.OBSERVATIONS, results, **where))
    texels = obs.texels.texel[obs.observed]
    estimate_dir = layout.located(layout.ESTIMATE, results, method=method, **where)
    truth = read_svbrdf({g: layout.located(layout.OBJECT_TEXTURE, results, object=obj, texture=g) for g in TEXTURES})
    error = texel_parameter_columns(read_svbrdf(estimate_dir), texels) - texel_parameter_columns(truth, texels)
    return np.abs(error) / texel_parameter_columns(read_posterior_std(estimate_dir), texels)


def scale_for_coverage(z: np.ndarray, used: float) -> float:
    """The variance scale under which a fraction 0.9 of ``z`` (errors over deviations at scale ``used``)
    falls within 1.645 deviations."""
    return float(used * (np.quantile(z, 0.9) / Z90) ** 2)


def main() -> None:
    parser = argparse.ArgumentParser(description=__doc__, formatter_class=argparse.RawDescriptionHelpFormatter)
    parser.add_argument("--results", type=Path, required=True, help="a finished tuning run's results directory")
    parser.add_argument("--captures", nargs="+", required=True, help="object/env pairs of that run")
    args = parser.parse_args()
    used = yaml.safe_load(layout.located(layout.RUN_CONFIG, args.results).read_text())["optimise"]["variance_scale"]
    pooled = []
    for capture in args.captures:
        z = standardised_errors(args.results, capture)
        pooled.append(z)
        print(f"{capture}: scale {scale_for_coverage(z, used):.2f}, coverage at the run's {used:g}: "
              f"{np.mean(z <= Z90):.3f}")
    z = np.concatenate(pooled)
    per_parameter = ", ".join(f"{name} {scale_for_coverage(z[:, i], used):.2f}" for i, name in enumerate(PARAMETERS))
    print(f"pooled: scale {scale_for_coverage(z, used):.2f} ({per_parameter}); "
          f"coverage at the run's {used:g}: {np.mean(z <= Z90):.3f}")


if __name__ == "__main__":
    main()
