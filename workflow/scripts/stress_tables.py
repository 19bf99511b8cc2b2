"""Rule stress_tables: the pose-effect table, the stress captures beside their references,
error and entropy inside and outside an unseen occluder's shadow, and the ambiguity pairs
(see rules/stress.smk). Every path comes from ``snakemake.input``, in the orders of
``snakemake.params``."""

import numpy as np
import pandas as pd

from freqbrdf.artefacts import read_entropy, read_observations, read_posterior_std, read_svbrdf
from freqbrdf.estimate.optimise.posterior import expected_error
from freqbrdf.sphere.brdf import TEXTURES
from freqbrdf.scene.cameras import cameras_from_json
from freqbrdf.report.figures import stress_figure
from freqbrdf.util.io import atomic_path, read_exr, read_json, read_views
from freqbrdf.util.logs import run_script
from freqbrdf.methods import FREQUENCY_RULES, METHODS
from freqbrdf.report.metrics import parameter_error_map, texel_parameter_columns
from freqbrdf.studies.stress import blocked_light, image_psnr, pair_table, pose_effect_table, region_table, stress_table
from freqbrdf.report.tables.display import fmt, method_label
from freqbrdf.report.tables.render import html_page, to_html, to_markdown
from freqbrdf.report.tables.tidy import read_tidy


def capture_arrays(smk, index):
    """The observations of stress capture ``index``, its observed texels (atlas indices), their
    uncertainty maps (``entropy``, and ``posterior_<method>`` for the methods whose estimates have
    a posterior) and each method's per-texel squared parameter error (arrays of shape (T_observed,))."""
    p, n, k = smk.params, len(smk.params.methods), len(TEXTURES)
    obs = read_observations(smk.input.observations[index])
    texels = obs.texels.texel[obs.observed]
    uncertainty = {"entropy": read_entropy(smk.input.entropy[index]).atlas.ravel()[texels]}
    truth = read_svbrdf(dict(zip(TEXTURES, smk.input.truth[k * index : k * (index + 1)])))
    estimates = dict(zip(p.methods, smk.input.estimates[n * index : n * (index + 1)]))
    error = {m: parameter_error_map(truth, read_svbrdf(d)).ravel()[texels] for m, d in estimates.items()}
    # as rule metrics scores it: the expected error of the scored texels' posterior deviations
    uncertainty |= {f"posterior_{m}": expected_error(texel_parameter_columns(read_posterior_std(d), texels) ** 2)
                    for m, d in estimates.items() if METHODS[m].has_posterior}
    return obs, texels, uncertainty, error


def pair_psnr(first, second):
    """PSNR between the training views of two captures of the same rig, over pixels both cover fully."""
    cameras = cameras_from_json(read_json(f"{first}/cameras.json"), f"{first}/cameras.json")
    a, cover_a, _ = read_views(first, cameras.names, cameras.width, cameras.height)
    b, cover_b, _ = read_views(second, cameras.names, cameras.width, cameras.height)
    return image_psnr(list(a), list(b), list((cover_a >= 0.99) & (cover_b >= 0.99)))


def occluder_regions(smk, arrays, index, log):
    """Per occluded capture (and its control), the region table of texels inside and outside the
    occluder's shadow; returns the tables and, per object, each observed texel's blocked light fraction."""
    p = smk.params
    regions, blocked_by = [], {}
    for (obj, env, occluder), envmap in zip(p.occluded, smk.input.envmaps):
        obs, texels, uncertainty, error = arrays[index[obj]]
        positions, normals = obs.texels.position[obs.observed], obs.texels.normal[obs.observed]
        blocked = blocked_light(positions, normals, read_exr(envmap), occluder["height"], occluder["radius"])
        blocked_by[obj] = blocked
        shadowed = blocked >= p.shadow_fraction
        log.info("%s: %d of %d observed texels lose >= %.0f%% of their light to the occluder", obj,
                 int(shadowed.sum()), len(blocked), 100 * p.shadow_fraction)
        scored = [(f"{obj} / {env}", uncertainty, error, shadowed)]
        ref = p.references.get(obj)
        if ref is not None and ref[0] in index:
            # The control (same object, light and views, no occluder) on the same atlas texels: what
            # the region's error is without the occluder (lower texels are seen from fewer views).
            _, ref_texels, ref_uncertainty, ref_error = arrays[index[ref[0]]]
            ref_shadowed = np.isin(ref_texels, texels[shadowed])
            scored.append((f"{ref[0]} / {ref[1]} (no occluder)", ref_uncertainty, ref_error, ref_shadowed))
        for name, maps, err, mask in scored:
            table = region_table(err, maps, mask)
            table.insert(0, "capture", name)
            regions.append(table.rename_axis("region").reset_index())
    return regions, blocked_by


