"""Config ``evaluate.interval_widths``: split-conformal widths of freq's posterior intervals, and
which way of pooling the tuning captures holds its levels on a capture it has not seen.

Reads a finished run of the tuning preset (config/tuning.yaml; never a reported run): per
capture, freq's standardised errors ``|estimate - truth| / std`` over its observed texels
(`variance_scale.standardised_errors`). Two ways of making widths from calibration captures:

- ``pooled``: the conformal quantile of all their texels together (`conformal_widths`);
- ``worst``: each capture's own conformal quantile, the largest over the captures.

Leave one capture out: widths from the others, coverage on it at every level. Prints per rule
the mean and the worst shortfall below each level, then both rules' widths from every capture,
as the config block to paste.

    python bench/interval_widths.py --results DIR --captures die/sunrise ...   (DIR: the tuning run's results)
"""

from __future__ import annotations

import argparse
from pathlib import Path

import numpy as np
from variance_scale import standardised_errors

from freqbrdf.report.metrics import PARAMETER_COLUMNS
from freqbrdf.report.sparsification import LEVELS, conformal_widths, gaussian_widths

RULES = ("gaussian", "pooled", "worst")


def widths_of(rule: str, errors: list[np.ndarray]) -> np.ndarray:
    """``(L, 5)`` half-widths per parameter column from calibration captures' standardised errors ``(T_i, 5)``."""
    out = np.empty((len(LEVELS), 5))
    for c in PARAMETER_COLUMNS.values():
        if rule == "gaussian":
            w = gaussian_widths()
        elif rule == "pooled":
            w = conformal_widths(np.concatenate([e[:, c].ravel() for e in errors]))
        else:
            w = np.max([conformal_widths(e[:, c].ravel()) for e in errors], axis=0)
        out[:, c] = w[:, None]
    return out


def coverage(errors: np.ndarray, widths: np.ndarray) -> np.ndarray:
    """``(L, 3)`` coverage per level and texture (base colour's three channels together)."""
    hits = errors[None] <= widths[:, None, :]  # (L, T, 5)
    return np.stack([hits[:, :, c].mean(axis=(1, 2)) for c in PARAMETER_COLUMNS.values()], axis=1)


def main() -> None:
    parser = argparse.ArgumentParser(description=__doc__, formatter_class=argparse.RawDescriptionHelpFormatter)
    parser.add_argument("--results", type=Path, required=True, help="a finished tuning run's results directory")
    parser.add_argument("--captures", nargs="+", required=True, help="object/env pairs of that run")
    args = parser.parse_args()
    errors = {capture: standardised_errors(args.results, capture) for capture in args.captures}
    levels = np.array(LEVELS)[:, None]
    print("leave one capture out: coverage minus level, per level "
          + " ".join(f"{p:g}" for p in LEVELS) + " (worst texture of the held-out capture)")
    for rule in RULES:
        gaps = []
        for held in args.captures:
            rest = [e for c, e in errors.items() if c != held]
            gap = (coverage(errors[held], widths_of(rule, rest)) - levels).min(axis=1)
            gaps.append(gap)
            print(f"  {rule:8s} {held:18s} " + " ".join(f"{g:+.3f}" for g in gap))
        gaps = np.array(gaps)
        print(f"  {rule:8s} mean {' '.join(f'{g:+.3f}' for g in gaps.mean(axis=0))}, "
              f"worst {' '.join(f'{g:+.3f}' for g in gaps.min(axis=0))}")
    for rule in RULES[1:]:
        widths = widths_of(rule, list(errors.values()))
        print(f"{rule} widths from all {len(errors)} captures:\n  interval_widths:")
        for g, c in PARAMETER_COLUMNS.items():
            print(f"    {g}: [{', '.join(f'{w:.3g}' for w in widths[:, c.start])}]")


if __name__ == "__main__":
    main()
