"""Tests for freqbrdf.dependencies: the library files each rule declares are the ones its script runs."""

from __future__ import annotations

import modulefinder
import re
from pathlib import Path

import pytest

from freqbrdf.dependencies import script_modules

REPO = Path(__file__).resolve().parents[1]
PACKAGE = REPO / "workflow" / "freqbrdf"
SCRIPTS = sorted((REPO / "workflow" / "scripts").glob("*.py"))


def imported_by_modulefinder(script: Path) -> list[str]:
    """Independent oracle: the source files of the freqbrdf modules Python's bytecode-level
    ModuleFinder reaches, relative to the package directory."""
    finder = modulefinder.ModuleFinder(path=[str(REPO / "workflow")])  # nothing else is findable: fast
    finder.run_script(str(script))
    return sorted(str(Path(module.__file__).relative_to(PACKAGE)) for name, module in finder.modules.items()
                  if name.split(".")[0] == "freqbrdf")


@pytest.mark.parametrize("script", SCRIPTS, ids=lambda p: p.stem)
def test_script_modules_match_what_python_imports(script: Path) -> None:
    assert script_modules(script, PACKAGE) == imported_by_modulefinder(script)


def test_an_edited_module_is_read_again_in_the_same_process(tmp_path: Path) -> None:
    """Modules are parsed once per version: an edit (new size and time) is seen at once."""
    import os

    package = tmp_path / "freqbrdf"
    package.mkdir()
    (package / "__init__.py").write_text("")
    (package / "a.py").write_text("X = 1\n")
    (package / "b.py").write_text("Y = 2\n")
    script = tmp_path / "script.py"
    script.write_text("from freqbrdf import a\n")
    assert script_modules(script, package) == ["__init__.py", "a.py"]
    (package / "a.py").write_text("from . import b\n")
    stat = (package / "a.py").stat()
    os.utime(package / "a.py", ns=(stat.st_atime_ns, stat.st_mtime_ns + 10**9))
    assert script_modules(script, package) == ["__init__.py", "a.py", "b.py"]


def rule_blocks() -> dict[str, str]:
    blocks = {}
    for smk in sorted((REPO / "workflow" / "rules").glob("*.smk")):
        for block in re.split(r"\n(?=rule |use rule )", smk.read_text()):
            if block.startswith("rule "):
                blocks[block.split(":")[0].removeprefix("rule ").strip()] = block
    return blocks


def test_every_rule_declares_the_modules_of_its_own_script() -> None:
    """A rule that runs a script lists ``code=library("<that script>")``: with the derivation
    above, its inputs are then exactly the modules the script imports, transitively."""
    blocks = rule_blocks()
    assert len(blocks) > 15
    for name, block in blocks.items():
        script = re.search(r'script:\s*"\.\./scripts/(\w+)\.py"', block)
        if script is None:
            continue
        declared = re.findall(r'code=library\("(\w+)"\)', block)
        assert declared == [script.group(1)], f"rule {name}: code inputs {declared}, script {script.group(1)}"


def test_transitive_imports_are_followed() -> None:
    """scripts/metrics.py imports freqbrdf.scene.cameras directly and freqbrdf.sphere.sh through
    artefacts -> capture.observations (a hand-kept list had neither); optimise_svbrdf reaches
    the observations through estimate.light."""
    metrics = set(script_modules(REPO / "workflow/scripts/metrics.py", PACKAGE))
    assert {"scene/cameras.py", "sphere/sh.py", "artefacts.py", "capture/observations.py", "report/metrics.py",
            "__init__.py", "scene/__init__.py", "report/__init__.py"} <= metrics
    optimise = set(script_modules(REPO / "workflow/scripts/optimise_svbrdf.py", PACKAGE))
    assert {"capture/observations.py", "estimate/light.py", "estimate/optimise/__init__.py"} <= optimise


