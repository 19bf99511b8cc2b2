"""When has the differentiable-rendering baseline (method ``mitsuba``) converged, and what stops it there?

Reads long runs of rule ``mitsuba`` on the tuning captures (config/tuning.yaml with a long
``mitsuba.epochs``, e.g. 96: the reference) and answers, per capture, from each run's
per-epoch parameter MSE (``mse_curve.tsv``, evaluation only) and training loss (``loss.tsv``):

- the MSE and time after each budget, relative to the reference's final MSE;
- the doubling budget (issue 48's definition of a converged budget): the fewest epochs ``k``
  from which on doubling the run lowers the MSE by less than ``--doubling`` (5%), for every
  longer budget the run can double too;
- for each stopping rule of the training loss (`freqbrdf.estimate.mitsuba_settings.stop_epoch`,
  windows x falls, no ground truth): the epoch it stops at, its time and MSE over the reference's.

At a constant learning rate a run of k epochs is the first k epochs of a longer one (the same
view orders and sampler seeds), so one long run per capture answers for every budget and rule.
Only for the tuning set, never the reported captures.

    python bench/mitsuba_converge.py --results DIR [--method mitsuba] [--out bench/out]

Prints the tables and writes ``<out>/mitsuba_converge_budgets.tsv`` and ``..._rules.tsv``.
"""

from __future__ import annotations

import argparse
import itertools
from pathlib import Path

import numpy as np
import pandas as pd
import yaml

from freqbrdf import layout
from freqbrdf.estimate.mitsuba_settings import stop_epoch

REPO = Path(__file__).resolve().parents[1]
BUDGETS = (6, 12, 24, 32, 48, 64, 96)
WINDOWS = (2, 4, 6, 8)
FALLS = (0.002, 0.005, 0.01, 0.02)


def read_run(estimate: Path) -> tuple[pd.DataFrame, np.ndarray]:
    """The run's per-epoch curve (``epoch``, ``elapsed_s``, ``mse_average``; epoch 0 the start) and
    its mean training loss per epoch, shape (E,)."""
    curve = pd.read_csv(estimate / "mse_curve.tsv", sep="\t")
    steps = pd.read_csv(estimate / "loss.tsv", sep="\t")
    epoch_loss = steps.groupby("epoch").loss.mean().sort_index().to_numpy()
    if len(epoch_loss) != curve.epoch.max():
        raise ValueError(f"{estimate}: loss.tsv has {len(epoch_loss)} epochs, mse_curve.tsv {curve.epoch.max()}")
    return curve.set_index("epoch"), epoch_loss


def doubling_budget(mse: pd.Series, tolerance: float) -> int | None:
    """The fewest epochs k from which on, for every k' >= k with 2k' within the run, doubling the
    run lowers the MSE by less than ``tolerance``: (mse[k'] - mse[2k']) < tolerance mse[k'].

    Parameters
    ----------
    mse : Series
        Parameter MSE indexed by epoch (0, 1, ..., E).
    tolerance : float

    Returns
    -------
    int or None
        None when even k = E // 2 fails (the run is too short to show it).
    """
    longest = int(mse.index.max()) // 2
    budget = None
    for k in range(longest, 0, -1):  # from the longest down: an early plateau that falls again does not count
        if mse[k] - mse[2 * k] >= tolerance * mse[k]:
            break
        budget = k
    return budget


def budget_rows(capture: str, curve: pd.DataFrame) -> list[dict]:
    """One row per budget of :data:`BUDGETS` within the run: its time, MSE and MSE over the reference's."""
    reference = float(curve.mse_average.iloc[-1])
    return [{"capture": capture, "epochs": k, "elapsed_s": float(curve.elapsed_s[k]),
             "mse": float(curve.mse_average[k]), "over_reference": float(curve.mse_average[k]) / reference - 1.0}
            for k in BUDGETS if k in curve.index]


