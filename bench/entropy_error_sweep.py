"""Pearson correlation of the spectrum entropy with ``freq``'s per-texel error, per entropy setting.

For each capture, the pipeline's SH fit (`freqbrdf.layout.SH_FIT`) is searched again
with every combination of `spectrum.normalise` (``light``, ``reference``),
`spectrum.combine` (``min``, ``luminance``) and a range of `spectrum.sigma`,
and each entropy is correlated (Pearson, over the observed texels) with the
squared parameter error of the run's ``freq`` estimate (`freqbrdf.layout.ESTIMATE`):
the criterion that chose `spectrum.sigma`. Choose on the tuning set
(config/tuning.yaml); on the reported captures it only shows how far the
criterion moves. The results directory is the repository's
(`freqbrdf.layout.RESULTS`), or ``FREQBRDF_RESULTS``'s.

    FREQBRDF_RESULTS=<tuning clone>/results python bench/entropy_error_sweep.py \\
        --captures die/museum die/overcast vase/museum vase/overcast
    python bench/entropy_error_sweep.py --captures sphere/studio sphere/sunny torus/studio torus/sunny

Writes ``bench/out/entropy_error.tsv``: one row per capture and setting, and their means (capture ``mean``).
"""

from __future__ import annotations

import argparse
import os
from pathlib import Path

import numpy as np

from freqbrdf import layout
from freqbrdf.artefacts import read_observations, read_sh_fit, read_svbrdf
from freqbrdf.sphere.brdf import TEXTURES
from freqbrdf.report.metrics import parameter_error_map, pearson
from freqbrdf.estimate.spectrum import default_grid, residual_width, spectrum_search

REPO = Path(__file__).resolve().parents[1]
RESULTS = Path(os.environ.get("FREQBRDF_RESULTS", REPO / layout.RESULTS))
SETTINGS = [(sigma, combine, "light") for sigma in (0.001, 0.003, 0.01, 0.03) for combine in ("min", "luminance")]
SETTINGS += [(sigma, combine, "reference") for sigma in (1e-5, 1e-4, 1e-3, 1e-2) for combine in ("min", "luminance")]


def correlations(capture: str) -> list[float]:
    """Pearson(entropy, freq's squared parameter error) of one capture, per entry of SETTINGS."""
    obj, env = capture.split("/")
    capture_fields = {"object": obj, "env": env, "poses": "gt"}
    fit = read_sh_fit(layout.located(layout.SH_FIT, RESULTS, **capture_fields))
    obs = read_observations(layout.located(layout.OBSERVATIONS, RESULTS, **capture_fields))
    truth = read_svbrdf({n: layout.located(layout.OBJECT_TEXTURE, RESULTS, object=obj, texture=n) for n in TEXTURES})
    estimate = read_svbrdf(layout.located(layout.ESTIMATE, RESULTS, **capture_fields, method="freq"))
    seen = obs.observed
    error = parameter_error_map(dict(truth), dict(estimate)).ravel()[obs.texels.texel][seen]
    ks, alpha = default_grid(8, 8, alpha_min=fit.a_prime)
    out = []
    for sigma, combine, normalise in SETTINGS:
        search = spectrum_search(fit.spectra_outgoing, fit.spectra_incoming, ks, residual_width(alpha, fit.a_prime),
                                 sigma=sigma, combine=combine, observed=seen, normalise=normalise)
        out.append(pearson(search.entropy[seen], error))
    return out


def main() -> None:
    parser = argparse.ArgumentParser(description=__doc__.splitlines()[0])
    parser.add_argument("--captures", nargs="+", required=True, help="object/env pairs")
    args = parser.parse_args()
    per_capture = {capture: correlations(capture) for capture in args.captures}
    lines = ["capture\tnormalise\tcombine\tsigma\tpearson_entropy_error"]
    for i, (sigma, combine, normalise) in enumerate(SETTINGS):
        values = [r[i] for r in per_capture.values()]
        lines += [f"{c}\t{normalise}\t{combine}\t{sigma:g}\t{r[i]:.3f}" for c, r in per_capture.items()]
        lines.append(f"mean\t{normalise}\t{combine}\t{sigma:g}\t{np.mean(values):.3f}")
        print(f"{normalise:9s} {combine:9s} sigma {sigma:<7g}", " ".join(f"{v:6.3f}" for v in values),
              f"mean {np.mean(values):.3f}", flush=True)
    out = REPO / "bench" / "out"
    out.mkdir(parents=True, exist_ok=True)
    (out / "entropy_error.tsv").write_text("\n".join(lines) + "\n")
    print(f"written {out / 'entropy_error.tsv'}")


if __name__ == "__main__":
    main()
