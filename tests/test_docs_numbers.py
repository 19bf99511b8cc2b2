"""Numbers in the docs that a command recounts: a job count written as

    190 jobs (`snakemake -n`, 2026-11-27)
    766 jobs (`snakemake -n --configfile config/benchmark.yaml`, 2026-11-27)

in README.md, docs/ or a preset's comments is what that dry run plans from an empty directory
today (issue 48, "Numbers that cannot go stale"). A count of a run that happened (a record's
"188 jobs") names no command and is left as it was.
"""

import re
from pathlib import Path

from workflow_runs import planned_jobs, snakemake

# "<N> jobs (`snakemake -n[ --configfile <preset>]`": the count, then the command that gives it.
STATEMENT = re.compile(r"(\d[\d,]*)\s+jobs\s+\(`snakemake\s+-n(?:\s+--configfile\s+(config/[\w.-]+\.yaml))?`")


def stated_counts(repo: Path) -> list[tuple[str, str | None, int]]:
    """Every (file:line, preset or None for the default, count) the docs state in that form."""
    files = [repo / "README.md", *sorted((repo / "docs").glob("*.md")), *sorted((repo / "config").glob("*.yaml"))]
    found = []
    for path in files:
        text = path.read_text()
        for match in STATEMENT.finditer(text):
            where = f"{path.relative_to(repo)}:{text.count(chr(10), 0, match.start()) + 1}"
            found.append((where, match.group(2), int(match.group(1).replace(",", ""))))
    return found


def test_the_readme_states_the_default_and_benchmark_counts_as_dry_run_counts(repo):
    """The statements the next test checks are there: a rewording that drops the command from one
    would otherwise leave its number unchecked."""
    readme = {(where.split(":")[0], preset) for where, preset, _ in stated_counts(repo)}
    assert {("README.md", None), ("README.md", "config/benchmark.yaml")} <= readme, readme


def test_every_stated_job_count_is_the_dry_runs(repo, tmp_path):
    statements = stated_counts(repo)
    planned: dict[str | None, int] = {}
    for preset in sorted({p for _, p, _ in statements}, key=str):
        workdir = tmp_path / (Path(preset).stem if preset else "default")
        workdir.mkdir()
        dry = snakemake(repo, workdir, "-n", base=None, extra_config=[repo / preset] if preset else ())
        planned[preset] = sum(planned_jobs(dry.stdout).values())
    stale = [f"{where} states {count} jobs for `snakemake -n{f' --configfile {p}' if p else ''}`; "
             f"the dry run plans {planned[p]}" for where, p, count in statements if count != planned[p]]
    assert not stale, "\n".join(stale)


# A Markdown link's target: "](path)" or "](path#anchor)", not a web address.
LINK = re.compile(r"\]\((?!https?://|mailto:)([^)#\s]*)(#[^)\s]*)?\)")


def _anchor(heading: str) -> str:
    """GitHub's anchor of a Markdown heading: lower case, punctuation dropped, spaces to hyphens."""
    return re.sub(r"[^\w\- ]", "", heading.strip().lower()).replace(" ", "-")


def test_every_relative_link_in_the_docs_names_a_file_and_heading_the_repository_holds():
    """README, docs/ and config/README point only at files the repository holds (issue 51: the
    README pointed at a file outside every clone), and at headings those files have."""
    repo = Path(__file__).resolve().parents[1]
    broken = []
    for page in [repo / "README.md", repo / "config" / "README.md", *sorted((repo / "docs").glob("*.md"))]:
        for match in LINK.finditer(page.read_text()):
            target = (page.parent / match.group(1)).resolve() if match.group(1) else page
            where = f"{page.relative_to(repo)}: {match.group(0)}"
            if not target.exists() or not target.is_relative_to(repo):
                broken.append(f"{where} (no such file in the repository)")
            elif match.group(2) and target.suffix == ".md":
                anchors = {_anchor(h) for h in re.findall(r"^#+ (.+)$", target.read_text(), re.M)}
                if match.group(2)[1:] not in anchors:
                    broken.append(f"{where} (no such heading)")
    assert not broken, "\n".join(broken)
