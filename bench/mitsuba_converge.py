"""When has the differentiable-rendering baseline (method ``mitsuba``) converged, and what gets it there first?

Reads runs of rule ``mitsuba`` on the tuning captures, each a results tree of config/tuning.yaml
with one schedule of the baseline: the first given is the reference, a long run at a constant
learning rate (e.g. ``mitsuba.epochs: 96``). From each run's per-epoch parameter MSE
(``mse_curve.tsv``, evaluation only) and training loss (``loss.tsv``), per capture:

- the MSE and time after each budget, over the reference's final MSE;
- the doubling budget of each run (issue 48's definition of a converged budget): the fewest
  epochs ``k`` from which on doubling the run lowers the MSE by less than ``--doubling`` (5%);
- each run's time to come within ``--within`` (5%) of the reference's final MSE;
- for each stopping rule of the training loss (`freqbrdf.estimate.mitsuba_settings.stop_epoch`,
  windows x falls, no ground truth): the epoch it stops at, its time and MSE over the reference's.

A run's schedule must not depend on its length (a constant rate, coarse levels fixed in epochs):
then a run of k epochs is the first k epochs of a longer one (the same view orders and sampler
seeds), and one long run per capture and schedule answers for every budget and rule. Only for
the tuning set, never the reported captures.

    python bench/mitsuba_converge.py --runs constant=DIR [coarse=DIR ...] [--out bench/out]

Prints the tables and writes ``<out>/mitsuba_converge_{budgets,reach,rules}.tsv``.
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
BUDGETS = (6, 12, 16, 24, 32, 48, 64, 96)
WINDOWS = (2, 4, 6, 8)
FALLS = (0.002, 0.005, 0.01, 0.02)


def read_run(estimate: Path) -> tuple[pd.DataFrame, np.ndarray]:
    """The run's per-epoch curve (``elapsed_s``, ``mse_average``, indexed by epoch, 0 the start)
    and its mean training loss per epoch, shape (E,)."""
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
    budget = None
    for k in range(int(mse.index.max()) // 2, 0, -1):  # from the longest down: an early plateau does not count
        if mse[k] - mse[2 * k] >= tolerance * mse[k]:
            break
        budget = k
    return budget


def first_within(curve: pd.DataFrame, target: float) -> tuple[int | None, float]:
    """The first epoch whose MSE is at most ``target``, and its time; (None, NaN) if none is."""
    hits = curve.index[(curve.mse_average <= target).to_numpy() & (curve.index > 0)]
    return (int(hits[0]), float(curve.elapsed_s[hits[0]])) if len(hits) else (None, float("nan"))


def budget_rows(run: str, capture: str, curve: pd.DataFrame, reference: float) -> list[dict]:
    """One row per budget of :data:`BUDGETS` within the run: its time, MSE and MSE over ``reference``."""
    return [{"run": run, "capture": capture, "epochs": k, "elapsed_s": float(curve.elapsed_s[k]),
             "mse": float(curve.mse_average[k]), "over_reference": float(curve.mse_average[k]) / reference - 1.0}
            for k in BUDGETS if k in curve.index]


def rule_rows(run: str, capture: str, curve: pd.DataFrame, epoch_loss: np.ndarray, reference: float,
              cap: int, start: int = 0) -> list[dict]:
    """One row per stopping rule (:data:`WINDOWS` x :data:`FALLS`): the epoch it stops at (the cap
    when it never does), its time, MSE and MSE over ``reference``. ``start``: epochs before the
    rule looks (a coarse-to-fine run's coarse epochs)."""
    rows = []
    last = min(cap, len(epoch_loss))
    for window, fall in itertools.product(WINDOWS, FALLS):
        stop = stop_epoch(epoch_loss[start:last], window, fall)
        stop = last if stop is None else start + stop
        rows.append({"run": run, "capture": capture, "window": window, "fall": fall, "cap": cap, "stop_epoch": stop,
                     "elapsed_s": float(curve.elapsed_s[stop]), "mse": float(curve.mse_average[stop]),
                     "over_reference": float(curve.mse_average[stop]) / reference - 1.0})
    return rows


def run_estimates(results: Path, method: str, poses: str) -> dict[str, Path]:
    """``object/env`` -> the run's estimate directory, for the estimates with an MSE curve."""
    pattern = layout.located(layout.ESTIMATE, results, object="*", env="*", poses=poses, method=method)
    found = sorted(p for p in results.glob(str(pattern.relative_to(results))) if (p / "mse_curve.tsv").is_file())
    return {f"{p.parts[-4]}/{p.parts[-3]}": p for p in found}


def main() -> None:
    parser = argparse.ArgumentParser(description=__doc__.splitlines()[0])
    parser.add_argument("--runs", nargs="+", required=True, help="NAME=RESULTS_DIR, the reference first")
    parser.add_argument("--method", default="mitsuba")
    parser.add_argument("--poses", default="gt")
    parser.add_argument("--doubling", type=float, default=0.05)
    parser.add_argument("--within", type=float, default=0.05)
    parser.add_argument("--cap", type=int, default=96, help="the stopping rules' cap in epochs")
    parser.add_argument("--out", type=Path, default=REPO / "bench" / "out")
    args = parser.parse_args()
    runs = dict(item.split("=", 1) for item in args.runs)
    default = yaml.safe_load((REPO / "config" / "config.yaml").read_text())
    bench = yaml.safe_load((REPO / "config" / "benchmark.yaml").read_text())
    reported = {f"{o}/{e}" for c in (default, bench) for o in c["objects"] for e in c["capture_envs"]}
    budgets, reach, rules, references = [], [], [], {}
    for name, results in runs.items():
        results = Path(results)
        settings = yaml.safe_load(layout.located(layout.RUN_CONFIG, results).read_text())["mitsuba"]
        if settings["lr_decay"] != "none" or settings["stop_window"]:
            raise SystemExit(f"{results}: mitsuba.lr_decay {settings['lr_decay']!r}, stop_window "
                             f"{settings['stop_window']}: a budget is a prefix of the run only at a constant rate, "
                             "run to its end")
        start = settings.get("coarse_levels", 0) * settings.get("coarse_epochs", 1)
        estimates = run_estimates(results, args.method, args.poses)
        if not estimates:
            raise SystemExit(f"{results}: no {args.method} estimates with an MSE curve")
        for capture, estimate in estimates.items():
            if capture in reported:
                raise SystemExit(f"{capture}: a capture a reported run uses; this bench is for the tuning set only")
            curve, epoch_loss = read_run(estimate)
            reference = references.setdefault(capture, float(curve.mse_average.iloc[-1]))
            budgets += budget_rows(name, capture, curve, reference)
            rules += rule_rows(name, capture, curve, epoch_loss, reference, args.cap, start)
            epoch, seconds = first_within(curve, (1.0 + args.within) * reference)
            reach.append({"run": name, "capture": capture, "epochs": epoch, "elapsed_s": seconds,
                          "doubling_budget": doubling_budget(curve.mse_average, args.doubling),
                          "final_over_reference": float(curve.mse_average.iloc[-1]) / reference - 1.0,
                          "s_per_epoch": float(curve.elapsed_s.iloc[-1]) / int(curve.index.max())})
    args.out.mkdir(parents=True, exist_ok=True)
    budgets, reach, rules = pd.DataFrame(budgets), pd.DataFrame(reach), pd.DataFrame(rules)
    for label, table in (("budgets", budgets), ("reach", reach), ("rules", rules)):
        table.to_csv(args.out / f"mitsuba_converge_{label}.tsv", sep="\t", index=False, float_format="%.5g")
    pd.set_option("display.width", 200)
    print("MSE after each budget over the reference's final MSE:")
    print(budgets.pivot(index="epochs", columns=["run", "capture"], values="over_reference")
          .to_string(float_format="{:+.1%}".format))
    print(f"\nfirst epoch within {args.within:.0%} of the reference, its time, the doubling budget:")
    print(reach.to_string(index=False, float_format="{:.3f}".format))
    worst = rules.groupby(["run", "window", "fall"]).agg(worst_over=("over_reference", "max"),
                                                         mean_s=("elapsed_s", "mean"),
                                                         mean_epochs=("stop_epoch", "mean"))
    print(f"\nstopping rules (cap {args.cap}): worst MSE over the reference and mean time over the captures")
    print(worst.to_string(float_format="{:.3f}".format))


if __name__ == "__main__":
    main()
