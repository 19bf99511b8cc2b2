# Tables and figures of the Snakemake report (snakemake --report results/report.html).
# These rules read finished outputs only and take no config that upstream rules
# use, so changing a metric setting reruns metrics, then these, and nothing else.

from freqbrdf.report.tables.summary import (
    SUMMARY_KEYS as TABLES,
)  # stems of the table files: the paper's Tables 1-6 and the claims

# Methods with a logged MSE curve (differentiable rendering) and those shown as points.
CONVERGENCE_CURVES = [m for m in METHODS if METHOD_REGISTRY[m].rule == "mitsuba"]
CONVERGENCE_POINTS = [m for m in METHODS if METHOD_REGISTRY[m].rule in FREQUENCY_RULES]


# Every file the report rules write.
REPORT_TARGETS = (
    [fill(layout.TABLE, name=f"{t}.{ext}") for t in TABLES for ext in ("md", "tex")]
    + [fill(layout.TABLE, name=name) for name in ("tables.md", "tables.html", "claims.html")]
    + [fill(layout.CAPTURE_FIGURE, object=o, env=e, poses=POSES, name="maps.png") for o, e in CAPTURES]
    + ([fill(layout.FIGURE, name="uncertainty.png")] if "freq" in METHODS and SYNTHETIC_CAPTURES else [])
    + [fill(layout.CAPTURE_FIGURE, object=o, env=e, poses=POSES, name="relight.png") for o, e in SYNTHETIC_CAPTURES]
    + [fill(layout.CAPTURE_FIGURE, object=o, env=e, poses=POSES, name="regulariser.png") for o, e in CAPTURES]
    + [fill(layout.VIEWS, object=o, env=e, poses=POSES, ext="png") for o, e in VIEWS_CAPTURES]
    + [fill(layout.AGREEMENT, object=o, env=e, poses=POSES, name="agreement.png") for o, e in AGREEMENT_CAPTURES]
    + [
        fill(layout.CAPTURE_FIGURE, object=o, env=e, poses=POSES, name="convergence.png")
        for o, e in (SYNTHETIC_CAPTURES if CONVERGENCE_CURVES else [])
    ]
)


rule tables:
    """The paper's Tables 1 to 6 with our numbers beside the paper's, and the
    claims table, as Markdown, LaTeX and HTML (the HTML pages are in the report)."""
    input:
        metrics=layout.METRICS,
        # The paper's numbers ship with the workflow, not with the working
        # directory: found next to the Snakefile, as the embedded config is,
        # also under --directory (no rule reads config/ relative to the workdir).
        paper=str(REPO / "config" / "paper_results.yaml"),
        code=library("tables"),
    output:
        **{f"{t}_{ext}": fill(layout.TABLE, name=f"{t}.{ext}") for t in TABLES for ext in ("md", "tex")},
        all_md=fill(layout.TABLE, name="tables.md"),
        html=report(
            fill(layout.TABLE, name="tables.html"),
            category="Tables",
            caption="../report/tables.rst",
            labels={"table": "Tables 1 to 6"},
        ),
        claims_html=report(
            fill(layout.TABLE, name="claims.html"),
            category="Tables",
            caption="../report/claims.rst",
            labels={"table": "claims"},
        ),
        # The report's landing page (report/workflow.rst) shows it.
        run_summary=fill(layout.TABLE, name="run_summary.html"),
    log:
        layout.log("tables"),
    conda:
        "../envs/freqbrdf.yaml"
    resources:
        mem_mb=memory(500),
        runtime=minutes(1),
    params:
        poses=POSES,
        stress=list(STRESS),
        # Which of the paper's environments each of ours stands beside (Table 2).
        env_kinds={env: config["envs"][env]["kind"] for env in ENVS},
        # the claims' intervals' level and which captures are real (freqbrdf.report.tables.claims)
        intervals=config["evaluate"]["intervals"],
        real_objects=list(REAL_CAPTURES),
        # what the report's landing summary says was run (freqbrdf.report.tables.summary.run_facts)
        run={
            "seed": config["seed"],
            "preset": config["preset"],
            "mitsuba": {key: config["mitsuba"][key] for key in ("epochs", "spp")} | {"variant": MITSUBA_VARIANT},
            "objects": SYNTHETIC_OBJECTS,
            "real_captures": list(REAL_CAPTURES),
            "capture_envs": CAPTURE_ENVS,
            "envs": ENVS,
            "relight_envs": config["evaluate"]["relight_envs"],
            "relight_methods": config["evaluate"]["relight_methods"],
            "render": {key: config["render"][key] for key in ("train_views", "test_views", "resolution", "spp")},
            "poses": POSES,
            "methods": METHODS,
        },
    script:
        "../scripts/tables.py"


rule capture_figure:
    """Ground truth against every method's base colour, roughness and metallic maps,
    with the entropy map (Turbo) and each method's per-texel error."""
    input:
        estimates=lambda w: [
            fill(layout.ESTIMATE, object=w.object, env=w.env, poses=w.poses, method=m) for m in METHODS
        ],
        # A real capture without ground-truth textures: its figure shows no error maps.
        truth=truth_files,
        observations=layout.OBSERVATIONS,
        entropy=layout.ENTROPY,
        code=library("capture_figure"),
    output:
        report(
            fill(layout.CAPTURE_FIGURE, name="maps.png"),
            category="Captures",
            subcategory="{object} / {env}",
            caption="../report/capture_maps.rst",
            labels={"capture": "{object} / {env}", "figure": "SVBRDF maps, entropy, error"},
        ),
    log:
        layout.log("capture_figure", "{object}_{env}_{poses}"),
    conda:
        "../envs/freqbrdf.yaml"
    resources:
        mem_mb=memory(500, "texels"),
        runtime=minutes(1, "texels"),
    params:
        methods=METHODS,
    script:
        "../scripts/capture_figure.py"


