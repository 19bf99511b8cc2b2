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
    """The rules, each once, every rule after the rules it depends on; the rules of a cycle
    (rules whose jobs depend on each other's both ways) together, after what the cycle depends
    on. Ties go by first level, then name.

    Parameters
    ----------
    first_level : mapping
        Rule -> the first level of the job DAG (Snakemake's ``dag.toposorted()``) with a job of it.
    edges : iterable of (str, str)
        (upstream rule, downstream rule) for every job dependency.

    Returns
    -------
    list of str
        Every rule of ``first_level`` once.
    """
    key = {rule: (level, rule) for rule, level in first_level.items()}
    upstream: dict[str, set[str]] = {rule: set() for rule in key}
    downstream: dict[str, set[str]] = {rule: set() for rule in key}
    for source, target in edges:
        if source != target:
            upstream[target].add(source)
            downstream[source].add(target)
    reach = {rule: _reachable(rule, downstream) for rule in key}
    # the strongly connected component of each rule: itself and the rules on a cycle through it
    component = {rule: frozenset({rule} | {r for r in reach[rule] if rule in reach[r]}) for rule in key}
    order: list[str] = []
    placed: set[str] = set()
    while len(order) < len(key):
        free = {component[r] for r in key if r not in placed
                and all(upstream[m] <= placed | component[r] for m in component[r])}
        chosen = min(free, key=lambda members: min(key[m] for m in members))
        order += sorted(chosen, key=key.get)
        placed |= chosen
    return order


def _reachable(rule: str, downstream: Mapping[str, set[str]]) -> set[str]:
    """The rules downstream of ``rule``, at any distance."""
    seen: set[str] = set()
    stack = [rule]
    while stack:
        for nxt in downstream[stack.pop()]:
            if nxt not in seen:
                seen.add(nxt)
                stack.append(nxt)
    return seen


def graph_spec(order: list[str], edges: Iterable[tuple[str, str]]) -> tuple[dict[str, Any], int, int]:
    """The report template's graph data for rules in ``order``.

    Returns
    -------
    spec : dict
        ``nodes`` (rule, fixed x and y), and the links between neighbours (``links_direct``, drawn
        straight) apart from the others (``links``, drawn as arcs), each distinct (upstream,
        downstream) rule pair once, without self-links.
    xmax, ymax : int
        The template's x and y extents.
    """
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
    """`graph_spec` of a Snakemake DAG (``snakemake.dag.DAG``) in `rule_order`, in place of
    ``snakemake.report.rulegraph_spec.rulegraph_spec``: the same argument and result."""
    first_level: dict[str, int] = {}
    for level, jobs in enumerate(dag.toposorted()):
        for job in jobs:
            first_level.setdefault(job.rule.name, level)
    edges = {(upstream.rule.name, job.rule.name) for job in dag.jobs for upstream in dag.dependencies[job]}
    return graph_spec(rule_order(first_level, edges), edges)
