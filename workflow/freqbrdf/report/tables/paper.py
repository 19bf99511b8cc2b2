"""The paper's numbers (Wiersma et al. 2024, arXiv 2406.17774), from ``config/paper_results.yaml``
(:func:`read_paper_results`): its Tables 1 to 6, keyed by its row labels, and the thresholds of the claims."""

from __future__ import annotations

import math
from collections.abc import Mapping, Sequence
from dataclasses import dataclass
from itertools import product
from os import PathLike

import yaml

RELIGHT_FIELDS = ("psnr_h", "psnr_l", "ssim", "lpips", "time_s")
"""Numbers of a row of the paper's Tables 1 and 5."""
ABLATION_FIELDS = ("psnr_h", "psnr_l", "ssim", "lpips", "time_orb_s", "mse", "time_s")
"""Numbers of a row of the paper's Table 4 (besides its shadowing and masking flags)."""
AVERAGE = "Average"
"""The key of the paper's Table 2 values averaged over its environments."""
AGREEMENT_FIELDS = ("pearson", "std", "time_s")
"""Numbers of a row of the paper's Table 3."""
CRITERIA_FIELDS = ("finetune_time_divisor",)

# The paper's rows that the claims quote: Tables 1 and 2 label their methods
# alike; in Table 5, "Ours" is fine-tuned and the last row is Mitsuba alone.
MITSUBA, OURS, SPECTRUM = "Mitsuba", "Ours", "Ours-Spectrum Only"
FINETUNED, MITSUBA_FULL = "Ours", "Full optimization - Constant"
MERGE_AVERAGE = "Average"  # Table 6: the mean over the separate environments
# Table 3's rows, keyed by the entropy of freqbrdf.studies.entropy_agreement they stand beside.
AGREEMENT_ROWS = {"mitsuba": "Entropy Mitsuba", "angular": "Entropy angular", "spectrum": "Entropy power spectrum"}
CLAIM_ROWS = {"table1": (MITSUBA, OURS), "table2": (MITSUBA, OURS, SPECTRUM), "table5": (FINETUNED, MITSUBA_FULL),
              "table6": (MERGE_AVERAGE,), "table3": tuple(AGREEMENT_ROWS.values())}


class PaperResultsError(ValueError):
    """The paper's results file is malformed; the one-line message names the file and the key."""


@dataclass(frozen=True)
class ParameterRow:
    """One method row of the paper's Table 2.

    Attributes
    ----------
    mse : Mapping[str, tuple of float]
        Paper environment name, or :data:`AVERAGE`, -> (average, base colour,
        roughness, metallic) parameter MSE.
    time_s : float
        Optimisation time on the authors' GPU machine.
    """

    mse: Mapping[str, tuple[float, float, float, float]]
    time_s: float


@dataclass(frozen=True)
class AblationRow:
    """One row of the paper's Table 4: which terms the model has, and its numbers (:data:`ABLATION_FIELDS`)."""

    shadowing: bool
    masking: bool
    values: Mapping[str, float]


@dataclass(frozen=True)
class ClaimCriteria:
    """The thresholds of the claims table that the paper states in words, not in its tables
    (see the YAML's comments); the others are :class:`PaperResults`' properties."""

    finetune_time_divisor: float