def test_subpackages_relative_imports_and_initialisers_are_followed(tmp_path: Path) -> None:
    """Every enclosing ``__init__`` runs and is followed; ``from .. import x`` climbs a level;
    ``from p import name`` reaches a module only when ``name`` is one."""
    package = tmp_path / "freqbrdf"
    for folder, files in {"": {"__init__.py": "", "top.py": ""},
                          "a": {"__init__.py": "from freqbrdf.c import d\n", "b.py": "from ..top import X\n"},
                          "c": {"__init__.py": "", "d.py": "from . import e\n", "e.py": "", "unused.py": ""},
                          "f": {"__init__.py": "def g():\n    pass\n", "h.py": ""}}.items():
        (package / folder).mkdir(parents=True, exist_ok=True)
        for name, text in files.items():
            (package / folder / name).write_text(text)
    script = tmp_path / "script.py"
    script.write_text("import freqbrdf.a.b\nfrom freqbrdf.f import g\n")
    assert script_modules(script, package) == ["__init__.py", "a/__init__.py", "a/b.py", "c/__init__.py", "c/d.py",
                                               "c/e.py", "f/__init__.py", "top.py"]
    (package / "a" / "b.py").write_text("from ... import X\n")
    with pytest.raises(ImportError, match="beyond the freqbrdf package"):
        script_modules(script, package)


def test_the_model_kernels_rerun_only_the_rules_that_fit_the_model() -> None:
    """The model's compiled kernels (`freqbrdf.estimate.optimise.kernels`, `freqbrdf.sphere.lobes`) are
    not reached from the scripts that build, render and extract observations, so changing the model
    does not rerun the renders (numba's thread setter lives apart, in `freqbrdf.util.threads`, for that)."""
    model = {"estimate/optimise/kernels.py", "sphere/lobes.py", "estimate/optimise/__init__.py"}
    for script in ("build_object", "render_capture", "extract_observations", "fit_sh"):
        modules = set(script_modules(REPO / f"workflow/scripts/{script}.py", PACKAGE))
        assert not modules & model, (script, sorted(modules & model))
    assert model <= set(script_modules(REPO / "workflow/scripts/optimise_svbrdf.py", PACKAGE))


def test_a_missing_module_is_named(tmp_path: Path) -> None:
    script = tmp_path / "rule.py"
    script.write_text("from freqbrdf.nonexistent import thing\n")
    with pytest.raises(FileNotFoundError, match="imports freqbrdf.nonexistent"):
        script_modules(script, PACKAGE)


def third_party_imports(files: list[Path]) -> set[str]:
    """Top-level names of every non-standard-library module imported anywhere in ``files``
    (function-level imports included)."""
    import ast
    import sys

    names = set()
    for path in files:
        for node in ast.walk(ast.parse(path.read_text())):
            if isinstance(node, ast.Import):
                names.update(alias.name.split(".")[0] for alias in node.names)
            elif isinstance(node, ast.ImportFrom) and node.level == 0 and node.module:
                names.add(node.module.split(".")[0])
    return {n for n in names if n not in sys.stdlib_module_names and n not in ("freqbrdf", "__future__")}


def declared(extra: str | None = None) -> set[str]:
    """Distribution names (lower case) pinned in workflow/pyproject.toml's dependencies or an extra."""
    import tomllib

    project = tomllib.loads((REPO / "workflow" / "pyproject.toml").read_text())["project"]
    pins = project["dependencies"] if extra is None else project["optional-dependencies"][extra]
    for pin in pins:
        assert re.fullmatch(r"[A-Za-z0-9_.\-]+==[0-9][A-Za-z0-9_.]*", pin), f"pyproject: {pin!r} is not pinned with =="
    return {pin.split("==")[0].lower() for pin in pins}


def test_every_imported_package_is_declared() -> None:
    from importlib.metadata import packages_distributions

    distributions = packages_distributions()
    library = third_party_imports(sorted(PACKAGE.rglob("*.py")) + SCRIPTS)
    missing = sorted(
        name for name in library
        if not {d.lower() for d in distributions.get(name, [name])} & (declared() | declared("workflow"))
    )
    assert not missing, f"imported but not declared in workflow/pyproject.toml: {missing}"
    # Snakemake is the workflow's (extra "workflow"): the library imports it only inside
    # check_config, which runs in the Snakefile, so freqbrdf installs beside any Snakemake
    assert "snakemake" not in declared() and "snakemake" in declared("workflow")


# conda-forge's names of the PyPI distributions whose names differ there
# (matplotlib-base: matplotlib without a GUI toolkit).
CONDA_NAMES = {"matplotlib-base": "matplotlib"}


