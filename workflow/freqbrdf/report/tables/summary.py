"""What rule tables writes: every table of the report with its title and caption
(:func:`summaries`), and the report's landing summary (:func:`run_facts`, :func:`run_summary_html`)."""

from __future__ import annotations

import html
from collections.abc import Mapping
from dataclasses import dataclass

import pandas as pd

from freqbrdf.methods import METHODS
from freqbrdf.report.tables.claims import ClaimContext, claims, verdict_counts
from freqbrdf.report.tables.display import method_label
from freqbrdf.report.tables.paper import PaperResults
from freqbrdf.report.tables.render import HTML_STYLE, scoped_style, to_html
from freqbrdf.report.tables.tidy import mitsuba_convergence
from freqbrdf.scene.hdri import CREDIT as HDRI_CREDIT
from freqbrdf.scene.scans import SCANS
from freqbrdf.report.tables.tables import (ablation_table, agreement_table, finetune_table, merge_table,
                                           parameter_table, relighting_table, uncertainty_table)


def run_facts(run: Mapping[str, object]) -> dict[str, str]:
    """What a run did, as the report's summary states it: one line per aspect.

    Parameters
    ----------
    run : mapping
        From the run's configuration: ``seed``, ``preset`` (``name``, ``smoke_test``),
        ``mitsuba`` (``epochs``, ``spp``), ``objects``, ``real_captures``
        (names), ``capture_envs``, ``envs``, ``env_kinds`` (config ``envs.<name>.kind`` of
        each of ``envs``), ``relight_envs`` (config ``evaluate.relight_envs``), ``render``
        (``train_views``, ``test_views``, ``resolution``, ``spp``), ``poses`` (config
        ``poses.source``) and ``methods``. Each object is called a scan or a procedural
        shape (:data:`freqbrdf.scene.scans.SCANS`), each environment a captured map (kind
        ``hdri``) or procedural light, and the scans' and maps' sources are credited.

    Returns
    -------
    dict of str to str
        Aspect -> text, in reading order.
    """
    render, relight, relit_methods = run["render"], run["relight_envs"], run["relight_methods"]
    if relight == "held_out":
        relit = "every environment lit as the capture was (a captured map or procedural light) but its own (held out)"
    else:
        relit = "every environment lit as the capture was" if relight == "all" else ", ".join(relight)
    if relit_methods != "all":
        relit += f"; only the estimates of {', '.join(relit_methods) or 'no method'}"
    preset, kinds = run["preset"], run["env_kinds"]
    objects = ", ".join(map(object_label, run["objects"]))
    facts = {
        "Preset": preset["name"] + (" (a smoke test: too few captures, views and steps for its verdicts to mean "
                                    "anything)" if preset["smoke_test"] else ""),
        "Mitsuba budget": mitsuba_budget(run["mitsuba"]),
        "Objects": f"{objects}, with seeded ground-truth SVBRDFs" if objects else "none",
        "Real captures": ", ".join(run["real_captures"]) or "none",
        # no synthetic object, no synthetic capture: the capture environments went unused
        "Captured under": ", ".join(light_label(env, kinds[env]) for env in run["capture_envs"] if objects) or "none",
        "Relit under": f"{relit}, of {', '.join(light_label(env, kinds[env]) for env in run['envs'])}",
        "Views": (f"{render['train_views']} training and {render['test_views']} test views per capture, "
                  f"{render['resolution']} x {render['resolution']} pixels at {render['spp']} samples per pixel"),
        "Poses": str(run["poses"]),
        "Methods": ", ".join(f"{method_label(m)} ({m})" for m in run["methods"]),
        "Seed": str(run["seed"]),
    }
    credits = [f"{name}: {SCANS[name].credit}" for name in run["objects"] if name in SCANS]
    maps = [env for env in run["envs"] if kinds[env] == "hdri"]
    if maps:
        credits.append(f"maps {', '.join(maps)}: {HDRI_CREDIT}")
    if credits:
        facts["Sources"] = "; ".join(credits)
    return facts


