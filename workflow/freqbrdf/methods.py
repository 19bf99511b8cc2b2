"""The registry of SVBRDF estimation methods: every method is one entry here.

A method is named once, in :data:`METHODS`; the workflow's wildcard
constraints (``rules/common.smk``), the check of ``config methods``
(:func:`freqbrdf.config.check_config`), the report's tables and the benchmarks
all read this registry. An entry says which rule estimates the method, what
its forward model includes, what it starts from, and which row of each of the
paper's tables it stands beside (Wiersma et al. 2024, Tables 1, 2, 4, 5 and 6).

Adding an estimator (README "Adding a method", docs/modules.md): one entry here and, if no
existing rule estimates it, one function and one rule.
"""

from __future__ import annotations

import re
from collections.abc import Mapping
from dataclasses import dataclass, field
from types import MappingProxyType

ESTIMATOR_RULES = ("spectrum_search", "optimise_svbrdf", "mitsuba", "merge_svbrdf")
"""The rules that write an estimate (`freqbrdf.layout.ESTIMATE`)."""

FREQUENCY_RULES = ("spectrum_search", "optimise_svbrdf")
"""The rules of the frequency-domain methods: they need the observations, Mitsuba's methods do not."""

PAPER_TABLES = ("table1", "table2", "table4", "table5", "table6")

MERGE_MAPS = ("entropy", "posterior")
"""What a merge takes each texel by: the capture of lowest spectrum entropy (the paper's Table 6)
or of lowest expected error under the fit's posterior (`freqbrdf.estimate.optimise.posterior.expected_error_atlas`;
only for estimates of ``optimise_svbrdf``, which write one)."""


@dataclass(frozen=True)
class Method:
    """One SVBRDF estimation method.

    Attributes
    ----------
    name : str
        The name used in config ``methods``, the ``{method}`` wildcard, result
        paths and ``metrics.csv``.
    label : str
        The display name in tables and figures.
    rule : str
        The rule that estimates it (one of :data:`ESTIMATOR_RULES`).
    start : str or None
        The method whose estimate this one starts from (``freq+mitsuba``
        fine-tunes ``freq``; ``merge_svbrdf`` merges this method's estimates
        of every capture of the object); None: the rule's own start.
    shadowing, masking : bool
        Smith G1 on the incoming light (shadowing) and on the outgoing
        direction (masking) in the frequency-domain model (paper section 4.2;
        the Table 4 ablation). Only read by ``optimise_svbrdf``.
    prefiltered : bool
        The light is low-passed by the views' band limit a' before the lobe
        is applied (paper section 4.2), as the paper does.
    entropy_scored : bool
        ``metrics`` correlates the entropy map with this method's per-texel error.
    merged_by : str or None
        For the methods of ``merge_svbrdf``: the uncertainty map (one of :data:`MERGE_MAPS`)
        whose lowest capture each texel is taken from.
    paper_rows : Mapping[str, str]
        The row of each of the paper's tables (keys of :data:`PAPER_TABLES`)
        that this method stands beside; row labels as in
        ``config/paper_results.yaml``.
    """

    name: str
    label: str
    rule: str
    start: str | None = None
    shadowing: bool = True
    masking: bool = True
    prefiltered: bool = False
    entropy_scored: bool = False
    merged_by: str | None = None
    paper_rows: Mapping[str, str] = field(default_factory=dict)

    def __post_init__(self) -> None:
        if self.rule not in ESTIMATOR_RULES:
            raise ValueError(f"method {self.name!r}: rule must be one of {ESTIMATOR_RULES}, got {self.rule!r}")
        if self.rule == "merge_svbrdf" and (self.merged_by not in MERGE_MAPS or self.start is None):
            raise ValueError(f"method {self.name!r} of rule merge_svbrdf needs a start and merged_by one of "
                             f"{MERGE_MAPS}, got start {self.start!r}, merged_by {self.merged_by!r}")
        if self.rule != "merge_svbrdf" and self.merged_by is not None:
            raise ValueError(f"method {self.name!r}: merged_by is for rule merge_svbrdf only, got {self.merged_by!r}")
        unknown = set(self.paper_rows) - set(PAPER_TABLES)
        if unknown:
            raise ValueError(f"method {self.name!r}: paper_rows names unknown tables {sorted(unknown)}")
        object.__setattr__(self, "paper_rows", MappingProxyType(dict(self.paper_rows)))

    @property
    def has_posterior(self) -> bool:
        """Whether its estimates carry a per-texel posterior (``std_*.exr``): those of ``optimise_svbrdf``."""
        return self.rule == "optimise_svbrdf"