@dataclass(frozen=True)
class PaperResults:
    """The paper's numbers, keyed by its row labels (``config/paper_results.yaml``).

    Attributes
    ----------
    table1, table5 : Mapping[str, Mapping[str, float]]
        Row label -> :data:`RELIGHT_FIELDS` -> value.
    environments : Mapping[str, str]
        Kind of our environment -> name of the paper's environment of that kind (Table 2).
    table2 : Mapping[str, ParameterRow]
        Row label -> parameter MSE and time.
    correlation_with : str
        The Table 2 row whose per-texel error the paper correlates with our entropy.
    correlation : Mapping[str, float]
        Paper environment name, or :data:`AVERAGE`, -> that correlation.
    table3 : Mapping[str, Mapping[str, float]]
        Row label -> :data:`AGREEMENT_FIELDS` -> value (entropy agreement).
    table4 : Mapping[str, AblationRow]
        Row label -> flags and numbers; one row per (shadowing, masking) pair.
    table6 : Mapping[str, tuple of float]
        Row label -> (average, base colour, roughness, metallic) MSE of the entropy-guided merge.
    criteria : ClaimCriteria
    """

    table1: Mapping[str, Mapping[str, float]]
    environments: Mapping[str, str]
    table2: Mapping[str, ParameterRow]
    correlation_with: str
    correlation: Mapping[str, float]
    table3: Mapping[str, Mapping[str, float]]
    table4: Mapping[str, AblationRow]
    table5: Mapping[str, Mapping[str, float]]
    table6: Mapping[str, tuple[float, float, float, float]]
    criteria: ClaimCriteria

    @property
    def accuracy_gap_mse(self) -> float:
        """"Comparable accuracy": the paper's own gap in average parameter MSE, ours - Mitsuba (Table 2)."""
        return self.table2[OURS].mse[AVERAGE][0] - self.table2[MITSUBA].mse[AVERAGE][0]

    @property
    def relight_gap_db(self) -> float:
        """"On par": the paper's own PSNR-H gap between ours and Mitsuba, in magnitude (Table 1)."""
        return abs(self.table1[OURS]["psnr_h"] - self.table1[MITSUBA]["psnr_h"])

    @property
    def speedup_synthetic(self) -> float:
        """Mitsuba's time over ours on the synthetic set (Table 2)."""
        return self.table2[MITSUBA].time_s / self.table2[OURS].time_s

    @property
    def speedup_real(self) -> float:
        """Mitsuba's time over ours on Stanford-ORB (Table 1)."""
        return self.table1[MITSUBA]["time_s"] / self.table1[OURS]["time_s"]

    @property
    def min_correlation(self) -> float:
        """The smallest of the paper's per-environment entropy-error correlations (Table 2)."""
        return min(r for env, r in self.correlation.items() if env != AVERAGE)

    def ablation_row(self, shadowing: bool, masking: bool) -> AblationRow:
        """The Table 4 row with this (shadowing, masking) pair."""
        return next(r for r in self.table4.values() if (r.shadowing, r.masking) == (shadowing, masking))


def _key(where: str, key: object) -> str:
    return f"{where}.{key}" if where else str(key)


def _mapping(node: object, where: str) -> Mapping[str, object]:
    """A non-empty mapping with string keys."""
    if not isinstance(node, Mapping) or not node:
        raise PaperResultsError(f"key {where or '<top level>'}: expected a non-empty mapping, got {node!r:.60}")
    for key in node:
        if not isinstance(key, str):
            raise PaperResultsError(f"key {_key(where, key)}: labels must be strings")
    return node


def _record(node: object, where: str, fields: Sequence[str]) -> Mapping[str, object]:
    """A mapping with exactly the keys ``fields``."""
    node = _mapping(node, where)
    missing = [f for f in fields if f not in node]
    if missing:
        raise PaperResultsError(f"key {_key(where, missing[0])}: missing")
    unexpected = [k for k in node if k not in fields]
    if unexpected:
        raise PaperResultsError(f"key {_key(where, unexpected[0])}: unexpected (expected {', '.join(fields)})")
    return node


def _number(node: object, where: str) -> float:
    # bool is an int subclass: `true` would otherwise read as 1.0.
    if isinstance(node, bool) or not isinstance(node, (int, float)) or not math.isfinite(node):
        raise PaperResultsError(f"key {where}: expected a number, got {node!r}")
    return float(node)


def _numbers(node: object, where: str, fields: Sequence[str]) -> dict[str, float]:
    record = _record(node, where, fields)
    return {f: _number(record[f], _key(where, f)) for f in fields}


def _flag(node: object, where: str) -> bool:
    if not isinstance(node, bool):
        raise PaperResultsError(f"key {where}: expected true or false, got {node!r}")
    return node


def _label(node: object, where: str) -> str:
    if not isinstance(node, str) or not node:
        raise PaperResultsError(f"key {where}: expected a row label, got {node!r}")
    return node


def _mse_parts(node: object, where: str) -> tuple[float, float, float, float]:
    if not isinstance(node, list) or len(node) != 4:
        raise PaperResultsError(f"key {where}: expected [average, base colour, roughness, metallic], got {node!r}")
    average, base, roughness, metallic = (_number(v, f"{where}[{k}]") for k, v in enumerate(node))
    return average, base, roughness, metallic


