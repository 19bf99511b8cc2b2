"""bench/mitsuba_converge.py: the doubling budget and the stopping rules on a known curve."""

from __future__ import annotations

import sys
from pathlib import Path

import numpy as np
import pandas as pd

sys.path.insert(0, str(Path(__file__).resolve().parents[1] / "bench"))
from mitsuba_converge import doubling_budget, first_within, rule_rows  # noqa: E402


def test_the_doubling_budget_is_where_doubling_stops_paying_for_good():
    # 1 / (1 + e): doubling k -> 2k lowers the MSE by k / (1 + 2k), under 5% never; a floor then
    # makes it 0 from epoch 10 on
    epochs = np.arange(0, 41)
    mse = pd.Series(np.maximum(1.0 / (1.0 + epochs), 1.0 / 11.0), index=epochs)
    assert doubling_budget(mse, 0.05) == 10  # (1/11 - 1/11) from 10; at 9: (1/10 - 1/11) / (1/10) = 9%
    # an early plateau (epochs 1-2 flat) that falls again is not convergence
    early = mse.copy()
    early[2] = early[1]
    assert doubling_budget(early, 0.05) == 10
    # too short to tell: still falling fast at the run's half
    assert doubling_budget(pd.Series(1.0 / (1.0 + epochs[:9]), index=epochs[:9]), 0.05) is None


def test_a_stopping_rule_stops_where_its_loss_levels_off_else_at_the_cap():
    epochs = np.arange(0, 13)
    curve = pd.DataFrame({"elapsed_s": 5.0 * epochs, "mse_average": 0.1 + 0.1 * 0.5 ** epochs}, index=epochs)
    loss = np.r_[np.geomspace(1.0, 0.1, 6), np.full(6, 0.1)]  # levels off after epoch 6
    reference = 0.1 + 0.1 * 0.5 ** 12
    rows = {(r["window"], r["fall"]): r for r in rule_rows("constant", "die/forest", curve, loss, reference, cap=12)}
    assert rows[2, 0.01]["stop_epoch"] == 9  # windows 6-7 and 8-9 both at 0.1 (epoch 6's the last fall)
    assert rows[2, 0.01]["elapsed_s"] == 45.0
    assert rows[2, 0.01]["over_reference"] == (0.1 + 0.1 * 0.5 ** 9) / reference - 1.0
    assert rows[8, 0.002]["stop_epoch"] == 12  # never within the cap: the cap
    # a coarse-to-fine run's rule looks only from its first full-resolution epoch on
    late = {(r["window"], r["fall"]): r for r in rule_rows("coarse", "die/forest", curve, loss, reference, 12, start=6)}
    assert late[2, 0.01]["stop_epoch"] == 10  # epochs 7-8 against 9-10: the first windows after epoch 6
    assert first_within(curve, 0.1 + 0.1 * 0.5 ** 5) == (5, 25.0)
    epoch, seconds = first_within(curve, 0.05)
    assert epoch is None and np.isnan(seconds)
