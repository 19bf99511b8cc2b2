"""Summary tables and claims from small synthetic tidy tables: values land in the right cells,
the paper's numbers sit beside ours, and each claim flips when the data contradict it."""

import io

import pandas as pd
import pytest

from freqbrdf import tables
from freqbrdf.tables import check_tidy, claims, parameter_table, relighting_table

ENV_KINDS = {"studio": "studio", "sunny": "sunny", "museum": "museum", "overcast": "overcast"}


def tidy(rows) -> pd.DataFrame:
    """(object, env, method, metric, value[, relight_env]) tuples -> a checked tidy table."""
    records = []
    for row in rows:
        obj, env, method, metric, value, *relight = row
        records.append({"object": obj, "env": env, "poses": "gt", "method": method,
                        "relight_env": relight[0] if relight else "", "metric": metric, "value": value})
    return check_tidy(pd.DataFrame(records))


def mse_rows(method, average, env="studio", obj="sphere", parts=(0.01, 0.02, 0.03)):
    names = ("mse_average", "mse_base_color", "mse_roughness", "mse_metallic")
    return [(obj, env, method, name, value) for name, value in zip(names, (average, *parts))]


def full_run(overrides=None) -> pd.DataFrame:
    """Every method on two captures, with numbers that satisfy every claim; ``overrides``
    replace (method, metric) values everywhere."""
    values = {
        ("mitsuba", "mse_average"): 0.04, ("freq", "mse_average"): 0.06, ("spectrum", "mse_average"): 0.20,
        ("freq_noshadow", "mse_average"): 0.08, ("freq_nomask", "mse_average"): 0.09,
        ("rh2001", "mse_average"): 0.12, ("freq+mitsuba", "mse_average"): 0.05,
        ("mitsuba", "time_total_s"): 100.0, ("freq", "time_total_s"): 5.0, ("spectrum", "time_total_s"): 2.0,
        ("freq_noshadow", "time_total_s"): 4.0, ("freq_nomask", "time_total_s"): 4.0,
        ("rh2001", "time_total_s"): 3.0, ("freq+mitsuba", "time_total_s"): 20.0,
        ("mitsuba", "psnr_h"): 26.0, ("freq", "psnr_h"): 25.8, ("freq+mitsuba", "psnr_h"): 26.5,
        ("spectrum", "psnr_h"): 24.0,
        ("mitsuba", "pearson_entropy_error"): 0.2, ("freq", "pearson_entropy_error"): 0.3,
    }
    values.update(overrides or {})
    rows = []
    for obj in ("sphere", "torus"):
        for (method, metric), value in values.items():
            relight = "museum" if metric.startswith("psnr") else ""
            rows.append((obj, "studio", method, metric, value, relight))
    return tidy(rows)


def verdicts(df) -> dict[str, str]:
    table = claims(df)
    return dict(zip(table.claim, table.holds))


def cell(table, column, **where):
    rows = table
    for key, value in where.items():
        rows = rows[rows[key] == value]
    assert len(rows) == 1, f"{where}: {len(rows)} rows"
    return rows.iloc[0][column]


def test_parameter_table_puts_means_and_paper_values_in_the_right_cells():
    df = tidy(mse_rows("freq", 0.10, "studio", "sphere") + mse_rows("freq", 0.20, "studio", "torus", (0.03, 0.04, 0.05))
              + mse_rows("freq", 0.30, "sunny") + mse_rows("spectrum", 0.5, "studio")
              + [("sphere", "studio", "freq", "time_total_s", 3.0), ("sphere", "sunny", "freq", "time_total_s", 5.0),
                 ("sphere", "studio", "freq", "pearson_entropy_error", 0.25)])
    table = parameter_table(df, ENV_KINDS)
    studio, sunny = "studio [paper: Photo Studio]", "sunny [paper: Rural Road]"
    assert list(table.columns) == ["Method", "source", studio, sunny, "Avg.", "Time"]
    # mean over the two objects, with the parts in brackets
    assert cell(table, studio, Method="Ours (freq)", source="here") == "0.150 (0.020, 0.030, 0.040)"
    assert cell(table, sunny, Method="Ours (freq)", source="here") == "0.300 (0.010, 0.020, 0.030)"
    assert cell(table, "Avg.", Method="Ours (freq)", source="here").startswith("0.200 ")
    assert cell(table, "Time", Method="Ours (freq)", source="here") == "4 s"
    # the paper's values for the environment of the same kind
    assert cell(table, studio, Method="Ours (freq)", source="paper") == "0.07 (0.02, 0.09, 0.10)"
    assert cell(table, sunny, Method="Ours (freq)", source="paper") == "0.05 (0.01, 0.05, 0.08)"
    assert cell(table, "Time", Method="Mitsuba (mitsuba)", source="paper") == "105 s"
    assert cell(table, "Avg.", Method="Ours-Spectrum Only (spectrum)", source="here").startswith("0.500")
    # Mitsuba is not in this run
    assert cell(table, studio, Method="Mitsuba (mitsuba)", source="here") == tables.NOT_RUN
    assert cell(table, studio, Method="Error-entropy correlation (freq)", source="here") == "0.25"
    assert cell(table, sunny, Method="Error-entropy correlation (freq)", source="here") == tables.MISSING
    assert cell(table, studio, Method="Error-entropy correlation (mitsuba)", source="paper") == "0.21"