def _relight_rows(node: object, where: str) -> dict[str, dict[str, float]]:
    return {label: _numbers(row, _key(where, label), RELIGHT_FIELDS) for label, row in _mapping(node, where).items()}


def _table2(node: object, where: str = "table2"
            ) -> tuple[dict[str, str], dict[str, ParameterRow], str, dict[str, float]]:
    """Environments, rows, the correlated row and the correlation of the paper's Table 2."""
    top = _record(node, where, ("environments", "rows", "correlation"))
    at = _key(where, "environments")
    environments = {kind: _label(name, _key(at, kind)) for kind, name in _mapping(top["environments"], at).items()}
    columns = (*environments.values(), AVERAGE)
    rows = {}
    for label, row in _mapping(top["rows"], _key(where, "rows")).items():
        at = _key(_key(where, "rows"), label)
        record = _record(row, at, ("time_s", "mse"))
        mse = _record(record["mse"], _key(at, "mse"), columns)
        rows[label] = ParameterRow({c: _mse_parts(mse[c], _key(_key(at, "mse"), c)) for c in columns},
                                   _number(record["time_s"], _key(at, "time_s")))
    at = _key(where, "correlation")
    correlation = _record(top["correlation"], at, ("with", "values"))
    correlated = _label(correlation["with"], _key(at, "with"))
    if correlated not in rows:
        raise PaperResultsError(f"key {_key(at, 'with')}: {correlated!r} is not a row of {where}.rows {list(rows)}")
    return environments, rows, correlated, _numbers(correlation["values"], _key(at, "values"), columns)


def _table4(node: object, where: str = "table4") -> dict[str, AblationRow]:
    """The paper's Table 4, checking that each (shadowing, masking) pair has exactly one row."""
    rows = {}
    for label, row in _mapping(node, where).items():
        at = _key(where, label)
        record = _record(row, at, ("shadowing", "masking", *ABLATION_FIELDS))
        rows[label] = AblationRow(_flag(record["shadowing"], _key(at, "shadowing")),
                                  _flag(record["masking"], _key(at, "masking")),
                                  {f: _number(record[f], _key(at, f)) for f in ABLATION_FIELDS})
    pairs = sorted((r.shadowing, r.masking) for r in rows.values())
    if pairs != sorted(product((False, True), repeat=2)):
        raise PaperResultsError(f"key {where}: needs one row per (shadowing, masking) pair, got {pairs}")
    return rows


def parse_paper_results(data: object) -> PaperResults:
    """Check and type the paper's results as loaded from YAML.

    Raises
    ------
    PaperResultsError
        ``key <dotted.path>: <what is wrong>``.
    """
    top = _record(data, "", ("table1", "table2", "table3", "table4", "table5", "table6", "claims"))
    environments, table2, correlated, correlation = _table2(top["table2"])
    paper = PaperResults(
        table1=_relight_rows(top["table1"], "table1"), environments=environments, table2=table2,
        correlation_with=correlated, correlation=correlation,
        table3={label: _numbers(row, _key("table3", label), AGREEMENT_FIELDS)
                for label, row in _mapping(top["table3"], "table3").items()},
        table4=_table4(top["table4"]),
        table5=_relight_rows(top["table5"], "table5"),
        table6={label: _mse_parts(row, _key("table6", label)) for label, row in _mapping(top["table6"], "table6").items()},
        criteria=ClaimCriteria(**_numbers(top["claims"], "claims", CRITERIA_FIELDS)),
    )
    for table, labels in CLAIM_ROWS.items():
        missing = [label for label in labels if label not in getattr(paper, table)]
        if missing:
            raise PaperResultsError(f"key {table}.{missing[0]}: missing (the claims quote it)")
    return paper


def read_paper_results(path: str | PathLike[str]) -> PaperResults:
    """Read and check ``config/paper_results.yaml``.

    Raises
    ------
    PaperResultsError
        One line: ``<path>: key <dotted.path>: <what is wrong>``.
    """
    with open(path) as f:
        data = yaml.safe_load(f)
    try:
        return parse_paper_results(data)
    except PaperResultsError as error:
        raise PaperResultsError(f"{path}: {error}") from None