def object_label(name: str) -> str:
    """A synthetic object as the summary names it: ``bunny (a scan, atlased by xatlas)``,
    ``sphere (a procedural shape)``."""
    return f"{name} (a scan, atlased by xatlas)" if name in SCANS else f"{name} (a procedural shape)"


def light_label(env: str, kind: str) -> str:
    """An environment as the summary names it, from its config ``kind``: ``sky (a captured map)``
    for ``hdri``, else ``studio (procedural)``, the kind named when it is not the name
    (``outdoor (procedural sunny)``)."""
    if kind == "hdri":
        return f"{env} (a captured map)"
    return f"{env} (procedural)" if kind == env else f"{env} (procedural {kind})"


def mitsuba_budget(mitsuba: Mapping[str, object]) -> str:
    """The baseline's budget as the tables label it, e.g. ``6 epochs x 8 spp``, from config ``mitsuba``."""
    return f"{mitsuba['epochs']} epochs x {mitsuba['spp']} spp"


# The summary sits in the report's own page: its style is scoped to its box.
RUN_SUMMARY_STYLE = scoped_style(HTML_STYLE, "div.freqbrdf-summary")


def run_summary_html(facts: Mapping[str, str], claims_table: pd.DataFrame, headline: pd.DataFrame,
                     timing: str) -> str:
    """The report's landing summary as an HTML fragment: what was run, the paper's claims
    with their verdicts, and the headline numbers.

    Parameters
    ----------
    facts : mapping of str to str
        From :func:`run_facts`.
    claims_table : DataFrame
        From :func:`freqbrdf.report.tables.claims.claims` (its ``criterion`` column is left to the claims page).
    headline : DataFrame
        From :func:`freqbrdf.report.tables.tables.headline_table`.
    timing : str
        Where the times were taken (`freqbrdf.util.mitsuba_setup.timing_note`).
    """
    tally = ", ".join(f"{n} {verdict}" for verdict, n in verdict_counts(claims_table).items())
    lines = "".join(f"<li><b>{html.escape(k)}:</b> {html.escape(v)}</li>" for k, v in facts.items())
    warning = ""
    if "smoke test" in facts.get("Preset", ""):
        warning = ('<p class="warning"><b>A smoke test:</b> this run checks that every rule works, on toy sizes; '
                   "its numbers and verdicts say nothing about the method.</p>\n")
    return (f'<div class="freqbrdf-summary"><style>{RUN_SUMMARY_STYLE}</style>\n'
            f"<h2>This run</h2>\n{warning}<ul>{lines}</ul>\n"
            + to_html(claims_table[["claim", "holds", "ours", "paper"]], "The paper's claims on this run",
                      f"{len(claims_table)} claims: {tally}. Criteria and the paper's sources: Tables, claims.",
                      verdicts="holds")
            + to_html(headline, "Headline numbers",
                      "Means over this run's captures [95% intervals]: parameter MSE over observed texels, PSNR-H of relighting "
                      f"under held-out environments, time per capture ({timing}). Every number: "
                      "Tables, metrics.csv.")
            + "</div>\n")


# How Table 6's caption names each map of `freqbrdf.methods.MERGE_MAPS`.
_MERGE_MAP_LABELS = {"entropy": "the spectrum entropy", "posterior": "the expected error of its fit's posterior"}


def _merge_caption() -> str:
    """Table 6's caption, naming the map each merged method of the registry merges by."""
    maps = "; ".join(f"{m.name}: {_MERGE_MAP_LABELS[m.merged_by]}" for m in METHODS.values() if m.merged_by)
    return ("One texture set per object from all its captures: each texel takes the parameters of the "
            f"capture whose uncertainty is lowest there ({maps}), against the mean of the separate captures' "
            "estimates; parameter MSE as in Table 2. The paper merged Mitsuba's results by the entropy. ")