rule relight_figure:
    """The first test view relit with every method's textures beside the ground-truth
    render, under each held-out environment, with that view's PSNR-H and error image."""
    input:
        relit=lambda w: [relit_dir(w.object, w.env, w.poses, m) for m, _ in capture_relights(w)],
        references=lambda w: [
            fill(layout.CAPTURE, object=w.object, env=r, split="test") for r in relight_figure_envs(w)
        ],
        code=library("relight_figure"),
    output:
        report(
            fill(layout.CAPTURE_FIGURE, name="relight.png"),
            category="Captures",
            subcategory="{object} / {env}",
            caption="../report/capture_relight.rst",
            labels={"capture": "{object} / {env}", "figure": "relighting"},
        ),
    log:
        layout.log("relight_figure", "{object}_{env}_{poses}"),
    conda:
        "../envs/freqbrdf.yaml"
    resources:
        mem_mb=memory(500, "pixels"),
        runtime=minutes(1),
    params:
        relights=capture_relights,
        references=relight_figure_envs,
        # PSNR-H of the view scored as metrics.csv scores the test set (rules/evaluate.smk)
        metrics={key: config["evaluate"][key] for key in METRIC_KEYS},
    script:
        "../scripts/relight_figure.py"


rule uncertainty_figure:
    """Sparsification curves of freq's per-texel error under the entropy and the trivial
    uncertainty baselines, one panel per capture (issue 33); the reliability diagram of
    freq's posterior, one panel per parameter (issue 50)."""
    input:
        curves=layout.SPARSIFICATION,
        reliability=layout.RELIABILITY,
        code=library("uncertainty_figure"),
    output:
        sparsification=report(
            fill(layout.FIGURE, name="uncertainty.png"),
            category="Tables",
            caption="../report/uncertainty.rst",
            labels={"table": "sparsification curves (freq)"},
        ),
        reliability=report(
            fill(layout.FIGURE, name="reliability.png"),
            category="Tables",
            caption="../report/reliability.rst",
            labels={"table": "reliability of the posterior (freq)"},
        ),
    log:
        layout.log("uncertainty_figure"),
    conda:
        "../envs/freqbrdf.yaml"
    resources:
        mem_mb=memory(500),
        runtime=minutes(1),
    params:
        poses=POSES,
        method="freq",
        captures=SYNTHETIC_CAPTURES,  # the benchmark's (the stress captures have their own page)
    script:
        "../scripts/uncertainty_figure.py"


rule convergence_figure:
    """Parameter MSE against time from the capture: Mitsuba's runs epoch by epoch beside
    the frequency-domain methods (issue 14's equal-accuracy comparison)."""
    input:
        curves=lambda w: [
            fill(layout.ESTIMATE, object=w.object, env=w.env, poses=w.poses, method=m) for m in CONVERGENCE_CURVES
        ],
        extraction=layout.benchmark("extract_observations", "{object}_{env}_{poses}"),
        metrics=layout.METRICS,
        code=library("convergence_figure"),
    output:
        report(
            fill(layout.CAPTURE_FIGURE, name="convergence.png"),
            category="Captures",
            subcategory="{object} / {env}",
            caption="../report/capture_convergence.rst",
            labels={"capture": "{object} / {env}", "figure": "MSE against time"},
        ),
    log:
        layout.log("convergence_figure", "{object}_{env}_{poses}"),
    conda:
        "../envs/freqbrdf.yaml"
    resources:
        mem_mb=memory(500),
        runtime=minutes(1),
    params:
        curves=CONVERGENCE_CURVES,
        starts=[METHOD_REGISTRY[m].start for m in CONVERGENCE_CURVES],
        points=CONVERGENCE_POINTS,
        variant=MITSUBA_VARIANT,
    script:
        "../scripts/convergence_figure.py"


rule regulariser_figure:
    """Paper Fig. 3 on a capture's own samples: how well each SH fit option (exp, constant, none,
    zero-padding) keeps a known lobe in the ratio of the spectra of filtered and unfiltered light."""
    input:
        observations=layout.OBSERVATIONS,
        envmap=envmap_file,
        code=library("regulariser_figure"),
    output:
        figure=report(
            fill(layout.CAPTURE_FIGURE, name="regulariser.png"),
            category="Captures",
            subcategory="{object} / {env}",
            caption="../report/capture_regulariser.rst",
            labels={"capture": "{object} / {env}", "figure": "SH fit options"},
        ),
        table=fill(layout.CAPTURE_FIGURE, name="regulariser.tsv"),
    log:
        layout.log("regulariser_figure", "{object}_{env}_{poses}"),
    conda:
        "../envs/freqbrdf.yaml"
    resources:
        mem_mb=memory(500, "texels"),
        runtime=minutes(1, "texels"),
    params:
        sh=config["sh"],
        texels=1000,  # observed texels sampled (seeded)
        alpha=0.3,  # the lobe filtering the light (roughness 0.55, mid-range of the benchmark)
        seed=lambda w: derived_seed(config["seed"], "regulariser", w.object, w.env, w.poses),
    script:
        "../scripts/regulariser_figure.py"