def test_environment_kinds_place_the_paper_columns():
    df = tidy(mse_rows("freq", 0.1, "lab"))
    table = parameter_table(df, {"lab": "overcast"})
    assert cell(table, "lab [paper: Overcast]", Method="Ours (freq)", source="paper") == "0.06 (0.02, 0.07, 0.09)"
    # an environment of unknown kind gets no paper value
    table = parameter_table(df, {})
    assert cell(table, "lab", Method="Ours (freq)", source="paper") == tables.MISSING


def test_relighting_table_means_paper_rows_and_extra_methods():
    df = tidy([("sphere", "studio", "freq", "psnr_h", 20.0, "museum"), ("sphere", "studio", "freq", "psnr_h", 22.0, "sunny"),
               ("sphere", "studio", "freq", "ssim", 0.9, "museum"), ("sphere", "studio", "rh2001", "psnr_h", 18.0, "museum"),
               ("sphere", "studio", "freq", "time_s", 7.0)])
    table = relighting_table(df)
    assert cell(table, "PSNR-H", method="freq") == "21.00"
    assert cell(table, "PSNR-H (paper)", method="freq") == "26.68"
    assert cell(table, "SSIM", method="freq") == "0.900"
    assert cell(table, "PSNR-L", method="freq") == tables.MISSING  # ran, but no such metric
    assert cell(table, "Time", method="freq") == "7 s"  # time_s when there is no time_total_s
    assert cell(table, "PSNR-H", Method="Mitsuba") == tables.NOT_RUN
    assert cell(table, "PSNR-H", Method="NVDiffRec") == tables.NOT_RUN
    assert cell(table, "PSNR-H (paper)", Method="NVDiffRec") == "24.32"
    assert cell(table, "PSNR-H", method="rh2001") == "18.00"  # not a paper row: appended
    assert cell(table, "PSNR-H (paper)", method="rh2001") == tables.MISSING


def test_ablation_and_finetune_tables():
    df = full_run()
    ablation = tables.ablation_table(df)
    assert list(ablation.method) == ["rh2001", "freq_nomask", "freq_noshadow", "freq"]
    assert cell(ablation, "MSE", method="freq_nomask") == "0.090"
    assert cell(ablation, "Shadowing", method="freq_nomask") == "yes"
    assert cell(ablation, "Masking", method="freq_nomask") == "no"
    assert cell(ablation, "MSE (paper)", method="freq_nomask") == "0.14"
    assert cell(ablation, "MSE (paper)", method="freq_noshadow") == "0.13"
    finetune = tables.finetune_table(df)
    assert cell(finetune, "PSNR-H", method="freq+mitsuba") == "26.50"
    assert cell(finetune, "PSNR-H (paper)", method="freq+mitsuba") == "27.04"
    assert cell(finetune, "Total time (paper)", method="mitsuba") == "70 s"
    assert cell(finetune, "MSE", method="freq+mitsuba") == "0.050"
    assert cell(finetune, "PSNR-H", Initialization="Constant") == tables.NOT_RUN


def test_every_claim_holds_on_consistent_data():
    assert set(verdicts(full_run()).values()) == {"yes"}