def conda_env_pins(path: Path) -> tuple[dict[str, str], str]:
    """PyPI name (lower case) -> version of every package of a conda env file, conda's and
    pip's alike, and the Python spec."""
    import yaml

    pins, python = {}, None
    for entry in yaml.safe_load(path.read_text())["dependencies"]:
        if isinstance(entry, dict):
            for pin in entry["pip"]:
                assert re.fullmatch(r"[A-Za-z0-9_.\-]+==[0-9][A-Za-z0-9_.]*", pin), f"{path.name}: pip entry {pin!r} is not a pin"
                name, version = pin.split("==")
                pins[name.lower()] = version
            continue
        name, _, spec = entry.partition(" ")
        if name == "python":
            python = spec
        elif name != "pip":
            assert re.fullmatch(r"==[0-9][A-Za-z0-9_.]*", spec), f"{path.name}: {entry!r} is not pinned with =="
            pins[CONDA_NAMES.get(name, name).lower()] = spec.removeprefix("==")
    return pins, python


def test_conda_env_has_exactly_the_pyproject_pins() -> None:
    import tomllib

    project = tomllib.loads((REPO / "workflow" / "pyproject.toml").read_text())["project"]
    expected = {name.lower(): version for name, version in (pin.split("==") for pin in project["dependencies"])}
    env_file = REPO / "workflow" / "envs" / "freqbrdf.yaml"
    pins, python = conda_env_pins(env_file)
    assert pins == expected
    # The Python it creates is one pyproject accepts (requires-python >=3.11,<3.13).
    assert python is not None and project["requires-python"] == ">=3.11,<3.13" and python in ("=3.11", "=3.12")
    # Snakemake copies the file elsewhere before creating the environment: no path may be relative to it.
    assert "../" not in env_file.read_text() and "-e " not in env_file.read_text()


def test_conda_env_pins_are_read_from_both_sections(tmp_path: Path) -> None:
    env = tmp_path / "env.yaml"
    env.write_text("dependencies:\n  - python =3.11\n  - pip\n  - matplotlib-base ==1.0\n  - pip:\n      - Mitsuba==2.0\n")
    assert conda_env_pins(env) == ({"matplotlib": "1.0", "mitsuba": "2.0"}, "=3.11")
    env.write_text("dependencies:\n  - numpy >=2\n")
    with pytest.raises(AssertionError, match="not pinned"):
        conda_env_pins(env)


def module_graph() -> dict[str, set[str]]:
    """Package-relative module files -> the package modules their module-level imports name
    (imports inside functions run later and cannot make an import cycle)."""
    import ast

    def target(dotted: str) -> str | None:
        base = PACKAGE.joinpath(*dotted.split("."))
        for candidate in (base / "__init__.py", base.with_suffix(".py")):
            if candidate.is_file():
                return str(candidate.relative_to(PACKAGE))
        return None

    graph = {}
    for path in sorted(PACKAGE.rglob("*.py")):
        edges = set()
        for node in ast.parse(path.read_text()).body:
            if isinstance(node, ast.ImportFrom) and node.level == 0 and (node.module or "").startswith("freqbrdf."):
                base = node.module.removeprefix("freqbrdf.")
                edges |= {t for alias in node.names for t in [target(f"{base}.{alias.name}") or target(base)] if t}
            elif isinstance(node, ast.Import):
                edges |= {t for alias in node.names if alias.name.startswith("freqbrdf.")
                          for t in [target(alias.name.removeprefix("freqbrdf."))] if t}
        graph[str(path.relative_to(PACKAGE))] = edges - {str(path.relative_to(PACKAGE))}
    return graph


def test_no_module_level_import_cycle() -> None:
    graph = module_graph()
    assert graph["estimate/optimise/solve.py"] >= {"estimate/optimise/model.py", "estimate/optimise/kernels.py"}
    state: dict[str, int] = {}  # 1: on the current path, 2: done

    def visit(node: str, path: list[str]) -> None:
        state[node] = 1
        for nxt in sorted(graph.get(node, ())):
            assert state.get(nxt) != 1, f"import cycle: {' -> '.join(path[path.index(nxt):] + [nxt])}"
            if nxt not in state:
                visit(nxt, path + [nxt])
        state[node] = 2

    for start in sorted(graph):
        if start not in state:
            visit(start, [start])
