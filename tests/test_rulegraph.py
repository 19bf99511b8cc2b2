"""The report's rule graph: each rule once, in an order its edges follow (freqbrdf.report.rulegraph)."""

from freqbrdf.report.rulegraph import graph_spec, rule_order


def test_a_rule_at_two_levels_is_one_node_after_everything_it_needs():
    # build_env's procedural jobs sit at level 0, its captured ones after fetch (level 1): Snakemake
    # drew it twice; here once, after fetch, though its first level ties fetch's.
    first = {"fetch": 0, "build_env": 0, "render": 1, "relight": 2, "all": 3}
    edges = {("fetch", "build_env"), ("build_env", "render"), ("build_env", "relight"), ("render", "relight"),
             ("relight", "all"), ("render", "all")}
    order = rule_order(first, edges)
    assert order == ["fetch", "build_env", "render", "relight", "all"]
    spec, _, height = graph_spec(order, edges)
    assert [n["rule"] for n in spec["nodes"]] == order and height == 4 * 50
    links = spec["links"] + spec["links_direct"]
    assert len(links) == len(edges) and all(link["source"] < link["target"] for link in links)
    assert {(link["sourcerule"], link["targetrule"]) for link in spec["links_direct"]} == {
        ("fetch", "build_env"), ("build_env", "render"), ("render", "relight"), ("relight", "all")}


def test_ties_go_by_first_level_then_name_and_a_cycle_comes_whole_before_what_follows_it():
    assert rule_order({"b": 0, "a": 0, "c": -1}, set()) == ["c", "a", "b"]
    # x and y depend on each other; z follows y but has the earliest first level of the three
    order = rule_order({"w": 0, "x": 2, "y": 3, "z": 1}, {("w", "x"), ("x", "y"), ("y", "x"), ("y", "z")})
    assert order == ["w", "x", "y", "z"]


def test_self_edges_and_repeated_edges_draw_no_link_twice():
    spec, _, _ = graph_spec(["a", "b"], [("a", "b"), ("a", "b"), ("a", "a")])
    assert spec["links_direct"] == [{"target": 1, "source": 0, "sourcerule": "a", "targetrule": "b", "value": 1}]
    assert spec["links"] == []