@pytest.mark.parametrize("overrides, claim", [
    # slower than Mitsuba also breaks the order of the times
    ({("freq", "time_total_s"): 200.0}, ("Ours (freq) fits much faster than Mitsuba",
                                         "Spectrum-only is faster than ours, which is faster than Mitsuba")),
    ({("spectrum", "time_total_s"): 6.0}, "Spectrum-only is faster than ours, which is faster than Mitsuba"),
    ({("freq", "mse_average"): 0.075}, "Parameter accuracy comparable to Mitsuba"),
    ({("freq", "psnr_h"): 24.9}, "Relighting on par with Mitsuba"),
    ({("spectrum", "mse_average"): 0.05}, "The full model is more accurate than the spectrum-only estimate"),
    ({("rh2001", "mse_average"): 0.085},
     "Shadowing and masking each improve on Ramamoorthi-Hanrahan; both together are best"),
    ({("freq_nomask", "mse_average"): 0.055},
     "Shadowing and masking each improve on Ramamoorthi-Hanrahan; both together are best"),
    ({("freq+mitsuba", "mse_average"): 0.07}, "Fine-tuning our result with Mitsuba improves on ours"),
    ({("freq+mitsuba", "time_total_s"): 40.0}, "Ours + Mitsuba beats Mitsuba alone in less than a third of its time"),
    ({("freq+mitsuba", "psnr_h"): 25.9}, "Ours + Mitsuba beats Mitsuba alone in less than a third of its time"),
    ({("mitsuba", "pearson_entropy_error"): -0.1}, "Our entropy correlates positively with Mitsuba's per-texel error"),
])
def test_a_claim_flips_when_the_data_contradict_it(overrides, claim):
    flipped = [claim] if isinstance(claim, str) else list(claim)
    result = verdicts(full_run(overrides))
    assert [c for c, v in result.items() if v != "yes"] == flipped
    assert {result[c] for c in flipped} == {"no"}


def test_claims_without_mitsuba_say_not_run_and_keep_the_others():
    df = full_run()
    df = df[~df.method.isin(["mitsuba", "freq+mitsuba"])]
    result = verdicts(df)
    assert result["Ours (freq) fits much faster than Mitsuba"] == "not run"
    assert result["Parameter accuracy comparable to Mitsuba"] == "not run"
    assert result["Our entropy correlates positively with Mitsuba's per-texel error"] == "not run"
    assert result["Fine-tuning our result with Mitsuba improves on ours"] == "not run"
    assert result["Shadowing and masking each improve on Ramamoorthi-Hanrahan; both together are best"] == "yes"
    table = claims(df)
    ours = dict(zip(table.claim, table.ours))
    assert ours["Our entropy correlates positively with Mitsuba's per-texel error"] == "freq 0.30"
    assert ours["Shadowing and masking each improve on Ramamoorthi-Hanrahan; both together are best"] == (
        "MSE neither 0.120, shadowing 0.090, masking 0.080, both 0.060")


def test_speed_ratio_prefers_the_reported_ratio():
    df = full_run()
    assert tables.speed_ratio(df, "freq") == pytest.approx(20.0)  # 100 s / 5 s from the times
    reported = pd.concat([df, tidy([("sphere", "studio", "freq", "speed_ratio_vs_mitsuba", 12.0)])])
    assert tables.speed_ratio(reported, "freq") == pytest.approx(12.0)


def test_csv_round_trip_reads_empty_relight_env_as_blank():
    text = "object,env,poses,method,relight_env,metric,value\nsphere,studio,gt,freq,,mse_average,0.1\n" \
           "sphere,studio,gt,freq,museum,psnr_h,25\n"
    df = check_tidy(pd.read_csv(io.StringIO(text)))
    assert list(df.relight_env) == ["", "museum"]
    with pytest.raises(ValueError, match=r"lacks columns \['relight_env'\]"):
        check_tidy(pd.read_csv(io.StringIO(text)).drop(columns="relight_env"))


def test_markdown_latex_and_html_rendering():
    table = pd.DataFrame({"method": ["freq_nomask", "a|b"], "MSE": ["0.100", "not run"], "Time": ["3.1 s", "-"]})
    md = tables.to_markdown(table, title="T", caption="C").splitlines()
    assert md[0] == "### T" and md[-1] == "C"
    assert md[2] == "| method | MSE | Time |"
    assert md[3] == "|---|---:|---:|"  # numeric columns right-aligned
    assert md[5] == r"| a\|b | not run | - |"
    tex = tables.to_latex(table, caption="50% of x_y", label="tab:t")
    assert r"\begin{tabular}{lrr}" in tex
    assert r"freq\_nomask & 0.100 & 3.1 s \\" in tex
    assert r"\caption{50\% of x\_y}" in tex and r"\label{tab:t}" in tex
    assert tables.latex_escape("a < b >= c") == r"a \textless{} b \textgreater{}= c"
    verdicts = pd.DataFrame({"shadowing": ["yes", "no", "no"], "holds": ["yes", "no", "not run"]})
    page = tables.html_page("P", tables.to_html(verdicts, verdicts="holds"))
    assert '<td class="yes">yes</td>' in page and '<td class="no">no</td>' in page
    assert '<td class="notrun">not run</td>' in page and "<script" not in page
    assert "<td>no</td>" in page  # only the verdict column is coloured
    assert tables.to_html(verdicts).count('class="yes"') == 0


def test_summaries_cover_the_four_tables_and_the_claims():
    keys = [s.key for s in tables.summaries(full_run(), ENV_KINDS)]
    assert keys == ["table1_relighting", "table2_parameters", "table4_ablation", "table5_finetune", "claims"]
