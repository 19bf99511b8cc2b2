"""The method registry: every rule's methods, wildcard patterns and paper rows."""

import re

import pytest

from freqbrdf import methods


def test_every_method_has_one_estimating_rule_and_patterns_do_not_overlap():
    by_rule = {rule: methods.methods_of(rule) for rule in methods.ESTIMATOR_RULES}
    assert sorted(n for names in by_rule.values() for n in names) == sorted(methods.METHODS)
    for rule, names in by_rule.items():
        pattern = re.compile(methods.wildcard_pattern(names))
        for name in methods.METHODS:
            # A rule's wildcard constraint matches its own methods and no other rule's.
            assert bool(pattern.fullmatch(name)) == (name in names), (rule, name)


def test_wildcard_pattern_escapes_names():
    pattern = re.compile(methods.wildcard_pattern(["freq+mitsuba"]))
    assert pattern.fullmatch("freq+mitsuba")
    assert not pattern.fullmatch("freqqmitsuba")
    with pytest.raises(ValueError, match="at least one"):
        methods.wildcard_pattern([])


def test_get_method_names_the_bad_value():
    assert methods.get_method("freq", "optimise_svbrdf").shadowing
    with pytest.raises(ValueError, match=r"rule optimise_svbrdf .*'mitsuba'"):
        methods.get_method("mitsuba", "optimise_svbrdf")
    with pytest.raises(ValueError, match="'nope'"):
        methods.get_method("nope")


def test_paper_rows_and_ablation():
    assert methods.paper_method("table1", "Ours") == "freq"
    assert methods.paper_method("table5", "Ours") == "freq+mitsuba"
    assert methods.paper_method("table1", "NVDiffRec") is None
    assert methods.ablation_method(False, False) == "rh2001"
    assert methods.ablation_method(True, True) == "freq"
    # Each (shadowing, masking) pair of Table 4 has exactly one method.
    pairs = [(m.shadowing, m.masking) for m in methods.METHODS.values() if "table4" in m.paper_rows]
    assert sorted(pairs) == [(False, False), (False, True), (True, False), (True, True)]


def test_registry_rejects_inconsistent_entries():
    with pytest.raises(ValueError, match="rule must be one of"):
        methods.Method("x", "X", "render_capture")
    with pytest.raises(ValueError, match="unknown tables"):
        methods.Method("x", "X", "optimise_svbrdf", paper_rows={"table9": "X"})
    with pytest.raises(ValueError, match="not registered"):
        methods.build_registry(methods.Method("x", "X", "mitsuba", start="y"))
    with pytest.raises(ValueError, match="needs a start and merged_by one of .* merged_by None"):
        methods.Method("x", "X", "merge_svbrdf", start="y")
    with pytest.raises(ValueError, match="merged_by 'bogus'"):
        methods.Method("x", "X", "merge_svbrdf", start="y", merged_by="bogus")
    with pytest.raises(ValueError, match="got start None"):
        methods.Method("x", "X", "merge_svbrdf", merged_by="posterior")
    for bad in ("entropy", "bogus"):
        with pytest.raises(ValueError, match=f"merged_by is for rule merge_svbrdf only, got '{bad}'"):
            methods.Method("x", "X", "optimise_svbrdf", merged_by=bad)
    with pytest.raises(ValueError, match="merges by the posterior, which 'm' does not write"):
        methods.build_registry(methods.Method("m", "M", "mitsuba"),
                               methods.Method("x", "X", "merge_svbrdf", start="m", merged_by="posterior"))


def test_every_estimating_rule_exists_and_constrains_its_methods():
    """Each rule of ESTIMATOR_RULES is a rule of the workflow whose {method} is constrained by the registry
    (spectrum_search writes the literal 'spectrum' path instead)."""
    from pathlib import Path

    text = "\n".join(p.read_text() for p in sorted((Path(__file__).parents[1] / "workflow" / "rules").glob("*.smk")))
    for rule in methods.ESTIMATOR_RULES:
        block = text.split(f"rule {rule}:", 1)
        assert len(block) == 2, f"rule {rule} is not defined in rules/"
        body = block[1].split("\nrule ", 1)[0]
        if rule == "spectrum_search":
            assert methods.methods_of(rule) == ("spectrum",) and 'fill(layout.ESTIMATE, method="spectrum")' in body
        else:
            assert f'method=wildcard_pattern(methods_of("{rule}"))' in body, rule
