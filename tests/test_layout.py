"""The code-layout rules of the README's "Layout and module map": short modules and functions, no private names
imported across modules, and scripts that take every path from Snakemake rather than building one."""

from __future__ import annotations

import ast
from pathlib import Path

import pytest

REPO = Path(__file__).resolve().parents[1]
SOURCES = sorted((REPO / "workflow").rglob("*.py"))
SCRIPTS = sorted((REPO / "workflow" / "scripts").glob("*.py"))
BENCHES = sorted((REPO / "bench").glob("*.py"))
TEST_MODULES = {p.stem for p in (REPO / "tests").glob("*.py")}
MAX_FUNCTION_LINES = 80
MAX_MODULE_LINES = 600


def long_functions(source: str) -> list[tuple[str, int]]:
    """(name, lines) of every function or method in ``source`` longer than the limit, docstring included."""
    return [(node.name, node.end_lineno - node.lineno + 1) for node in ast.walk(ast.parse(source))
            if isinstance(node, ast.FunctionDef | ast.AsyncFunctionDef)
            and node.end_lineno - node.lineno + 1 > MAX_FUNCTION_LINES]


def private_imports(source: str) -> list[str]:
    """Names starting with an underscore that ``source`` imports from another module."""
    return [f"{node.module}.{alias.name}" for node in ast.walk(ast.parse(source))
            if isinstance(node, ast.ImportFrom) and node.module != "__future__"
            for alias in node.names if alias.name.startswith("_")]


def results_paths(source: str) -> list[str]:
    """String constants (f-string parts included) of ``source`` that start a ``results/`` path."""
    return [node.value for node in ast.walk(ast.parse(source))
            if isinstance(node, ast.Constant) and isinstance(node.value, str)
            and node.value.lstrip("./").startswith("results/")]


def test_the_checks_find_what_they_look_for() -> None:
    body = "\n".join(f"    x = {i}" for i in range(MAX_FUNCTION_LINES))
    assert long_functions(f"def f():\n{body}\n") == [("f", MAX_FUNCTION_LINES + 1)]
    assert long_functions(f"def f():\n{body[:-10]}\n") == []
    assert private_imports("from freqbrdf.sphere.sh import _check, eval_sh\nfrom .io import read_exr") == ["freqbrdf.sphere.sh._check"]
    assert results_paths('p = f"results/estimates/{obj}"\nq = "see results/ in the docs"') == ["results/estimates/"]


@pytest.mark.parametrize("path", SOURCES, ids=lambda p: str(p.relative_to(REPO / "workflow")))
def test_functions_are_at_most_80_lines_and_import_no_private_names(path: Path) -> None:
    source = path.read_text()
    assert long_functions(source) == []
    assert private_imports(source) == []


@pytest.mark.parametrize("path", SOURCES, ids=lambda p: str(p.relative_to(REPO / "workflow")))
def test_modules_are_at_most_600_lines(path: Path) -> None:
    assert len(path.read_text().splitlines()) <= MAX_MODULE_LINES


def test_the_library_is_laid_out_in_subpackages() -> None:
    """Beside the contracts the rules see, every module lives in a subpackage of its stage."""
    package = REPO / "workflow" / "freqbrdf"
    top = sorted(p.stem for p in package.glob("*.py"))
    assert top == ["__init__", "artefacts", "config", "dependencies", "layout", "methods"]
    assert all((d / "__init__.py").is_file() for d in package.iterdir() if d.is_dir() and any(d.glob("*.py")))


@pytest.mark.parametrize("path", SCRIPTS, ids=lambda p: p.stem)
def test_scripts_build_no_results_path(path: Path) -> None:
    assert results_paths(path.read_text()) == []


@pytest.mark.parametrize("path", [p for p in SOURCES if p.name != "layout.py"] + BENCHES,
                         ids=lambda p: str(p.relative_to(REPO)))
def test_results_paths_are_written_only_in_the_layout_module(path: Path) -> None:
    """Every ``results/`` path comes from `freqbrdf.layout` (the rules use it too), so moving
    an artefact is a change in one place; not even a docstring spells one out."""
    assert "results/" not in path.read_text()


@pytest.mark.parametrize("path", BENCHES, ids=lambda p: p.stem)
def test_benches_import_only_the_library(path: Path) -> None:
    """A bench is run as a user runs it, beside the installed library: it imports no test module."""
    source = path.read_text()
    imported = {alias.name.split(".")[0] for node in ast.walk(ast.parse(source)) if isinstance(node, ast.Import)
                for alias in node.names}
    imported |= {node.module.split(".")[0] for node in ast.walk(ast.parse(source))
                 if isinstance(node, ast.ImportFrom) and node.module and node.level == 0}
    assert not imported & TEST_MODULES
    assert '"tests"' not in source


def test_fill_keeps_the_fields_it_is_not_given() -> None:
    from freqbrdf import layout

    assert layout.fill(layout.ESTIMATE, method="spectrum") == "results/estimates/{object}/{env}/{poses}/spectrum"
    assert layout.fill(layout.CAPTURE, object="a", env="b", split="test") == "results/captures/a/b/test"
    assert layout.log("fit_sh", "{object}") == "results/logs/fit_sh/{object}.log"
    assert layout.benchmark("metrics") == "results/benchmarks/metrics.tsv"
    templates = [v for k, v in vars(layout).items() if k.isupper() and isinstance(v, str) and k != "TRUTH"]
    assert all(t.startswith(layout.RESULTS + "/") for t in templates if t != layout.RESULTS)