def main(smk, log):
    p = smk.params
    metrics = read_tidy(smk.input.metrics)
    primary = metrics[metrics.poses == p.poses]
    sections = []
    for source in p.compare:
        table = pose_effect_table(metrics, p.poses, source, p.benchmark, p.methods)
        sections.append((f"Pose source: {source} against {p.poses}", table,
                         f"Each method on the benchmark's {len(p.benchmark)} captures estimated from {source} poses "
                         f"instead of {p.poses}: parameter MSE and relighting PSNR-H (means over captures and "
                         "relighting environments) and their change."))
        log.info("pose effect (%s vs %s):\n%s", source, p.poses, to_markdown(table))

    if p.captures:
        stress = {o: (e, p.descriptions[o]) for o, e in p.captures}
        table = stress_table(primary, stress, p.references, p.poses, p.methods)
        sections.append(("Stress captures", table,
                         "Each capture that breaks one of the model's assumptions, its value first and, in brackets, "
                         "that of the capture it is compared with (same textures, the assumption kept). Mean entropy: "
                         "the spectrum entropy over observed texels (0 certain, 1 uniform)."))

    # The figure and the region table show the gradient-descent estimator when it ran.
    frequency = [m for m in p.methods if METHODS[m].rule in FREQUENCY_RULES]
    shown = next((m for m in frequency if METHODS[m].rule == "optimise_svbrdf"), (frequency or p.methods)[0])
    index = {o: i for i, (o, _) in enumerate(p.captures)}
    arrays = [capture_arrays(smk, i) for i in range(len(p.captures))]
    regions, blocked_by = occluder_regions(smk, arrays, index, log)
    figure_rows = []
    for (obj, env), (obs, texels, uncertainty, error) in zip(p.captures, arrays):
        figure_rows.append({"name": f"{obj} / {env}", "resolution": obs.texels.resolution, "texels": texels,
                            "entropy": uncertainty["entropy"], "error": error[shown], "blocked": blocked_by.get(obj)})
    region_rows = pd.concat(regions, ignore_index=True) if regions else pd.DataFrame(columns=["capture", "region"])
    with atomic_path(smk.output.regions) as tmp:
        region_rows.to_csv(tmp, sep="\t", index=False, float_format="%.6g")
    if regions:
        shown_regions = region_rows.rename(columns={f"mse_{m}": f"MSE {method_label(m)}" for m in p.methods}
                                           | {f"mean_posterior_{m}": f"Mean posterior error {method_label(m)}"
                                              for m in p.methods}
                                           | {"mean_entropy": "Mean entropy"})
        shown_regions = shown_regions.map(lambda v: fmt(v, 4) if isinstance(v, float) else str(v))
        sections.append(("Unseen occluder: inside and outside its shadow", shown_regions,
                         f"Observed texels whose light the occluder (absent from the estimators' mesh) cuts by at "
                         f"least {100 * p.shadow_fraction:.0f}% (shadowed) or less (lit): mean per-texel parameter "
                         "error of each method, the mean error its posterior expects (where it has one) and the "
                         "mean entropy; the control capture (no occluder), where the config has one, on the same "
                         "texels."))

    if p.pairs:
        pairs = [(first, second, pair_psnr(smk.input.pairs[2 * i], smk.input.pairs[2 * i + 1]))
                 for i, (first, second) in enumerate(p.pairs)]
        for first, second, psnr in pairs:
            log.info("ambiguity pair %s / %s: training views %.1f dB apart", first[0], second[0], psnr)
        sections.append(("Light/material ambiguity pairs", pair_table(primary, pairs, p.references, p.poses, p.methods),
                         "A rough material under a sharp light and a shinier one under a blurred light: the PSNR "
                         "between their training views (same cameras), their mean entropy (in brackets: the benchmark "
                         "capture of the base object) and each method's roughness MSE."))

    text = "# FreqBRDF: stress captures and pose sources\n\n" + "\n".join(
        to_markdown(table, title, caption) for title, table, caption in sections)
    with atomic_path(smk.output.md) as tmp:
        tmp.write_text(text)
    body = "\n".join(to_html(table, title, caption) for title, table, caption in sections)
    with atomic_path(smk.output.html) as tmp:
        tmp.write_text(html_page("FreqBRDF: stress captures and pose sources", body))
    stress_figure(smk.output.figure, figure_rows, method_label(shown))
    log.info("%s", text)


run_script(main, snakemake)  # noqa: F821 (injected by Snakemake)
