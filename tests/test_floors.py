"""The floors of the freqbrdf package (docs/modules.md, "Floors"): no import climbs, and an
edit to the evaluation or the exports reruns no estimator.

A rule's code inputs are its script's transitive imports (`freqbrdf.dependencies`), so an
import from a lower floor to a higher one makes every edit up there rerun the rules below:
a figure edit reran every fit while ``artefacts`` imported the report's plots.
"""

from __future__ import annotations

import os
import re
import shutil
from pathlib import Path

import pytest

from freqbrdf.dependencies import package_imports, script_modules
from workflow_runs import planned_jobs, snakemake

REPO = Path(__file__).resolve().parents[1]
PACKAGE = REPO / "workflow" / "freqbrdf"

FLOORS = (
    {"util", "methods", "layout", "dependencies"},
    {"sphere"},
    {"scene"},
    {"artefacts"},
    {"capture"},
    {"estimate"},
    {"export", "report"},
    {"studies"},
    {"config"},
)
"""From the bottom up: a module imports from its own part, from lower floors, never from a
higher floor nor from another part of its own floor. Scripts and benches stand above them all."""

ESTIMATORS = ("render_capture", "fit_sh", "spectrum_search", "optimise_svbrdf", "mitsuba")
"""Rules whose jobs take minutes to hours: nothing of the evaluation (``report``) or the
exports may be among their code inputs, so that editing those reruns none of them."""


def floor_of(part: str) -> int:
    """Index in `FLOORS` of a top-level module or subpackage."""
    for level, parts in enumerate(FLOORS):
        if part in parts:
            return level
    raise KeyError(f"freqbrdf.{part} is on no floor: add it to FLOORS here and to docs/modules.md")


def climbing_imports(graph: dict[str, frozenset[str]]) -> list[str]:
    """``"importer -> imported"`` for every import that goes up a floor or across one."""
    found = []
    for module, imports in sorted(graph.items()):
        if not module:  # freqbrdf/__init__.py: the package's docstring, imports nothing
            continue
        part = module.split(".")[0]
        for target in sorted(imports):
            other = target.split(".")[0]
            if target and other != part and floor_of(other) >= floor_of(part):
                found.append(f"{module} -> {target}")
    return found


def test_every_part_of_the_package_is_on_a_floor() -> None:
    parts = {name.split(".")[0] for name in package_imports(PACKAGE) if name}
    assert sorted(p for p in parts if not any(p in floor for floor in FLOORS)) == []
    assert sorted(p for floor in FLOORS for p in floor if p not in parts) == []  # no floor names a gone module


def test_no_import_climbs_a_floor() -> None:
    assert climbing_imports(package_imports(PACKAGE)) == []


@pytest.mark.parametrize(("module", "line", "expected"), [
    ("util/io.py", "def _planted():\n    from freqbrdf.report import metrics\n", "util.io -> report.metrics"),
    ("artefacts.py", "from freqbrdf.capture.observations import tangent_frame\n",
     "artefacts -> capture.observations"),
    ("report/figures.py", "from freqbrdf.export import gltf\n", "report.figures -> export.gltf"),
], ids=["function-local", "module-level", "across-a-floor"])
def test_a_planted_back_import_is_reported(tmp_path: Path, module: str, line: str, expected: str) -> None:
    package = tmp_path / "freqbrdf"
    shutil.copytree(PACKAGE, package, ignore=shutil.ignore_patterns("web", "__pycache__"))
    with (package / module).open("a") as f:
        f.write("\n\n" + line)
    assert expected in climbing_imports(package_imports(package))


@pytest.mark.parametrize("script", ESTIMATORS)
def test_estimators_run_no_evaluation_or_export_code(script: str) -> None:
    modules = script_modules(REPO / "workflow" / "scripts" / f"{script}.py", PACKAGE)
    assert [m for m in modules if m.split("/")[0] in ("report", "export")] == []


def stand_in_run(plan: str, workdir: Path, stamp: float) -> None:
    """Empty files and directories for every output, log and benchmark that the dry run ``plan``
    (``-n -F``) lists, all modified at ``stamp``: a finished run as far as a dry run can tell."""
    for kind, names in re.findall(r"^\s+(output|log|benchmark): (.*)$", plan, re.M):
        for name in names.split(", "):
            path = workdir / name
            path.parent.mkdir(parents=True, exist_ok=True)
            if kind == "output" and not path.suffix:  # the rules' directory() outputs have no suffix
                path.mkdir(exist_ok=True)
            else:
                path.touch()
            os.utime(path, (stamp, stamp))


def test_editing_every_report_and_export_module_reruns_no_estimator(tmp_path: Path) -> None:
    """One dry run after a comment line is added to every module of report/ and export/, on a
    copy of the workflow whose tiny run stands finished (empty outputs newer than every source)."""
    repo, workdir = tmp_path / "repo", tmp_path / "run"
    for part in ("workflow", "config"):
        shutil.copytree(REPO / part, repo / part, ignore=shutil.ignore_patterns("__pycache__"))
    for path in repo.rglob("*"):
        os.utime(path, (1e9, 1e9))
    stand_in_run(snakemake(repo, workdir, "-n", "-F").stdout, workdir, 1.5e9)  # between the sources and the edits below
    assert "Nothing to be done" in snakemake(repo, workdir, "-n").stdout
    edited = sorted((repo / "workflow" / "freqbrdf" / "report").rglob("*.py")) + sorted(
        (repo / "workflow" / "freqbrdf" / "export").rglob("*.py"))
    for path in edited:
        with path.open("a") as f:
            f.write("# edited\n")
    jobs = planned_jobs(snakemake(repo, workdir, "-n").stdout)
    assert {"metrics", "tables", "export_gltf", "viewer"} <= set(jobs)  # the edits were seen
    assert sorted(set(jobs) & set(ESTIMATORS)) == []
