"""The rule graph of the Snakemake report, each rule drawn once.

Snakemake 9's report (``snakemake.report.rulegraph_spec``) lays the graph out as a column of
nodes, one per rule and *level* of the job DAG: a rule whose jobs sit at several depths (an
environment built from the asset package and one built procedurally; the relighting of an
estimate and of a merge of estimates) is drawn once per depth, with its edges split among the
copies. Here the nodes are the rules, in an order in which every edge points down where the rule
graph allows it (a topological order, ties broken by the first level a rule has jobs at, then
its name), in the same Vega specification the report's template reads; the Snakefile puts
`rulegraph_spec` in the place of Snakemake's when it builds a report.
"""

from __future__ import annotations

from collections.abc import Iterable, Mapping
from typing import Any

__all__ = ["rule_order", "graph_spec", "rulegraph_spec"]

_STEP = 50  # vertical distance between nodes, in the template's units (Snakemake's own)


def rule_order(first_level: Mapping[str, int], edges: Iterable[tuple[str, str]]) -> list[str]:
    """The rules, each once, every rule after the rules it depends on where the rule graph is
    acyclic; ties (and a cycle's rules, once no rule is free) go by first level, then name.

    Parameters
    ----------
    first_level : mapping
        Rule -> the first level of the job DAG (Snakemake's ``dag.toposorted()``) with a job of it.
    edges : iterable of (str, str)
        (upstream rule, downstream rule) for every job dependency.
    """
    key = {rule: (level, rule) for rule, level in first_level.items()}
    upstream = {rule: set() for rule in key}
    for source, target in edges:
        if source != target:
            upstream[target].add(source)
    order, placed = [], set()
    while len(order) < len(key):
        free = [rule for rule in key if rule not in placed and upstream[rule] <= placed]
        rule = min(free or (r for r in key if r not in placed), key=key.get)
        order.append(rule)
        placed.add(rule)
    return order


def graph_spec(order: list[str], edges: Iterable[tuple[str, str]]) -> tuple[dict[str, Any], int, int]:
    """The report template's graph data for rules in ``order``: nodes, and the links between
    neighbours (``links_direct``, drawn straight) apart from the others (drawn as arcs), each
    distinct (upstream, downstream) rule pair once; with the template's x and y extents."""
    index = {rule: i for i, rule in enumerate(order)}
    nodes = [{"rule": rule, "fx": 10, "fy": i * _STEP} for i, rule in enumerate(order)]
    links, direct = [], []
    for source, target in sorted(set(edges), key=lambda edge: (index[edge[1]], index[edge[0]])):
        if source == target:
            continue
        link = {"target": index[target], "source": index[source], "sourcerule": source, "targetrule": target, "value": 1}
        (direct if index[target] - index[source] == 1 else links).append(link)
    return {"nodes": nodes, "links": links, "links_direct": direct}, 100, max((n["fy"] for n in nodes), default=0)


def rulegraph_spec(dag: Any) -> tuple[dict[str, Any], int, int]:
    """`graph_spec` of a Snakemake DAG, in place of ``snakemake.report.rulegraph_spec.rulegraph_spec``
    (same arguments and result)."""
    first_level: dict[str, int] = {}
    for level, jobs in enumerate(dag.toposorted()):
        for job in jobs:
            first_level.setdefault(job.rule.name, level)
    edges = {(upstream.rule.name, job.rule.name) for job in dag.jobs for upstream in dag.dependencies[job]}
    return graph_spec(rule_order(first_level, edges), edges)