def rule_rows(capture: str, curve: pd.DataFrame, epoch_loss: np.ndarray, cap: int) -> list[dict]:
    """One row per stopping rule (:data:`WINDOWS` x :data:`FALLS`): the epoch it stops at (the cap
    when it never does), its time, MSE and MSE over the reference's."""
    reference = float(curve.mse_average.iloc[-1])
    rows = []
    for window, fall in itertools.product(WINDOWS, FALLS):
        stop = stop_epoch(epoch_loss[:cap], window, fall) or min(cap, len(epoch_loss))
        rows.append({"capture": capture, "window": window, "fall": fall, "cap": cap, "stop_epoch": stop,
                     "elapsed_s": float(curve.elapsed_s[stop]), "mse": float(curve.mse_average[stop]),
                     "over_reference": float(curve.mse_average[stop]) / reference - 1.0})
    return rows


def main() -> None:
    parser = argparse.ArgumentParser(description=__doc__.splitlines()[0])
    parser.add_argument("--results", type=Path, required=True, help="a tuning run's results with long mitsuba runs")
    parser.add_argument("--method", default="mitsuba")
    parser.add_argument("--poses", default="gt")
    parser.add_argument("--doubling", type=float, default=0.05)
    parser.add_argument("--cap", type=int, default=96, help="the stopping rules' cap in epochs")
    parser.add_argument("--out", type=Path, default=REPO / "bench" / "out")
    args = parser.parse_args()
    run = yaml.safe_load(layout.located(layout.RUN_CONFIG, args.results).read_text())["mitsuba"]
    if run["lr_decay"] != "none" or run["stop_window"]:
        raise SystemExit(f"{args.results}: mitsuba.lr_decay {run['lr_decay']!r}, stop_window {run['stop_window']}: "
                         "a budget is a prefix of the run only at a constant rate, run to its end")
    default = yaml.safe_load((REPO / "config" / "config.yaml").read_text())
    bench = yaml.safe_load((REPO / "config" / "benchmark.yaml").read_text())
    reported = {(o, e) for c in (default, bench) for o in c["objects"] for e in c["capture_envs"]}
    pattern = layout.located(layout.ESTIMATE, args.results, object="*", env="*", poses=args.poses, method=args.method)
    estimates = sorted(p for p in args.results.glob(str(pattern.relative_to(args.results))) if (p / "mse_curve.tsv").is_file())
    if not estimates:
        raise SystemExit(f"{args.results}: no {args.method} estimates with an MSE curve")
    budgets, rules, doubling = [], [], {}
    for estimate in estimates:
        obj, env = estimate.parts[-4], estimate.parts[-3]
        if (obj, env) in reported:
            raise SystemExit(f"{obj}/{env}: a capture a reported run uses; this bench is for the tuning set only")
        capture = f"{obj}/{env}"
        curve, epoch_loss = read_run(estimate)
        budgets += budget_rows(capture, curve)
        rules += rule_rows(capture, curve, epoch_loss, args.cap)
        doubling[capture] = doubling_budget(curve.mse_average, args.doubling)
    args.out.mkdir(parents=True, exist_ok=True)
    budgets, rules = pd.DataFrame(budgets), pd.DataFrame(rules)
    budgets.to_csv(args.out / "mitsuba_converge_budgets.tsv", sep="\t", index=False, float_format="%.5g")
    rules.to_csv(args.out / "mitsuba_converge_rules.tsv", sep="\t", index=False, float_format="%.5g")
    print("MSE after each budget over the reference's (its last epoch), and the time:")
    print(budgets.pivot(index="epochs", columns="capture", values="over_reference").to_string(float_format="{:+.1%}".format))
    print(budgets.pivot(index="epochs", columns="capture", values="elapsed_s").to_string(float_format="{:.0f} s".format))
    print(f"\nfewest epochs from which on doubling lowers the MSE by less than {args.doubling:.0%}:",
          ", ".join(f"{c} {k}" for c, k in doubling.items()))
    worst = rules.groupby(["window", "fall"]).agg(worst_over=("over_reference", "max"), mean_s=("elapsed_s", "mean"),
                                                  mean_epochs=("stop_epoch", "mean"))
    print(f"\nstopping rules (cap {args.cap}): worst MSE over the reference and mean time over the captures")
    print(worst.to_string(float_format="{:.3f}".format))


if __name__ == "__main__":
    main()