def build_registry(*methods: Method) -> Mapping[str, Method]:
    """A read-only name -> method mapping, checking that names are unique and starts registered."""
    registry = {m.name: m for m in methods}
    if len(registry) != len(methods):
        raise ValueError("method names in the registry must be unique")
    for m in methods:
        if m.start is not None and m.start not in registry:
            raise ValueError(f"method {m.name!r} starts from {m.start!r}, which is not registered")
        if m.merged_by == "posterior" and not registry[m.start].has_posterior:
            raise ValueError(f"method {m.name!r} merges by the posterior, which {m.start!r} does not write")
    return MappingProxyType(registry)


METHODS: Mapping[str, Method] = build_registry(
    Method("spectrum", "Ours-Spectrum Only", "spectrum_search", shadowing=False, masking=False,
           prefiltered=True, paper_rows={"table1": "Ours-Spectrum Only", "table2": "Ours-Spectrum Only"}),
    Method("freq", "Ours", "optimise_svbrdf", entropy_scored=True,
           paper_rows={"table1": "Ours", "table2": "Ours", "table4": "Shadowing + masking",
                       "table5": "Ours, no fine-tuning (Table 1)"}),
    Method("freq_paper", "Ours, paper's band limit", "optimise_svbrdf", prefiltered=True),
    Method("freq_noshadow", "Ours, no shadowing", "optimise_svbrdf", shadowing=False,
           paper_rows={"table4": "Masking"}),
    Method("freq_nomask", "Ours, no masking", "optimise_svbrdf", masking=False,
           paper_rows={"table4": "Shadowing"}),
    Method("rh2001", "RH2001 (neither)", "optimise_svbrdf", shadowing=False, masking=False,
           paper_rows={"table4": "Neither"}),
    Method("mitsuba", "Mitsuba", "mitsuba", entropy_scored=True,
           paper_rows={"table1": "Mitsuba", "table2": "Mitsuba", "table5": "Full optimization - Constant"}),
    Method("freq+mitsuba", "Ours+Mitsuba", "mitsuba", start="freq",
           paper_rows={"table1": "Ours+Mitsuba (1 epoch)", "table5": "Ours"}),
    # paper Table 6 merges Mitsuba's results: its "Average" row is Mitsuba's Table 2 average
    Method("mitsuba_merged", "Mitsuba, entropy-merged", "merge_svbrdf", start="mitsuba", merged_by="entropy",
           paper_rows={"table6": "argmin Entropy"}),
    # by the posterior: it merges better than the entropy on the captured tuning set (docs/uncertainty.md)
    Method("freq_merged", "Ours, posterior-merged", "merge_svbrdf", start="freq", merged_by="posterior"),
)
"""Every method, in the order of tables and figures."""


def get_method(name: str, rule: str | None = None) -> Method:
    """The registered method ``name``; with ``rule``, one that this rule estimates.

    Raises
    ------
    ValueError
        Naming the method and the registered names (or those of ``rule``).
    """
    candidates = methods_of(rule) if rule is not None else tuple(METHODS)
    if name not in candidates:
        where = f" estimated by rule {rule}" if rule is not None else ""
        raise ValueError(f"method must be one of the methods{where} {candidates}, got {name!r}")
    return METHODS[name]


def methods_of(rule: str) -> tuple[str, ...]:
    """Names of the methods that ``rule`` estimates, in registry order."""
    if rule not in ESTIMATOR_RULES:
        raise ValueError(f"rule must be one of {ESTIMATOR_RULES}, got {rule!r}")
    return tuple(name for name, m in METHODS.items() if m.rule == rule)


def wildcard_pattern(names: tuple[str, ...] | list[str]) -> str:
    """A regular expression matching exactly the method names given (a ``{method}`` constraint)."""
    if not names:
        raise ValueError("a method wildcard pattern needs at least one method")
    return "|".join(re.escape(name) for name in names)


def paper_method(table: str, row: str) -> str | None:
    """Our method beside row ``row`` of the paper's table ``table``; None if none is."""
    if table not in PAPER_TABLES:
        raise ValueError(f"table must be one of {PAPER_TABLES}, got {table!r}")
    matches = [name for name, m in METHODS.items() if m.paper_rows.get(table) == row]
    return matches[0] if matches else None


def ablation_method(shadowing: bool, masking: bool) -> str:
    """The method of the Table 4 ablation with this (shadowing, masking) pair."""
    for name, m in METHODS.items():
        if "table4" in m.paper_rows and (m.shadowing, m.masking) == (shadowing, masking):
            return name
    raise ValueError(f"no Table 4 method has shadowing={shadowing}, masking={masking}")