@dataclass(frozen=True)
class Summary:
    """One summary table with its file stem, title and caption."""

    key: str
    title: str
    caption: str
    table: pd.DataFrame


SUMMARY_KEYS = ("table1_relighting", "table2_parameters", "table3_agreement", "table4_ablation", "table5_finetune",
                "table6_merge", "uncertainty", "claims")
"""Keys of `summaries`, in its order: the stems of rule tables' output files."""


_UNCERTAINTY_CAPTION = (
    "Sparsification (Ilg et al. 2018): texels removed most uncertain first, the mean error of the rest "
    "divided by the mean error of all; AUSE is the area between that curve and the one ordered by the "
    "true error (0: the ideal order; Random: the expected area of a random order). Maps: our spectrum "
    "entropy; -views: fewer views that see the texel first (1/sqrt(views) has the same order); -light: "
    "less light along the views' mirror directions first. Errors: the per-texel parameter error "
    "(Table 2's MSE) and BRDF error (its log-RMSE). Pearson r: entropy against the parameter error; "
    "partial r | views: the same after removing each one's linear fit in the view count. ")


def summaries(df: pd.DataFrame, paper: PaperResults, env_kinds: Mapping[str, str] | None = None,
              context: ClaimContext | None = None) -> list[Summary]:
    """Every summary table of the report, in the paper's order, then the claims.

    Parameters
    ----------
    df : DataFrame
        Tidy metrics (:func:`freqbrdf.report.tables.tidy.check_tidy`), one pose source.
    paper : PaperResults
        The paper's numbers (:func:`freqbrdf.report.tables.paper.read_paper_results`).
    env_kinds : mapping, optional
        Our environment name -> kind, to place the paper's environments
        (:func:`freqbrdf.report.tables.tables.parameter_table`).
    context : ClaimContext, optional
        The claims' intervals, Mitsuba's budget (which also labels its rows) and the real captures.

    Returns
    -------
    list of Summary
        Keyed by :data:`SUMMARY_KEYS` (the output file stems).
    """
    context = context or ClaimContext()
    n_captures = len(df[["object", "env"]].drop_duplicates())
    n_truth = len(df[df.metric == "mse_average"][["object", "env"]].drop_duplicates())
    scope = (f"Ours: means over this run's {n_captures} capture(s), {n_truth} with ground truth, and in brackets "
             f"their {100 * context.intervals.level:g}% t-interval over captures (objects for a merge) "
             "(docs/metrics.md, Intervals); "
             f"(parameter MSE, relighting); times: {context.timing}. "
             "Paper: Wiersma et al. 2024 (arXiv 2406.17774), on an RTX 4090.")
    tables = [
        Summary("table1_relighting", "Table 1: relighting under held-out environments",
                "PSNR-H (linear HDR), PSNR-L (tone-mapped) and SSIM of renders of the recovered textures "
                "against ground-truth renders under environments not seen in training, mean over test views. "
                "The paper's numbers are on Stanford-ORB photographs; ours on the synthetic benchmark. "
                "LPIPS is not computed (no network weights offline). " + scope,
                relighting_table(df, paper, context.intervals)),
        Summary("table2_parameters", "Table 2: parameter MSE per capture environment",
                "Average (base colour, roughness, metallic) MSE against the ground-truth textures over "
                "observed texels; 'paper' rows give the paper's value for the environment of the same kind. "
                "BRDF log-RMSE: RMS difference of log(1 + f cos theta_i) between the estimated and true "
                "BRDF over a fixed set of direction pairs, on the same texels; Base SI-PSNR/SSIM: the base colour "
                "after a per-channel least-squares scale (Stanford-ORB), sRGB; both means over captures. "
                "Error-entropy correlation: Pearson correlation between our entropy and the method's "
                "per-texel squared error (the paper correlates with Mitsuba's). " + scope,
                parameter_table(df, paper, env_kinds, intervals=context.intervals)),
        Summary("table3_agreement", "Table 3: entropy agreement",
                "Pearson correlation, over a seeded sample of each capture's observed texels, of each entropy "
                "with the entropy of a grid of uniform materials (roughness x metallic x base colour) path traced "
                "by Mitsuba at the training views; mean \u00b1 standard deviation over the captures. 'Half the "
                "paths': against the Mitsuba grid from one of its two sample sets. Times are for the sampled "
                "texels (ours) and for whole captures on a GPU (paper). " + scope,
                agreement_table(df, paper)),
        Summary("table4_ablation", "Table 4: ablation of shadowing and masking",
                "Our model with and without the shadowing G1(theta_i) and masking G1(theta_o) terms; "
                "rh2001 has neither (Ramamoorthi and Hanrahan 2001). The paper's relighting numbers are on "
                "Stanford-ORB and its MSE and time on its synthetic set, both without cosine weighting of "
                "the samples (its section 5.5.1), as ours: every observed pair weighs the same in our data "
                "term, so Ours here is the Shadowing + masking row's configuration. " + scope,
                ablation_table(df, paper, intervals=context.intervals)),
        Summary("table5_finetune", "Table 5: fine-tuning with Mitsuba",
                "A short Mitsuba optimisation started from our textures (freq+mitsuba) against Mitsuba's "
                "full optimisation from a constant (mitsuba) and our textures alone (freq). Total time "
                "includes the initialisation. Rows without a method of ours are not in this pipeline. " + scope,
                finetune_table(df, paper, intervals=context.intervals)),
        Summary("table6_merge", "Table 6: captures merged by uncertainty", _merge_caption() + scope,
                merge_table(df, paper, intervals=context.intervals)),
        Summary("uncertainty", "Uncertainty: does the entropy rank the errors better than the view count?",
                _UNCERTAINTY_CAPTION + scope, uncertainty_table(df, context.intervals)),
        Summary("claims", "Claims of the paper, checked on this run",
                f"Each number: mean [{100 * context.intervals.level:g}% interval], Student's t over the captures' "
                "means (each over its relighting environments and test views; over objects for a merge); "
                "differences paired capture by capture. A claim that reads Mitsuba's estimate is judged on "
                "the captures where Mitsuba converged, all captures beside, and not judged when fewer than half did. "
                "holds: 'yes' when the criterion holds at the interval's unfavourable end, 'no' when it fails "
                "at the favourable end, 'within noise' otherwise; 'not judged' when the numbers cannot decide "
                "it (too few converged baselines, no interval), 'not run' when a method it needs did "
                "not run. " + scope,
                claims(df, paper, context)),
    ]
    return [Summary(s.key, s.title, s.caption, label_budget(s.table, df, context.mitsuba_budget)) for s in tables]


def label_budget(table: pd.DataFrame, df: pd.DataFrame, budget: str) -> pd.DataFrame:
    """The table with the ``mitsuba`` baseline's rows labelled with its budget and whether it converged.

    Parameters
    ----------
    table : DataFrame of str
        A summary table; its rows name methods in a ``method`` column (config names) or a
        ``Method`` column (``Label (name)``).
    df : DataFrame
        Tidy metrics, for ``mitsuba_converged``.
    budget : str
        :func:`mitsuba_budget`; '' leaves the table as it is.
    """
    if not budget:
        return table
    state = mitsuba_convergence(df)[1]
    out = table.copy()
    ours = out["source"] == "here" if "source" in out.columns else pd.Series(True, index=out.index)
    for column, name in (("method", "mitsuba"), ("Method", f"{method_label('mitsuba')} (mitsuba)")):
        if column in out.columns:
            out.loc[ours & (out[column] == name), column] = f"{name}, {budget}, {state}"
    return out
