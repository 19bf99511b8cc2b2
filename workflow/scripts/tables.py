"""Rule tables: the paper's Tables 1 to 6 and the claims table from the tidy metrics,
as Markdown and LaTeX files, and as HTML pages for the Snakemake report; and the
report's landing summary (what was run, the claims' verdicts, the headline numbers)."""


from freqbrdf.util.io import atomic_path
from freqbrdf.util.logs import run_script
from freqbrdf.util.mitsuba_setup import timing_note
from freqbrdf.report.tables.paper import read_paper_results
from freqbrdf.report.tables.render import html_page, to_html, to_latex, to_markdown
from freqbrdf.report.intervals import IntervalSettings
from freqbrdf.report.tables.claims import ClaimContext
from freqbrdf.report.tables.summary import mitsuba_budget, run_facts, run_summary_html, summaries
from freqbrdf.report.tables.tables import headline_table
from freqbrdf.report.tables.tidy import read_tidy


def write_text(path: str, text: str) -> None:
    with atomic_path(path) as tmp:
        tmp.write_text(text)


def main(smk, log):
    metrics = read_tidy(smk.input.metrics)
    # One pose source per table, the run's, and the benchmark's captures only: metrics.csv also
    # holds poses.compare and the stress captures (rule stress_tables reports them).
    metrics = metrics[(metrics.poses == smk.params.poses) & ~metrics.object.isin(smk.params.stress)]
    if metrics.empty:
        raise ValueError(f"{smk.input.metrics}: no rows with poses == {smk.params.poses!r}")
    context = ClaimContext(IntervalSettings.from_config(smk.params.intervals),
                           mitsuba_budget(smk.params.run["mitsuba"]), frozenset(smk.params.real_objects),
                           timing_note(smk.params.run["mitsuba"]["variant"]))
    tables = summaries(metrics, read_paper_results(smk.input.paper), smk.params.env_kinds, context)
    for summary in tables:
        write_text(smk.output[f"{summary.key}_md"], to_markdown(summary.table, summary.title, summary.caption))
        write_text(smk.output[f"{summary.key}_tex"],
                   to_latex(summary.table, f"{summary.title}. {summary.caption}", f"tab:{summary.key}"))
        log.info("%s:\n%s", summary.title, to_markdown(summary.table))
    write_text(smk.output.all_md, "# FreqBRDF: summary tables\n\n"
               + "\n".join(to_markdown(s.table, s.title, s.caption) for s in tables))
    body = "\n".join(to_html(s.table, s.title, s.caption) for s in tables if s.key != "claims")
    write_text(smk.output.html, html_page("FreqBRDF: the paper's tables, reproduced", body))
    claims = next(s for s in tables if s.key == "claims")
    write_text(smk.output.claims_html, html_page("FreqBRDF: the paper's claims, checked",
                                                 to_html(claims.table, None, claims.caption, verdicts="holds")))
    # what was run, from the run's config: env_kinds tells a captured map from procedural light
    facts = run_facts(dict(smk.params.run, env_kinds=smk.params.env_kinds))
    write_text(smk.output.run_summary, run_summary_html(facts, claims.table, headline_table(metrics, context.intervals),
                                                    context.timing))
    verdicts = claims.table.holds.value_counts().to_dict()
    log.info("claims: %s", ", ".join(f"{n} {v}" for v, n in sorted(verdicts.items())))


run_script(main, snakemake)  # noqa: F821 (injected by Snakemake)
