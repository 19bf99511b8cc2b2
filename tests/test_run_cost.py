"""bench/run_cost.py: what a finished run's jobs cost, from their benchmark files."""

from __future__ import annotations

import sys
from pathlib import Path

import pytest

sys.path.insert(0, str(Path(__file__).resolve().parents[1] / "bench"))
from run_cost import job_costs, rule_costs  # noqa: E402

HEADER = "s\th:m:s\tmax_rss\tmax_vms\tmax_uss\tmax_pss\tio_in\tio_out\tmean_load\tcpu_time\n"


def _write(path: Path, s: float, cpu: float) -> None:
    path.parent.mkdir(parents=True, exist_ok=True)
    path.write_text(HEADER + f"{s}\t0:00:01\t1\t1\t1\t1\t0\t0\t50\t{cpu}\n")


def test_costs_sum_per_rule_the_costliest_first(tmp_path: Path) -> None:
    _write(tmp_path / "relight/a.tsv", 2.0, 3.0)
    _write(tmp_path / "relight/b.tsv", 4.0, 5.0)
    _write(tmp_path / "mitsuba/c.tsv", 10.0, 19.0)
    _write(tmp_path / "metrics.tsv", 1.0, 1.5)  # a rule of one job: benchmarks/<rule>.tsv
    jobs = job_costs(tmp_path)
    assert len(jobs) == 4
    table = rule_costs(jobs)
    assert list(table.index) == ["mitsuba", "relight", "metrics"]
    assert table.loc["relight"].tolist() == [2, 6.0, 8.0]
    assert table.loc["metrics"].tolist() == [1, 1.0, 1.5]


def test_a_missing_directory_or_column_is_named(tmp_path: Path) -> None:
    with pytest.raises(ValueError, match="no benchmark files"):
        job_costs(tmp_path)
    bad = tmp_path / "relight/a.tsv"
    bad.parent.mkdir()
    bad.write_text("s\n1.0\n")
    with pytest.raises(ValueError, match=r"relight/a\.tsv: not a benchmark file"):
        job_costs(tmp_path)
